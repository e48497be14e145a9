"""The previous release's spellings, kept for one release: each still does what it did,
then says on stderr what to write instead.

- ``prrrp identify DATA [--out RESULTS.json]`` without ``--robot``: the paper's arm in its
  closed form, λ printed (and written as one JSON file);
- ``prrrp simulate --out DATA.csv`` without ``--robot``/``--trajectory``: the paper's
  optimised excitation run on its closed-form model, one CSV;
- ``prrrp simulate|excite ... --out FILE.csv``: one CSV file instead of a folder.

The rule (:func:`identify_spelling`, :func:`file_spelling`) is documented in each command's
help epilogue and the README. Remove this module, and its branches in the commands, in the
release after."""

from __future__ import annotations

import argparse
import math
import shlex
import sys
from pathlib import Path
from typing import Any

import numpy as np

import prrrp
from prrrp import csvio, lambda_view, outdir, paper
from prrrp.cli.common import (
    EXIT_OK,
    CliError,
    Progress,
    attr,
    check_output_file,
    dump_json,
    first_line,
    options,
    print_table,
)

#: The one-line rule each command's help epilogue gives.
IDENTIFY_RULE = (
    "Deprecated (removed in the next release): with no --robot and an --out ending in .json, "
    "or no --out at all, the previous release's closed-form paper arm runs (λ printed, one "
    "JSON file)."
)
FILE_RULE = (
    "Deprecated (removed in the next release): an --out ending in .csv writes that one file, "
    "as the previous release did."
)
SIMULATE_RULE = (
    "Deprecated (removed in the next release): an --out ending in .csv writes that one file, "
    "as the previous release did (without --robot and --trajectory: its closed-form paper arm)."
)


def identify_spelling(args: argparse.Namespace) -> bool:
    """The previous release's ``prrrp identify`` of the paper's closed form: no ``--robot``
    and an ``--out`` that is absent or ends in ``.json`` (that release's JSON file; the
    general path writes a folder)."""
    return not args.robot and (not args.out or str(args.out).lower().endswith(".json"))


def file_spelling(args: argparse.Namespace) -> bool:
    """The previous release's ``prrrp simulate``/``excite``: an ``--out`` ending in ``.csv``
    (that release wrote one CSV file there; today ``--out`` is a folder)."""
    return str(args.out).lower().endswith(".csv")


def folder_for(out: str) -> str:
    """The folder a new spelling writes instead of the file ``out``: its name without the
    suffix (``runs/data.csv`` → ``runs/data``)."""
    path = Path(out)
    return str(path.with_suffix("")) if path.suffix else str(path) + "-out"


def notice(new: list[str], what: str) -> None:
    """Tells, on stderr after a successful run (an error stays one line), what to write
    instead of the spelling just used."""
    command = " ".join(shlex.quote(a) for a in new)
    print(
        f"prrrp: deprecated: this spelling is removed in the next release; use `{command}` "
        f"({what})",
        file=sys.stderr,
    )


def option(args: argparse.Namespace, name: str, default: Any = None) -> list[str]:
    """``--name VALUE`` as the user gave it, or nothing when it is the default."""
    value = getattr(args, name, default)
    if value is None or value == default:
        return []
    return [f"--{name.replace('_', '-')}", f"{value:g}" if isinstance(value, float) else str(value)]


def robot_options(args: argparse.Namespace) -> list[str]:
    return [*option(args, "robot"), *option(args, "base"), *option(args, "tip")]


#: The one output file of a deprecated spelling: not a folder, in an existing folder.
check_file = check_output_file


def check_out(args: argparse.Namespace, old: bool) -> Path:
    """``--out`` checked before any work: the one file of the previous release's spelling
    (``old``, see :func:`file_spelling`), else the output folder (:func:`prrrp.outdir.check`)."""
    out = Path(args.out)
    if old:
        check_file(out)
    else:
        outdir.check(out)
    return out


#: Methods of the paper's arm in the closed-form spelling.
PAPER_METHODS = ("wls", "ls", "adaline", "hopfield", "ekf", "all")
METHOD_KEYS = {
    "wls": "weighted_least_squares",
    "ls": "least_squares",
    "adaline": "adaline",
    "hopfield": "hopfield",
    "ekf": "ekf",
}
#: What ``--method all`` runs on the paper's arm: the default, then the paper's four.
PAPER_ALL = ("weighted_least_squares", *paper.METHODS)
#: The method names of ``prrrp.identify`` by result key.
METHOD_NAMES = {v: k for k, v in METHOD_KEYS.items()}


