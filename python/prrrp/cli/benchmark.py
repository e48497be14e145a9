"""``prrrp benchmark``: a Monte-Carlo benchmark of the estimators (seeds × noise scales ×
sampling rates × methods) on every core or a Dask cluster, into a folder of results.csv,
results.json, report.md and figures."""

from __future__ import annotations

import argparse
import contextlib
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from prrrp.cli import common

#: ``prrrp benchmark --help``.
HELP = "Monte-Carlo benchmark of the estimators on every core or a Dask cluster"
DESCRIPTION = (
    "For each case (seed × noise scale × sampling rate): excitation, "
    "closed-loop simulation, sensor noise, preprocessing, identification with each "
    "method, torque prediction on a second trajectory. Writes results.csv (one row per "
    "case × method), results.json, report.md and figures into DIR (built aside and "
    "swapped in whole). Deterministic per seed whatever the worker count or engine. "
    "A case whose worker dies or times out is retried once, then recorded as failed."
)


def _list_of(convert: Any, kind: str, what: str, at_least: int | None = None) -> Any:
    """An argparse type: comma-separated values of `convert` (``kind`` names them in the
    error), at least one, each at least ``at_least`` when given."""

    def parse(text: str) -> list[Any]:
        try:
            values = [convert(x) for x in text.split(",") if x.strip()]
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"not a comma-separated list of {kind}: {text!r}"
            ) from None
        if not values:
            raise argparse.ArgumentTypeError(f"no {what} given")
        bad = [v for v in values if at_least is not None and v < at_least]
        if bad:
            raise argparse.ArgumentTypeError(f"must be at least {at_least}, got {bad[0]}")
        return values

    return parse


def _floats(what: str) -> Any:
    return _list_of(float, "numbers", what)


_positive_ints = _list_of(int, "integers", "value", at_least=1)


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {value}")
    return value


def add_parser(sub: Any) -> None:
    from prrrp.montecarlo import DEFAULT_METHODS, METHODS

    p = common.add_command(sub, "benchmark", run, help=HELP, description=DESCRIPTION)
    common.add_robot_arguments(p)
    p.add_argument(
        "--methods",
        default=",".join(DEFAULT_METHODS),
        help=f"comma-separated, of {', '.join(METHODS)} (default: %(default)s)",
    )
    p.add_argument(
        "--noise",
        type=_floats("noise scales"),
        default=[1.0],
        help="noise scales of the default sensor noise, e.g. 1,3 (default: 1)",
    )
    p.add_argument(
        "--rates",
        type=_floats("rates"),
        default=[50.0],
        help="sampling rates in Hz, e.g. 50,100 (default: 50)",
    )
    p.add_argument(
        "--seeds",
        type=_positive_int,
        default=10,
        help="number of seeds per noise and rate (default: 10)",
    )
    p.add_argument(
        "--duration",
        type=common.number,
        default=10.0,
        help="excitation length per case, s (default: 10)",
    )
    p.add_argument(
        "--excitation-evaluations",
        type=_positive_ints,
        default=[300],
        metavar="N[,N...]",
        help="cost evaluations of the excitation optimiser per case; several (e.g. 50,300) "
        "add a grid axis and the report compares the errors per budget (default: 300)",
    )
    p.add_argument(
        "--timeout",
        type=float,
        default=300.0,
        help="seconds per case before it is abandoned (default: 300)",
    )
    engine = p.add_mutually_exclusive_group()
    engine.add_argument(
        "--workers",
        type=_positive_int,
        help="worker processes on this machine (default: every core)",
    )
    engine.add_argument(
        "--dask",
        metavar="ADDRESS",
        help="run on the Dask cluster at ADDRESS (tcp://host:8786; needs "
        "`pip install prrrp[cluster]`) (default: none, a local process pool)",
    )
    common.add_out_argument(
        p, help="output directory (default: ./benchmark-out)", default="benchmark-out"
    )


