"""``prrrp identify``: base parameters from a measurement file, printed and optionally written
as JSON, and validated on another file."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

import prrrp
from prrrp import csvio, paper, workflow
from prrrp.cli import identify_robot
from prrrp.cli.common import (
    EXIT_OK,
    CliError,
    Progress,
    as_list,
    attr,
    check_output_file,
    dump_json,
    first_line,
    nonempty_path,
    print_table,
)

#: Methods of the paper's arm (without --robot).
PAPER_METHODS = ("ls", "adaline", "hopfield", "ekf", "all")
METHOD_CHOICES = (*workflow.METHODS, "all")
METHOD_KEYS = {"ls": "least_squares", "adaline": "adaline", "hopfield": "hopfield", "ekf": "ekf"}


def add_parser(sub: Any) -> None:
    p = sub.add_parser(
        "identify",
        help="identify a robot's dynamic parameters from a measurement file",
        description="Without --robot: the paper's arm. Reads DATA.csv (columns t, q1..q5, "
        "tau1..tau5, optionally qd1..qd5 and qdd1..qdd5; SI units), filters and "
        "differentiates it when velocities and accelerations are absent, runs the chosen "
        "estimators and prints λ; with --validate, predicts the torques of VAL.csv with each "
        "estimate. With --robot ROBOT (.urdf or .toml): any arm, from a CSV (t, q1..qN, "
        "tau1..tauN, optional qd1..qdN, qdd1..qddN; time stamps may repeat) or a ROS 2 bag "
        "(sensor_msgs/JointState matched by joint name); writes DIR/model.json "
        "(DIR/model-<method>.json for --method all), DIR/report.md and figures.",
    )
    p.add_argument("data", metavar="DATA", help="measurement file (CSV, or a bag with --robot)")
    p.add_argument(
        "--method",
        choices=METHOD_CHOICES,
        default="ls",
        help="ls = least squares (with σ and cond(W)), wls = weighted, rls, adaline, "
        "hopfield, ekf, physical (physically consistent), or all (default: ls; the paper's "
        "arm: ls, adaline, hopfield, ekf, all)",
    )
    p.add_argument("--validate", metavar="VAL.csv", help="validation measurement file")
    p.add_argument(
        "--out",
        type=nonempty_path,
        metavar="RESULTS.json|DIR",
        help="the paper's arm: write the estimates as JSON; with --robot: the output folder "
        "(built aside and swapped in whole)",
    )
    identify_robot.add_arguments(p)
    p.set_defaults(func=run)


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
        "t": np.asarray(attr(data, "t")),
        "q": np.asarray(attr(data, "q")),
        "qd": np.asarray(attr(data, "qd")),
        "qdd": np.asarray(attr(data, "qdd")),
        "tau": np.asarray(attr(data, "tau")),
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
        "lambda": as_list(attr(res, "lam")),
        "std": as_list(attr(res, "std")),
        "rsd_percent": as_list(attr(res, "rsd_percent")),
        "cond": as_list(attr(res, "cond")),
        "sigma2": as_list(attr(res, "sigma2")),
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
    return {"method": method, "lambda": as_list(estimator.estimate), "initial_guess": lam0.tolist()}


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
        raise CliError(f"{path}: {method}: {first_line(e)}") from None
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
    print_table(header, rows)
    for e in estimates:
        if e.get("cond") is not None:
            print(f"cond(W) = {e['cond']:.4g}; residual variance σ² = {e['sigma2']:.4g}")


def run(args: argparse.Namespace) -> int:
    if args.robot:
        return identify_robot.run(args)
    if args.method not in PAPER_METHODS:
        raise CliError(
            f"--method {args.method} needs --robot (the paper's arm has {PAPER_METHODS})"
        )
    out = Path(args.out) if args.out else None
    if out is not None:
        check_output_file(out)
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
    return EXIT_OK
