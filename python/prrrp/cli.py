"""The ``prrrp`` command line (also ``python -m prrrp``).

Subcommands:

- ``prrrp reproduce [--out DIR] [--seed N]``: the paper's whole study (excitation, simulation,
  the four estimators, validation, sensitivity) → ``DIR/results.json``, ``DIR/report.md`` and
  the figures ``DIR/*.png``.
- ``prrrp simulate --out data.csv [--seed N] [--noise SCALE] [--duration S]``: an optimised
  excitation run on the simulated robot, written as a measurement file.
- ``prrrp identify DATA.csv [--method ls|adaline|hopfield|ekf|all] [--validate VAL.csv]
  [--out results.json]``: λ from a measurement file, optionally validated on another.

The measurement CSV format is documented in :mod:`prrrp.csvio`. Exit codes: 0 success,
1 a computation failed (e.g. an estimator diverged), 2 bad usage or bad input, 130
interrupted. Errors are one line on stderr, never a traceback.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import shutil
import signal
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, NoReturn

import numpy as np

import prrrp
from prrrp import csvio, paper

EXIT_OK = 0
EXIT_FAILED = 1
EXIT_USAGE = 2
EXIT_INTERRUPTED = 130

#: The core's default sensor noise (prrrp_core::SensorNoise::default): standard deviations
#: of the measured positions (m, rad) and generalised forces (N, N·m) per joint. ``--noise``
#: scales both.
DEFAULT_Q_NOISE = (1e-5, 1e-4, 1e-4, 1e-4, 1e-5)
DEFAULT_TAU_NOISE = (0.5, 0.03, 0.015, 0.007, 0.05)

METHOD_CHOICES = ("ls", "adaline", "hopfield", "ekf", "all")
METHOD_KEYS = {"ls": "least_squares", "adaline": "adaline", "hopfield": "hopfield", "ekf": "ekf"}


class CliError(Exception):
    """A user-facing failure: the message is printed as one line."""

    def __init__(self, message: str, code: int = EXIT_USAGE) -> None:
        super().__init__(message)
        self.code = code


# ---------------------------------------------------------------------------------- progress


class Progress:
    """Progress bars (tqdm) on stderr when it is a terminal; silent otherwise.

    Call as ``progress(stage, done, total)``; a new stage closes the previous bar.
    """

    def __init__(self, enabled: bool | None = None) -> None:
        self.enabled = sys.stderr.isatty() if enabled is None else enabled
        self._bar: Any = None
        self._stage: str | None = None

    def __call__(self, stage: str, done: int, total: int) -> None:
        if not self.enabled:
            return
        from tqdm import tqdm

        if stage != self._stage or self._bar is None:
            self.close()
            self._stage = stage
            size = shutil.get_terminal_size()
            self._bar = tqdm(
                total=max(int(total), 1),
                desc=f"{stage:<13}",
                file=sys.stderr,
                leave=False,
                # tqdm draws nothing on a terminal that reports a size of 0 × 0 (some
                # pseudo-terminals do): fall back to 80 × 24 then.
                ncols=size.columns or 80,
                nrows=size.lines or 24,
            )
        if total and self._bar.total != total:
            self._bar.total = int(total)
        self._bar.n = int(done)
        self._bar.refresh()

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None
            self._stage = None


# ---------------------------------------------------------------------------------- helpers


def _attr(obj: Any, name: str, default: Any = None) -> Any:
    """Field ``name`` of a result that may be a dict or an object."""
    if isinstance(obj, dict):
        return obj.get(name, default)
    return getattr(obj, name, default)


def _list(x: Any) -> Any:
    if x is None:
        return None
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, np.generic):
        return x.item()
    return x


def _json_default(x: Any) -> Any:
    if isinstance(x, np.ndarray | np.generic):
        return x.tolist()
    raise TypeError(f"not JSON serialisable: {type(x).__name__}")


def _dump_json(data: Any, path: Path) -> None:
    with path.open("w", encoding="utf-8") as f:
        json.dump(data, f, indent=1, default=_json_default, allow_nan=True)
        f.write("\n")


def _check_output_dir(path: Path) -> None:
    if path.is_dir():
        raise CliError(f"output {path} is a directory; give a file name")
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.is_dir():
        raise CliError(f"output directory {parent} does not exist")


# ---------------------------------------------------------------------------------- reproduce


def cmd_reproduce(args: argparse.Namespace) -> int:
    from prrrp import outdir, plots, report

    if not hasattr(prrrp, "run_study"):
        raise CliError("this build of prrrp has no run_study (reinstall the package)", EXIT_FAILED)
    out = Path(args.out)
    progress = Progress()

    # The folder is built aside and swapped in whole (outdir.write_dir): a failed or
    # interrupted run leaves the previous results exactly as they were.
    def build(tmp: Path) -> tuple[dict[str, Any], list[Path]]:
        try:
            results = prrrp.run_study(seed=args.seed, progress=progress)
        finally:
            progress.close()
        _dump_json(results, tmp / "results.json")
        (tmp / "report.md").write_text(report.render(results), encoding="utf-8")
        return results, plots.write_all(results, tmp)

    results, figures = outdir.write_dir(out, build)
    total = (results.get("timings_s") or {}).get("total")
    took = f" ({total:.1f} s)" if isinstance(total, int | float) else ""
    print(f"results in {out}/report.md, {out}/results.json and {len(figures)} figures{took}")
    return EXIT_OK


# ---------------------------------------------------------------------------------- simulate


def _noise(scale: float) -> tuple[Any, Any]:
    if scale == 1.0:
        return None, None  # the core's defaults
    return (
        scale * np.asarray(DEFAULT_Q_NOISE, dtype=float),
        scale * np.asarray(DEFAULT_TAU_NOISE, dtype=float),
    )


def cmd_simulate(args: argparse.Namespace) -> int:
    out = Path(args.out)
    _check_output_dir(out)
    if not (math.isfinite(args.noise) and args.noise >= 0):
        raise CliError(f"--noise must be a finite number >= 0, got {args.noise}")
    if args.duration is not None and not (math.isfinite(args.duration) and args.duration > 0):
        raise CliError(f"--duration must be a positive number of seconds, got {args.duration}")
    progress = Progress()
    try:
        excitation = prrrp.optimise_excitation(
            seed=args.seed,
            progress=lambda done, total, *_: progress("excitation", done, total),
        )
    finally:
        progress.close()
    duration = args.duration if args.duration is not None else _attr(excitation, "duration", 10.0)
    q_noise, tau_noise = _noise(args.noise)
    rec = prrrp.simulate_closed_loop(
        excitation, duration, q_noise=q_noise, tau_noise=tau_noise, seed=args.seed
    )
    text = csvio.format_measurements(rec["t"], rec["q_measured"], rec["tau_measured"])
    csvio.write_text_atomic(out, text)
    n = len(rec["t"])
    print(
        f"results in {out} ({n} samples over {duration:g} s; cond(W) of the excitation "
        f"{_attr(excitation, 'cond_initial'):.4g} -> {_attr(excitation, 'cond_final'):.4g})"
    )
    return EXIT_OK


# ---------------------------------------------------------------------------------- identify


def _load(path: str) -> dict[str, Any]:
    """Reads a measurement file and preprocesses it when q̇, q̈ are absent."""
    raw = csvio.read_measurements(path)
    if "qd" in raw:
        return {**raw, "preprocessed": False}
    try:
        data = prrrp.preprocess(raw["t"], raw["q"], raw["tau"])
    except prrrp.TooFewSamplesError as e:
        raise CliError(
            f"{path}: too few samples ({len(raw['t'])}) for the preprocessing, which trims "
            f"the filter's edge transient at each end: {e}"
        ) from None
    return {
        "t": np.asarray(_attr(data, "t")),
        "q": np.asarray(_attr(data, "q")),
        "qd": np.asarray(_attr(data, "qd")),
        "qdd": np.asarray(_attr(data, "qdd")),
        "tau": np.asarray(_attr(data, "tau")),
        "preprocessed": True,
    }


def _least_squares(data: dict[str, Any], path: str) -> dict[str, Any]:
    try:
        res = prrrp.least_squares(data["q"], data["qd"], data["qdd"], data["tau"])
    except prrrp.RankDeficientError as e:
        cond = getattr(e, "cond", float("inf"))
        rank = getattr(e, "rank", None)
        params = getattr(e, "params", prrrp.NPARAM)
        rank_text = f"rank {rank} of {params}, " if rank is not None else ""
        raise CliError(
            f"{path}: the data does not excite every parameter: the observation matrix W is "
            f"rank deficient ({rank_text}cond(W) = {cond:.3g}); record a richer motion "
            "(see `prrrp simulate`)"
        ) from None
    return {
        "method": "least_squares",
        "lambda": _list(_attr(res, "lam")),
        "std": _list(_attr(res, "std")),
        "rsd_percent": _list(_attr(res, "rsd_percent")),
        "cond": _list(_attr(res, "cond")),
        "sigma2": _list(_attr(res, "sigma2")),
    }


#: Passes over the data of the two neural networks (they learn slowly from one pass).
ADALINE_EPOCHS = 50
HOPFIELD_EPOCHS = 20
#: The iterative estimators start from this fraction of the paper robot's λ, so that they
#: have something to learn even on data of the paper robot (their bindings' default start
#: is the truth, λ of Table 3).
INITIAL_GUESS_FACTOR = 0.5


def _iterative(method: str, data: dict[str, Any]) -> dict[str, Any]:
    lam0 = INITIAL_GUESS_FACTOR * prrrp.Robot.paper().base_parameters()
    cols = (data["q"], data["qd"], data["qdd"], data["tau"])
    dt = float(np.median(np.diff(data["t"])))
    if method in ("adaline", "hopfield"):
        if method == "adaline":
            estimator = prrrp.Adaline(lam0)
            errors = estimator.train(*cols, ADALINE_EPOCHS)
        else:
            estimator = prrrp.Hopfield(lam0, dt=dt)
            errors = estimator.train(*cols, HOPFIELD_EPOCHS)
        if not np.all(np.isfinite(errors)):
            raise CliError(
                f"{method}: the equation error is not finite; the data holds values too "
                "large to compute with (remove or rescale those rows)"
            )
    else:
        estimator = prrrp.Ekf(lam0, dt=dt)
        estimator.run(*cols)
    return {"method": method, "lambda": _list(estimator.estimate), "initial_guess": lam0.tolist()}


ESTIMATORS: dict[str, Callable[[str, dict[str, Any], str], dict[str, Any]]] = {
    "least_squares": lambda m, d, p: _least_squares(d, p),
    "adaline": lambda m, d, p: _iterative(m, d),
    "hopfield": lambda m, d, p: _iterative(m, d),
    "ekf": lambda m, d, p: _iterative(m, d),
}


def _estimate(method: str, data: dict[str, Any], path: str) -> dict[str, Any]:
    """One estimator's result; an estimate that is not finite (data whose magnitudes
    overflow the arithmetic, e.g. τ = 1e308 on some rows) is a usage error (exit 2)."""
    try:
        result = ESTIMATORS[method](method, data, path)
    except prrrp.NonFiniteError as e:
        raise CliError(f"{path}: {method}: {_first_line(e)}") from None
    lam = np.asarray(result["lambda"], dtype=float)
    if not np.all(np.isfinite(lam)):
        raise CliError(
            f"{path}: {method}: the estimate is not finite; the data holds values too large "
            "to compute with (remove or rescale those rows)"
        )
    return result


def _validate(estimates: list[dict[str, Any]], data: dict[str, Any]) -> list[dict[str, Any]]:
    """Torque prediction on validation data: τ̂ = Φ(q, q̇, q̈)·λ̂ against the measured τ."""
    phi = prrrp.regressor(data["q"], data["qd"], data["qdd"])
    tau = np.asarray(data["tau"])
    tau_rms = np.sqrt(np.mean(tau**2, axis=0))
    out = []
    for e in estimates:
        err = phi @ np.asarray(e["lambda"], dtype=float) - tau
        rms = np.sqrt(np.mean(err**2, axis=0))
        rel = np.where(tau_rms > 0, 100.0 * rms / np.where(tau_rms > 0, tau_rms, 1.0), np.nan)
        out.append(
            {
                "method": e["method"],
                "torque_rms": rms.tolist(),
                "torque_relative_percent": rel.tolist(),
            }
        )
    return out


def _print_estimates(estimates: list[dict[str, Any]], truth: np.ndarray) -> None:
    header = ["λ", "unit"]
    for e in estimates:
        header.append(paper.METHOD_LABELS.get(e["method"], e["method"]))
        if e.get("std") is not None:
            header += ["σ", "%σ"]
    header.append("paper robot")
    rows = []
    for i in range(prrrp.NPARAM):
        row = [f"λ{i + 1}", paper.PARAMETER_UNITS[i]]
        for e in estimates:
            row.append(f"{e['lambda'][i]:.6g}")
            if e.get("std") is not None:
                row += [f"{e['std'][i]:.3g}", f"{e['rsd_percent'][i]:.3g}"]
        row.append(f"{truth[i]:.6g}")
        rows.append(row)
    _print_table(header, rows)
    for e in estimates:
        if e.get("cond") is not None:
            print(f"cond(W) = {e['cond']:.4g}; residual variance σ² = {e['sigma2']:.4g}")


def _print_table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> None:
    widths = [max(len(h), *(len(r[k]) for r in rows)) for k, h in enumerate(header)]
    print("  ".join(h.rjust(w) for h, w in zip(header, widths, strict=True)))
    for r in rows:
        print("  ".join(c.rjust(w) for c, w in zip(r, widths, strict=True)))


def cmd_identify(args: argparse.Namespace) -> int:
    out = Path(args.out) if args.out else None
    if out is not None:
        _check_output_dir(out)
    data = _load(args.data)
    val = _load(args.validate) if args.validate else None
    methods = list(paper.METHODS) if args.method == "all" else [METHOD_KEYS[args.method]]
    progress = Progress()
    estimates = []
    try:
        for k, method in enumerate(methods):
            progress("identify", k, len(methods))
            estimates.append(_estimate(method, data, args.data))
        progress("identify", len(methods), len(methods))
    finally:
        progress.close()
    truth = prrrp.Robot.paper().base_parameters()
    print(
        f"{args.data}: {len(data['t'])} samples"
        + (" (after preprocessing)" if data["preprocessed"] else "")
    )
    _print_estimates(estimates, truth)
    validation = None
    if val is not None:
        validation = _validate(estimates, val)
        print(f"\nvalidation on {args.validate}: torque-prediction RMS per joint")
        header = [
            "method",
            *(f"{j} ({u})" for j, u in zip(paper.FORCES, paper.FORCE_UNITS, strict=True)),
        ]
        rows = [
            [
                paper.METHOD_LABELS.get(v["method"], v["method"]),
                *(f"{x:.4g}" for x in v["torque_rms"]),
            ]
            for v in validation
        ]
        _print_table(header, rows)
    if out is not None:
        result = {
            "data": str(args.data),
            "samples": len(data["t"]),
            "preprocessed": data["preprocessed"],
            "estimates": estimates,
            "validation": (
                {"data": str(args.validate), "samples": len(val["t"]), "methods": validation}
                if val is not None
                else None
            ),
        }
        csvio.write_atomic(out, lambda p: _dump_json(result, p))
        print(f"results in {out}")
    return EXIT_OK


# ---------------------------------------------------------------------------------- parser


def _seed(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
    if not 0 <= value < 2**64:
        raise argparse.ArgumentTypeError(f"must be between 0 and 2^64 - 1, got {value}")
    return value


class _Parser(argparse.ArgumentParser):
    """Usage errors in one line on stderr (argparse prints the whole usage first)."""

    def error(self, message: str) -> NoReturn:
        _error(f"{message} (see `{self.prog} --help`)")
        raise SystemExit(EXIT_USAGE)


def _nonempty_path(text: str) -> str:
    if not text.strip():
        raise argparse.ArgumentTypeError("an empty path")
    return text


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="prrrp",
        description="Dynamic parameter identification of the PRRRP robot (Urrea & Pascal 2017).",
        epilog="Run `prrrp reproduce` for the paper's whole study; `prrrp COMMAND --help` "
        "for each command.",
    )
    parser.add_argument("--version", action="version", version=f"prrrp {prrrp.__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)

    p = sub.add_parser(
        "reproduce",
        help="run the paper's whole study: tables, figures, results.json",
        description="Runs the paper's study (excitation optimisation, closed-loop simulation, "
        "least squares, Adaline, Hopfield, EKF, validation, sensitivity) and writes "
        "results.json, report.md and PNG figures into DIR. DIR is built aside and swapped "
        "in whole when the run succeeds; a failed or interrupted run leaves it as it was. "
        "An existing DIR must be empty or an earlier prrrp output.",
    )
    p.add_argument(
        "--out",
        default="prrrp-out",
        type=_nonempty_path,
        metavar="DIR",
        help="output directory (default: ./prrrp-out)",
    )
    p.add_argument("--seed", type=_seed, default=0, help="random seed (default: 0)")
    p.set_defaults(func=cmd_reproduce)

    p = sub.add_parser(
        "simulate",
        help="write a simulated measurement file (CSV)",
        description="Optimises an excitation trajectory, runs it on the simulated paper robot "
        "under PD control with sensor noise, and writes the measured t, q1..q5, tau1..tau5 as "
        "CSV (SI units: s, m/rad, N/N·m) for `prrrp identify`.",
    )
    p.add_argument(
        "--out", required=True, type=_nonempty_path, metavar="DATA.csv", help="CSV file to write"
    )
    p.add_argument(
        "--seed", type=_seed, default=0, help="seed of the excitation and noise (default: 0)"
    )
    p.add_argument(
        "--noise",
        type=float,
        default=1.0,
        metavar="SCALE",
        help="multiplies the default sensor noise (std 1e-5 m / 1e-4 rad on positions, "
        "0.5 N .. 0.007 N·m on forces); 0 = noise-free (default: 1)",
    )
    p.add_argument(
        "--duration",
        type=float,
        default=None,
        metavar="S",
        help="simulated time, s (default: the excitation's period, 10 s)",
    )
    p.set_defaults(func=cmd_simulate)

    p = sub.add_parser(
        "identify",
        help="estimate λ from a measurement file (CSV)",
        description="Reads DATA.csv (columns t, q1..q5, tau1..tau5, optionally qd1..qd5 and "
        "qdd1..qdd5; SI units), filters and differentiates it when velocities and "
        "accelerations are absent, runs the chosen estimators and prints λ. With --validate, "
        "predicts the torques of VAL.csv with each estimate.",
    )
    p.add_argument("data", metavar="DATA.csv", help="measurement file")
    p.add_argument(
        "--method",
        choices=METHOD_CHOICES,
        default="ls",
        help="ls = least squares (with σ and cond(W)), adaline, hopfield, ekf, or all "
        "(default: ls)",
    )
    p.add_argument("--validate", metavar="VAL.csv", help="validation measurement file")
    p.add_argument(
        "--out", type=_nonempty_path, metavar="RESULTS.json", help="write the estimates as JSON"
    )
    p.set_defaults(func=cmd_identify)
    return parser


def _oserror_message(e: OSError) -> str:
    what = e.filename if e.filename is not None else ""
    reason = e.strerror or str(e)
    if isinstance(e, FileNotFoundError):
        return f"{what}: no such file or directory"
    return f"{what}: {reason}" if what else reason


def _on_sigterm(signum: int, _frame: Any) -> None:
    # An exception, unlike the default action, unwinds: temporary output is removed and
    # running computations stop (the bindings poll for signals).
    raise SystemExit(128 + signum)


def main(argv: Sequence[str] | None = None) -> int:
    """Runs the command line; returns the exit code (argparse exits itself on usage errors)."""
    args = build_parser().parse_args(argv)
    with contextlib.suppress(ValueError):  # not the main thread: keep the default
        signal.signal(signal.SIGTERM, _on_sigterm)
    try:
        return int(args.func(args))
    except CliError as e:
        _error(str(e))
        return e.code
    except KeyboardInterrupt:
        _error("interrupted")
        return EXIT_INTERRUPTED
    except OSError as e:
        _error(_oserror_message(e))
        return EXIT_USAGE
    except prrrp.RankDeficientError as e:
        _error(
            f"the data does not excite every parameter (rank deficient, cond(W) = "
            f"{getattr(e, 'cond', float('inf')):.3g}): {_first_line(e)}"
        )
        return EXIT_USAGE
    except (prrrp.InvalidInputError, ValueError) as e:
        _error(_first_line(e))
        return EXIT_USAGE
    except prrrp.PrrrpError as e:
        _error(_first_line(e))
        return EXIT_FAILED


def _first_line(e: BaseException) -> str:
    text = str(e).strip() or type(e).__name__
    return text.splitlines()[0]


def _error(message: str) -> None:
    print(f"prrrp: error: {message}", file=sys.stderr)


if __name__ == "__main__":
    sys.exit(main())