@contextlib.contextmanager
def _dask_executor(address: str) -> Iterator[Any]:
    try:
        from distributed import Client
    except ImportError:
        raise common.CliError(
            "--dask needs dask.distributed: pip install 'prrrp[cluster]'"
        ) from None
    try:
        client = Client(address, timeout="10s")
    except (OSError, TimeoutError, ValueError) as e:
        raise common.CliError(f"--dask {address}: cannot connect to the scheduler ({e})") from None
    try:
        yield client.get_executor()
    finally:
        client.close()


def run(args: argparse.Namespace) -> int:
    import prrrp
    from prrrp import outdir
    from prrrp.montecarlo import report

    out = Path(args.out)
    # Refuse an unusable --out before hours of computation, not after.
    outdir.check(out)
    with contextlib.ExitStack() as stack:
        executor = stack.enter_context(_dask_executor(args.dask)) if args.dask else None
        result = prrrp.benchmark(
            robot=args.robot,
            methods=args.methods,
            noise=args.noise,
            rates=args.rates,
            seeds=args.seeds,
            executor=executor,
            workers=args.workers,
            timeout=args.timeout,
            duration=args.duration,
            excitation_evaluations=args.excitation_evaluations,
            base=args.base,
            tip=args.tip,
        )
    try:
        result.save(out)
    except (OSError, outdir.OutputDirError) as e:
        rescue = _rescue(result, out)
        raise common.CliError(
            f"--out {out}: the results could not be written there ({_oserror(e)}); "
            + (f"they are in {rescue}" if rescue else "and no rescue file could be written"),
            code=common.EXIT_FAILED,
        ) from None
    stats = result.stats
    budgets = len(result.config["excitation_evaluations"]) > 1
    print(
        f"{'method':>9} {'noise':>6} {'rate':>6} "
        + (f"{'evals':>6} " if budgets else "")
        + f"{'ok':>4} {'failed':>6} {'max param err %':>16} {'torque err %':>13}"
    )
    for s in report.summary(result.rows):

        def cell(column: str, s: dict[str, Any] = s) -> str:
            v = s[column + "_median"]
            return "-" if v is None else f"{v:.3g}"

        print(
            f"{s['method']:>9} {s['noise']:>6g} {s['rate']:>6g} "
            + (f"{s['excitation_evaluations']:>6} " if budgets else "")
            + f"{s['ok']:>4} {s['failed']:>6} "
            f"{cell('max_param_error_percent'):>16} {cell('torque_rms_relative_percent'):>13}"
        )
    print(
        f"results in {out}/report.md, results.csv, results.json ({stats.cases} cases, "
        f"{stats.failed_cases} failed, {stats.elapsed_s:.1f} s, "
        f"{stats.cases_per_second:.2f} cases/s on {stats.engine})"
    )
    for name, e in result.figure_errors.items():
        common.error(f"figure {name} could not be drawn ({e}); the results are complete")
    if stats.failed_cases == stats.cases:
        errors = sorted({r["error"] for r in result.rows if r.get("error")})
        raise common.CliError(
            f"every case failed ({stats.cases}); first error: {errors[0] if errors else '?'} "
            f"(all errors in {out}/report.md)",
            code=common.EXIT_FAILED,
        )
    return common.EXIT_OK


def _oserror(e: Exception) -> str:
    if isinstance(e, OSError):
        return f"{e.strerror or e}" + (f": {e.filename}" if e.filename else "")
    return str(e)


def _rescue(result: Any, out: Path) -> Path | None:
    """Writes results.json where it can (beside --out, else the temporary folder) so that
    a run's computation is not lost to an unwritable --out; returns where, or None."""
    import os
    import tempfile

    name = f"{out.name or 'benchmark'}-results-{os.getpid()}.json"
    for folder in (out.absolute().parent, Path.cwd(), Path(tempfile.gettempdir())):
        with contextlib.suppress(OSError):
            return result.save_results(folder / name)
    return None
