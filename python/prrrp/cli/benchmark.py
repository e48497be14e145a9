"""``prrrp benchmark``: a Monte-Carlo benchmark of the estimators (seeds × noise scales ×
sampling rates × methods) on every core or a Dask cluster, into a folder of results.csv,
results.json, report.md and figures."""

from __future__ import annotations

import argparse
import contextlib
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from prrrp.cli.common import EXIT_OK, CliError, nonempty_path


def _floats(what: str) -> Any:
    def parse(text: str) -> list[float]:
        try:
            values = [float(x) for x in text.split(",") if x.strip()]
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"not a comma-separated list of numbers: {text!r}"
            ) from None
        if not values:
            raise argparse.ArgumentTypeError(f"no {what} given")
        return values

    return parse


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

    p = sub.add_parser(
        "benchmark",
        help="Monte-Carlo benchmark of the estimators on every core or a Dask cluster",
        description="For each case (seed × noise scale × sampling rate): excitation, "
        "closed-loop simulation, sensor noise, preprocessing, identification with each "
        "method, torque prediction on a second trajectory. Writes results.csv (one row per "
        "case × method), results.json, report.md and figures into DIR (built aside and "
        "swapped in whole). Deterministic per seed whatever the worker count or engine. "
        "A case whose worker dies or times out is retried once, then recorded as failed.",
    )
    p.add_argument(
        "--robot", metavar="ROBOT", help="robot file (.urdf or .toml); default: the paper's arm"
    )
    p.add_argument("--base", metavar="LINK", help="URDF: first link of the chain")
    p.add_argument("--tip", metavar="LINK", help="URDF: last link of the chain")
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
        "--duration", type=float, default=10.0, help="excitation length per case, s (default: 10)"
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
        "`pip install prrrp[cluster]`)",
    )
    p.add_argument(
        "--out",
        default="benchmark-out",
        type=nonempty_path,
        metavar="DIR",
        help="output directory (default: ./benchmark-out)",
    )
    p.set_defaults(func=run)


@contextlib.contextmanager
def _dask_executor(address: str) -> Iterator[Any]:
    try:
        from distributed import Client
    except ImportError:
        raise CliError("--dask needs dask.distributed: pip install 'prrrp[cluster]'") from None
    try:
        client = Client(address, timeout="10s")
    except (OSError, TimeoutError, ValueError) as e:
        raise CliError(f"--dask {address}: cannot connect to the scheduler ({e})") from None
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
    outdir._check(out.absolute())
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
            base=args.base,
            tip=args.tip,
        )
    result.save(out)
    stats = result.stats
    print(
        f"{'method':>9} {'noise':>6} {'rate':>6} {'ok':>4} {'failed':>6} "
        f"{'max param err %':>16} {'torque err %':>13}"
    )
    for s in report.summary(result.rows):

        def cell(column: str, s: dict[str, Any] = s) -> str:
            v = s[column + "_median"]
            return "-" if v is None else f"{v:.3g}"

        print(
            f"{s['method']:>9} {s['noise']:>6g} {s['rate']:>6g} {s['ok']:>4} {s['failed']:>6} "
            f"{cell('max_param_error_percent'):>16} {cell('torque_rms_relative_percent'):>13}"
        )
    print(
        f"results in {out}/report.md, results.csv, results.json ({stats.cases} cases, "
        f"{stats.failed_cases} failed, {stats.elapsed_s:.1f} s, "
        f"{stats.cases_per_second:.2f} cases/s on {stats.engine})"
    )
    return EXIT_OK