def _load(path: str) -> dict[str, Any]:
    """Reads a measurement file and preprocesses it when q̇, q̈ are absent; keeps the
    measured time stamps and torque (``raw_t``, ``raw_tau``) that validation scores
    against."""
    raw = csvio.read_measurements(path)
    if "qd" in raw:
        return {**raw, "preprocessed": False, "raw_t": raw["t"], "raw_tau": raw["tau"]}
    try:
        data = prrrp.preprocess(raw["t"], raw["q"], raw["tau"])
    except prrrp.TooFewSamplesError as e:
        raise CliError(
            f"{path}: too few samples ({len(raw['t'])}) for the preprocessing, which trims "
            f"the filter's edge transient at each end: {e}"
        ) from None
    return {
        "t": np.asarray(attr(data, "t")),
        "q": np.asarray(attr(data, "q")),
        "qd": np.asarray(attr(data, "qd")),
        "qdd": np.asarray(attr(data, "qdd")),
        "tau": np.asarray(attr(data, "tau")),
        "preprocessed": True,
        "raw_t": raw["t"],
        "raw_tau": raw["tau"],
    }


def _rank_deficient(path: str, e: Exception) -> CliError:
    cond = getattr(e, "cond", float("inf"))
    rank = getattr(e, "rank", None)
    params = getattr(e, "params", None)
    rank_text = f"rank {rank} of {params}, " if rank is not None and params is not None else ""
    return CliError(
        f"{path}: the data does not excite every parameter: the observation matrix W is "
        f"rank deficient ({rank_text}cond(W) = {cond:.3g}); record a richer motion "
        "(see `prrrp simulate`)"
    )


#: Moved to :mod:`prrrp.lambda_view` (the λ view of any ``paper`` model).
lambda_map = lambda_view.lambda_map


def _identify(method: str, data: dict[str, Any], path: str) -> dict[str, Any]:
    """``prrrp.identify(prrrp.Robot.paper(), data, method)`` with its defaults (the same
    as ``prrrp identify --robot``), reported in the paper's λ (:func:`lambda_map`), with
    σ from the model's covariance where the method gives one (LS, EKF)."""
    ds = prrrp.Dataset(data["t"], data["q"], data["qd"], data["qdd"], data["tau"])
    try:
        model = prrrp.identify(prrrp.Robot.paper(), ds, method)
    except prrrp.RankDeficientError as e:
        raise _rank_deficient(path, e) from None
    t = lambda_map()
    lam = t @ np.asarray(model.beta)
    out: dict[str, Any] = {
        "method": METHOD_KEYS[method],
        "lambda": lam.tolist(),
        "converged": bool(model.converged),
        "epochs": model.epochs,
    }
    cov = model.covariance
    if cov is not None:
        std = np.sqrt(np.maximum(np.diag(t @ np.asarray(cov) @ t.T), 0.0))
        out["std"] = std.tolist()
        out["rsd_percent"] = (100.0 * std / np.abs(lam)).tolist()
    if method in ("ls", "wls"):
        n = len(data["t"])
        rms = np.asarray(model.residual_rms)
        out["cond"] = model.cond
        out["sigma2"] = float(n * np.sum(rms**2) / (n * prrrp.NDOF - len(model.beta)))
    return out


def _estimate(method: str, data: dict[str, Any], path: str) -> dict[str, Any]:
    """One estimator's result; an estimate that is not finite (data whose magnitudes
    overflow the arithmetic, e.g. τ = 1e308 on some rows) is a usage error (exit 2)."""
    try:
        result = _identify(method, data, path)
    except prrrp.NonFiniteError as e:
        raise CliError(f"{path}: {method}: {first_line(e)}") from None
    lam = np.asarray(result["lambda"], dtype=float)
    if not np.all(np.isfinite(lam)):
        raise CliError(
            f"{path}: {method}: the estimate is not finite; the data holds values too large "
            "to compute with (remove or rescale those rows)"
        )
    return result


def _validate(estimates: list[dict[str, Any]], data: dict[str, Any]) -> list[dict[str, Any]]:
    """Torque prediction on validation data: τ̂ = Φ(q, q̇, q̈)·λ̂ on the (processed) states,
    mapped to the measured rows, against the torque as measured there (never the low-passed
    torque the preprocessing makes). Rows in the filter's edge transient (outside the
    processed span) are not scored: :func:`_scored_rows`."""
    phi = prrrp.regressor(data["q"], data["qd"], data["qdd"])
    rows = _scored_rows(data)
    t_rows, tau = data["raw_t"][rows], data["raw_tau"][rows]
    tau_rms = np.sqrt(np.mean(tau**2, axis=0))
    out = []
    for e in estimates:
        pred = phi @ np.asarray(e["lambda"], dtype=float)
        at_rows = np.column_stack(
            [np.interp(t_rows, data["t"], pred[:, j]) for j in range(pred.shape[1])]
        )
        err = at_rows - tau
        rms = np.sqrt(np.mean(err**2, axis=0))
        rel = np.where(tau_rms > 0, 100.0 * rms / np.where(tau_rms > 0, tau_rms, 1.0), np.nan)
        out.append(
            {
                "method": e["method"],
                "torque_rms": rms.tolist(),
                "torque_relative_percent": rel.tolist(),
                "rows_scored": int(rows.sum()),
                "rows": len(rows),
            }
        )
    return out


def _scored_rows(data: dict[str, Any]) -> np.ndarray:
    """The measured rows a prediction is scored at: those within the processed data's time
    span (the preprocessing trims the filter's edge transient at each end)."""
    t = data["raw_t"]
    return (t >= data["t"][0]) & (t <= data["t"][-1])


def _label(e: dict[str, Any]) -> str:
    """The method's column title; a method that did not meet its stopping rule is flagged
    on every number it prints, so that it is not read as a converged estimate."""
    label = paper.METHOD_LABELS.get(e["method"], e["method"])
    return label if e.get("converged", True) else f"{label} (NOT CONVERGED)"


def _print_estimates(estimates: list[dict[str, Any]], truth: np.ndarray) -> None:
    header = ["λ", "unit"]
    for e in estimates:
        header.append(_label(e))
        if e.get("std") is not None:
            header += ["σ", "%σ"]
    header.append("paper robot")
    rows = []
    for i in range(prrrp.NPARAM):
        row = [f"λ{i + 1}", paper.PARAMETER_UNITS[i]]
        for e in estimates:
            mark = "" if e.get("converged", True) else "?"
            row.append(f"{e['lambda'][i]:.6g}{mark}")
            if e.get("std") is not None:
                row += [f"{e['std'][i]:.3g}", f"{e['rsd_percent'][i]:.3g}"]
        row.append(f"{truth[i]:.6g}")
        rows.append(row)
    print_table(header, rows)
    status = [
        [
            _label(e),
            "yes" if e.get("converged", True) else "NO",
            "-" if e.get("epochs") is None else str(e["epochs"]),
        ]
        for e in estimates
    ]
    print_table(["method", "converged", "epochs"], status)
    for e in estimates:
        if not e.get("converged", True):
            print(
                f"warning: {_label(e)} did not meet its stopping rule within its epoch cap; "
                "its λ (marked ?) is not at the method's optimum"
            )
    for e in estimates:
        if e.get("cond") is not None:
            print(
                f"{_label(e)}: cond(W) = {e['cond']:.4g}; "
                f"torque residual variance σ² = {e['sigma2']:.4g}"
            )


def identify(args: argparse.Namespace) -> int:
    """``prrrp identify DATA [--out RESULTS.json]`` without ``--robot`` as the previous
    release ran it: λ of the paper's closed form printed, optionally written as JSON."""
    robot_only = [
        f"--{name.replace('_', '-')}"
        for name, default in (
            ("cutoff", None),
            ("rate", None),
            ("decimate", None),
            ("friction", "viscous,coulomb,offset"),
            ("coulomb_scale", "auto"),
            ("ekf_prior_width", None),
            ("ekf_noise", None),
        )
        if getattr(args, name) != default
    ]
    if robot_only:
        raise CliError(
            f"{' and '.join(robot_only)} {'apply' if len(robot_only) > 1 else 'applies'} to "
            "--robot ROBOT (the closed-form paper arm of the deprecated spelling is "
            "preprocessed at its own 5 Hz and has no friction terms); write "
            "--robot paper --out DIR"
        )
    if args.method not in PAPER_METHODS:
        raise CliError(
            f"--method {args.method} needs --robot (the deprecated closed-form paper arm has "
            f"{options(PAPER_METHODS)}); write --robot paper --out DIR"
        )
    out = Path(args.out) if args.out else None
    if out is not None:
        check_output_file(out)
    data = _load(args.data)
    val = _load(args.validate) if args.validate else None
    methods = list(PAPER_ALL) if args.method == "all" else [METHOD_KEYS[args.method]]
    methods = [METHOD_NAMES[m] for m in methods]
    progress = Progress()
    estimates: list[dict[str, Any]] = []
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
        scored = _scored_rows(val)
        edge = "" if scored.all() else f"; {int((~scored).sum())} in the filter's edge transient"
        print(
            f"\nvalidation on {args.validate}: torque-prediction error per joint against the "
            f"measured torque (RMS, and % of the measured torque's RMS; {int(scored.sum())} of "
            f"{len(scored)} rows scored{edge})"
        )
        header = [
            "method",
            *(f"{j} ({u})" for j, u in zip(paper.FORCES, paper.FORCE_UNITS, strict=True)),
        ]
        rows = [
            [
                paper.METHOD_LABELS.get(v["method"], v["method"]),
                *(
                    f"{x:.4g} ({p:.3g}%)"
                    for x, p in zip(v["torque_rms"], v["torque_relative_percent"], strict=True)
                ),
            ]
            for v in validation
        ]
        print_table(header, rows)
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
        csvio.write_atomic(out, lambda p: dump_json(result, p))
        print(f"results in {out}")
    new = ["prrrp", "identify", args.data]
    new += option(args, "method", "wls") + option(args, "validate")
    new += ["--robot", "paper", "--out", folder_for(str(out)) if out is not None else "DIR"]
    notice(new, "a folder: model.json, report.md, figures")
    return EXIT_OK


# ---------------------------------------------------------------------------------- simulate

#: The core's default sensor noise (prrrp_core::SensorNoise::default): standard deviations
#: of the measured positions (m, rad) and generalised forces (N, N·m) per joint. ``--noise``
#: scales both.
DEFAULT_Q_NOISE = (1e-5, 1e-4, 1e-4, 1e-4, 1e-5)
DEFAULT_TAU_NOISE = (0.5, 0.03, 0.015, 0.007, 0.05)


def _noise(scale: float) -> tuple[Any, Any]:
    if scale == 1.0:
        return None, None  # the core's defaults
    return (
        scale * np.asarray(DEFAULT_Q_NOISE, dtype=float),
        scale * np.asarray(DEFAULT_TAU_NOISE, dtype=float),
    )


def reference_for(excitation: Any, duration: float) -> Any:
    """The reference a recording of ``duration`` s follows: the excitation itself, or, for a
    recording longer than it, the excitation played forward and backward in turn (it
    starts and ends at rest, so the reflection is C² and stays within the same limits;
    a longer recording sees the same motion again rather than a gentler one)."""
    if duration > excitation.duration * (1 + 1e-9):
        return excitation.reflected()
    return excitation


def simulate_paper(args: argparse.Namespace) -> int:
    """``prrrp simulate --out DATA.csv`` without ``--robot``/``--trajectory`` as the previous
    release ran it: the paper's optimised excitation on its closed-form model, one CSV."""
    out = Path(args.out)
    check_output_file(out)
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
    duration = args.duration if args.duration is not None else attr(excitation, "duration", 10.0)
    q_noise, tau_noise = _noise(args.noise)
    rec = prrrp.simulate_closed_loop(
        reference_for(excitation, duration),
        duration,
        q_noise=q_noise,
        tau_noise=tau_noise,
        seed=args.seed,
    )
    text = csvio.format_measurements(rec["t"], rec["q_measured"], rec["tau_measured"])
    csvio.write_text_atomic(out, text)
    n = len(rec["t"])
    print(
        f"results in {out} ({n} samples over {duration:g} s; cond(W) of the excitation "
        f"{attr(excitation, 'cond_initial'):.4g} -> {attr(excitation, 'cond_final'):.4g})"
    )
    new = ["prrrp", "simulate", *option(args, "seed", 0), *option(args, "noise", 1.0)]
    new += [*option(args, "duration"), "--robot", "paper", "--out", folder_for(args.out)]
    notice(new, "a folder: the designed trajectory.csv and the measured data.csv")
    return EXIT_OK
