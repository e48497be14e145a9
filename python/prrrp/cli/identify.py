"""``prrrp identify DATA [--robot ROBOT] --out DIR``: a robot (a URDF/TOML file, or the
built-in ``paper``, the default) and a log (CSV or ROS 2 bag) → ``DIR/model.json``,
``DIR/report.md`` and figures. The previous release's closed-form spelling is dispatched to
:mod:`prrrp.cli.deprecated`."""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

import prrrp
from prrrp import (
    bags,
    drawing,
    drives,
    lambda_view,
    measurements,
    model_report,
    outdir,
    prediction,
    workflow,
)
from prrrp import payload as payloads
from prrrp.cli import common, deprecated
from prrrp.measurements import measurements_to_dataset, read_measurements

#: The core's default cut-off (DEFAULT_LOG_CUTOFF_HZ), Hz, before the cap at a tenth of the
#: output rate.
DEFAULT_CUTOFF_HZ = 10.0


def add_parser(sub: Any) -> None:
    p = sub.add_parser(
        "identify",
        help="identify a robot's dynamic parameters from a measurement log",
        description="Reads DATA, a CSV (t, q1..qN, tau1..tauN, optionally qd1..qdN and "
        "qdd1..qddN; SI units; time stamps may repeat) or a ROS 2 bag (sensor_msgs/JointState "
        "matched by joint name), resamples, filters and differentiates it, identifies the "
        "robot's base parameters and friction with the chosen method, and writes "
        "DIR/model.json (for `prrrp predict`; DIR/model-<method>.json each for --method "
        "all), DIR/report.md and figures; with --validate, the torque errors on another log.",
        epilog=deprecated.IDENTIFY_RULE,
    )
    p.add_argument("data", metavar="DATA", help="measurement log (CSV or ROS 2 bag)")
    p.add_argument(
        "--method",
        choices=(*workflow.METHODS, "all"),
        default=workflow.DEFAULT_METHOD,
        help="wls = least squares with each joint weighted by its residual noise, ls = "
        "ordinary least squares (the paper's), rls = recursive least squares, adaline = "
        "linear network (delta rule), hopfield = recurrent network, ekf = extended Kalman "
        "filter, physical = physically consistent (every link a rigid body), or all = every "
        "method compared (model-<method>.json each, model.json the default's) "
        f"(default: {workflow.DEFAULT_METHOD})",
    )
    p.add_argument(
        "--validate",
        metavar="VAL",
        help="validation log: each model's torque error against its measured torque "
        "(default: none)",
    )
    p.add_argument(
        "--out",
        type=common.nonempty_path,
        metavar="DIR",
        help="the output folder (built aside and swapped in whole; a symbolic link is "
        "followed and kept) (required, no default)",
    )
    add_arguments(p)
    p.set_defaults(func=run)


def add_arguments(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("robot and log")
    common.add_robot_arguments(g)
    g.add_argument(
        "--friction",
        metavar="TERMS",
        default="viscous,coulomb,offset",
        help="friction terms to identify, comma-separated from viscous, coulomb, offset, or "
        "'none' (default: viscous,coulomb,offset)",
    )
    g.add_argument(
        "--coulomb-scale",
        metavar="auto|0|V",
        default="auto",
        help="speed scale v_s (rad/s) of the smooth Coulomb term fc·tanh(q̇/v_s): auto = "
        "chosen from the data by cross-validation, 0 = exact sign (default: auto)",
    )
    g.add_argument(
        "--armature",
        action="store_true",
        help="identify one rotor inertia (armature) per actuator: Ia·q̈ₘ through the coupling "
        "of the robot file's [actuators] (default: as the robot file says)",
    )
    common.add_drive_gains_argument(g, "none, the log has torques tau1..tauN")
    g.add_argument(
        "--payload-run",
        metavar="LOADED",
        help="identify the drive gains (Gautier & Briot): DATA and LOADED are current logs "
        "(i1..iN) of the same trajectory without and with a payload of --payload-mass at the "
        "tip; writes the gains with σ into model.json (instrumental variables, unbiased by "
        "the currents' noise), the arm in N·m and DIR/payload.json (default: none, the "
        "gains are given or the log has torques)",
    )
    g.add_argument(
        "--payload-mass",
        type=common.number,
        metavar="KG",
        help="the known mass of the payload of --payload-run (kg) (default: none; required "
        "with --payload-run)",
    )
    common.add_motor_side_argument(g, "joint side")
    g.add_argument(
        "--cutoff",
        type=common.number,
        metavar="HZ",
        help="low-pass cut-off of the log, Hz; shapes the signals identification fits, "
        "never the torque errors (scored against the measured torque) (default: "
        f"min({DEFAULT_CUTOFF_HZ:g} Hz, output rate/10))",
    )
    g.add_argument(
        "--rate",
        type=common.number,
        metavar="HZ",
        help="resampling rate of the log, Hz (default: the log's median rate, or the "
        "smallest whole multiple of --decimate at or above it)",
    )
    g.add_argument(
        "--decimate",
        type=common.number,
        metavar="HZ",
        help="output rate after filtering, Hz (default: none, every resampled sample kept)",
    )
    g.add_argument(
        "--topic",
        default=bags.DEFAULT_TOPIC,
        help=f"JointState topic of a ROS 2 bag (default: {bags.DEFAULT_TOPIC})",
    )
    g.add_argument(
        "--ekf-prior-width",
        type=common.number,
        metavar="W",
        help="ekf: the filter starts from the weighted least-squares fit with covariance "
        "W²·(its covariance); smaller W keeps the filter closer to the fit (default 3)",
    )
    g.add_argument(
        "--ekf-noise",
        type=common.number,
        metavar="F",
        help="ekf: factor on the measurement noise of positions (1e-3 rad) and velocities "
        "(1e-2 rad/s); raise it when the filter diverges on noisy data (default 1)",
    )


def _ekf_settings(args: argparse.Namespace) -> dict[str, float]:
    """The EKF's settings from --ekf-prior-width and --ekf-noise (checked)."""
    out: dict[str, float] = {}
    common.check_factor("--ekf-prior-width", args.ekf_prior_width)
    common.check_factor("--ekf-noise", args.ekf_noise)
    given = [
        f
        for f, v in [("--ekf-prior-width", args.ekf_prior_width), ("--ekf-noise", args.ekf_noise)]
        if v is not None
    ]
    if given and args.method not in ("ekf", "all"):
        raise common.CliError(f"{given[0]} is an ekf setting: it needs --method ekf (or all)")
    if args.ekf_prior_width is not None:
        out["least_squares_prior_width"] = args.ekf_prior_width
    if args.ekf_noise is not None:
        out["position_noise"] = 1e-3 * args.ekf_noise
        out["velocity_noise"] = 1e-2 * args.ekf_noise
    return out


def run(args: argparse.Namespace) -> int:
    if deprecated.identify_spelling(args):
        return deprecated.identify(args)
    if not args.out:
        raise common.CliError("--out DIR is required (the model, report and figures)")
    out = Path(args.out)
    outdir.check(out)
    if args.payload_run or args.payload_mass is not None:
        return _run_drive_gains(args, *_setup(args), out)
    # The figures are drawn natively (prrrp.canvas): no matplotlib to import or to wait for.
    return _identify(args, out)


def _setup(args: argparse.Namespace) -> tuple[Any, str | float, dict[str, Any]]:
    """The robot, the Coulomb speed scale and the preprocessing settings of the command."""
    args.robot = args.robot or common.DEFAULT_ROBOT
    robot = workflow.load_robot(
        args.robot,
        base=args.base,
        tip=args.tip,
        friction=common.friction_terms(args.friction),
        armature=True if args.armature else None,
    )
    scale = common.coulomb_scale(args.coulomb_scale)
    pre = {"cutoff_hz": args.cutoff, "rate_hz": args.rate, "decimate_to_hz": args.decimate}
    return robot, scale, pre


def _identify(args: argparse.Namespace, out: Path) -> int:
    """The command without --payload-run: one method or all, model(s), report, figures."""
    robot, scale, pre = _setup(args)
    gains = None if args.drive_gains is None else drives.parse_gains(args.drive_gains, robot.dof)
    conversion = {"drive_gains": gains, "motor_side": args.motor_side}
    record = drives.record(gains, args.motor_side)
    raw = read_measurements(args.data, robot, topic=args.topic, **conversion)
    val_raw = (
        read_measurements(args.validate, robot, topic=args.topic, **conversion)
        if args.validate
        else None
    )
    methods = list(workflow.METHODS) if args.method == "all" else [args.method]
    ekf = _ekf_settings(args)
    progress = common.Progress()
    try:
        if len(methods) == 1:
            # One method asked for: its failure is the command's (typed, with its exit code).
            t0 = time.perf_counter()
            result = workflow.identify_measurements(
                robot,
                raw,
                methods[0],
                coulomb_scale=scale,
                preprocessing=pre,
                drives=record,
                **(ekf if methods[0] == "ekf" else {}),
            )
            method_runs = [workflow.MethodRun(methods[0], result, None, time.perf_counter() - t0)]
        else:
            method_runs = workflow.identify_methods(
                robot,
                raw,
                methods,
                coulomb_scale=scale,
                preprocessing=pre,
                drives=record,
                progress=lambda k, total: progress("identify", k, total),
                per_method={"ekf": ekf},
            )
    finally:
        progress.close()
    runs = {r.method: r.result for r in method_runs if r.result is not None}
    if not runs:
        raise common.CliError(
            "every method failed: " + "; ".join(f"{r.method}: {r.error}" for r in method_runs),
            code=common.EXIT_FAILED,
        )
    default = workflow.DEFAULT_METHOD
    main = runs.get(default) or next(iter(runs.values()))
    settings = main.model.preprocessing.get("settings") or {}
    # Prepared once: every method is scored on the same rows of the same logs.
    fit_grid = prediction.prepare(raw, settings, identified=(main.data, main.log_report))
    val_grid = prediction.prepare(val_raw, settings) if val_raw is not None else None
    table = _comparison_rows(method_runs, fit_grid, val_grid)

    def build(tmp: Path) -> list[Path]:
        written = []
        for method, r in runs.items():
            name = "model.json" if len(methods) == 1 else f"model-{method}.json"
            r.model.save(tmp / name)
            written.append(tmp / name)
        if len(methods) > 1:
            main.model.save(tmp / "model.json")
            written.append(tmp / "model.json")
        lam = lambda_view.paper_lambda(main.model)
        if lam is not None:
            # The paper's arm: its 8 grouped parameters beside the base parameters.
            (tmp / "lambda.json").write_text(json.dumps(lam, indent=2) + "\n", encoding="utf-8")
            written.append(tmp / "lambda.json")
        sources = {"robot": str(args.robot), "data": str(args.data)}
        if args.validate:
            sources["validation"] = str(args.validate)
        comparison: list[str] = []
        figures: list[tuple[str, str]] = []
        # Every text file first, then the figures: model.json and report.md never wait.
        drawings: list[Callable[[], object]] = []
        if len(methods) > 1:
            joints = list(robot.joint_names)
            drawings.append(
                drawing.job(
                    "methods", model_report.comparison_figure, table, joints, tmp / "methods.png"
                )
            )
            figures.append(("methods.png", "Torque error per joint and method"))
            comparison = model_report.comparison_section(
                table, joints, main.model.method, "methods.png", default
            )

        def report(result: workflow.Identification, folder: Path, **extra: Any) -> list[Path]:
            """report.md and figures of one method's result, on the logs every method
            is scored on."""
            return model_report.write_report(
                result.model,
                folder,
                fit_grid,
                validation=val_grid,
                log_report=result.log_report,
                coulomb=result.coulomb,
                sources=sources,
                drawings=drawings,
                **extra,
            )

        written += report(main, tmp, comparison=comparison, figures=figures)
        physical = runs.get("physical")
        if physical is not None:
            (tmp / "robot.urdf").write_text(physical.model.to_urdf(), encoding="utf-8")
            written.append(tmp / "robot.urdf")
            identified = physical.model.robot
            act = identified.actuators
            if act["coupling"] is not None or act["armature"] or act["gear_ratios"] is not None:
                # What URDF cannot hold (a coupling, per-actuator friction) goes to a TOML
                # robot file that takes its links from robot.urdf.
                text = identified.to_toml("robot.urdf", physical.model.standard_parameters)
                (tmp / "robot.toml").write_text(text, encoding="utf-8")
                written.append(tmp / "robot.toml")
            if physical is not main:
                report_dir = tmp / "physical"
                report_dir.mkdir()
                written += report(physical, report_dir)
        # Here, one after another (a few ms each: a worker's fork would cost more); a
        # failed figure does not lose the rest.
        drawing.draw_all(drawings, workers=1)
        return written

    written = outdir.write_dir(out, build)
    _summary(main, table, fit_grid, val_grid)
    names = "model-<method>.json, model.json" if len(methods) > 1 else "model.json"
    print(f"results in {out}/ ({len(written)} files: {names}, report.md, figures)")
    return common.EXIT_OK


def _run_drive_gains(
    args: argparse.Namespace,
    robot: Any,
    scale: str | float,
    pre: dict[str, Any],
    out: Path,
) -> int:
    """``--payload-run``: drive gains, arm and payload from two current logs."""
    if not args.payload_run or args.payload_mass is None:
        raise common.CliError("--payload-run LOADED and --payload-mass KG go together")
    mass = args.payload_mass
    common.check_factor("--payload-mass", mass, unit=" kg")
    if args.drive_gains is not None:
        raise common.CliError("--payload-run identifies the drive gains: drop --drive-gains")
    if args.method not in (workflow.DEFAULT_METHOD, "wls"):
        raise common.CliError(
            "--payload-run has its own estimator (instrumental variables): drop --method"
        )
    conversion = {"motor_side": args.motor_side, "currents": True}
    raw_u = read_measurements(args.data, robot, topic=args.topic, **conversion)
    raw_l = read_measurements(args.payload_run, robot, topic=args.topic, **conversion)
    progress = common.Progress()
    try:
        progress("identify", 0, 2)
        # The unloaded run in current units: the Coulomb speed scale and the base analysis.
        start = workflow.identify_measurements(
            robot,
            raw_u,
            "wls",
            coulomb_scale=scale,
            preprocessing=pre,
            drives={"drive_gains": None, "motor_side": bool(args.motor_side), "identified": True},
        )
        loaded, _ = measurements_to_dataset(raw_l, pre)
        progress("identify", 1, 2)
        arm, payload, _naive = payloads.drive_gains(start.model, start.data, loaded, mass)
        progress("identify", 2, 2)
    finally:
        progress.close()
    gains = arm.drive_gains
    d = start.data
    tau = arm.robot.joint_torques_from_currents(np.asarray(d.tau), np.asarray(gains["values"]))
    data = prrrp.Dataset(d.t, d.q, d.qd, d.qdd, np.asarray(tau))
    run = workflow.Identification(arm, data, start.log_report, start.coulomb)
    joints = list(arm.robot.joint_names)

    def build(tmp: Path) -> list[Path]:
        arm.save(tmp / "model.json")
        (tmp / "payload.json").write_text(
            json.dumps(payload, indent=1, allow_nan=False) + "\n", encoding="utf-8"
        )
        sources = {
            "robot": str(args.robot),
            "unloaded run": str(args.data),
            "loaded run": str(args.payload_run),
        }
        written = [tmp / "model.json", tmp / "payload.json"]
        written += run.report(tmp, sources=sources)
        lines = [
            "",
            f"## Drive gains (payload of {mass:g} kg)",
            "",
            *payloads.gain_lines(gains, joints),
            "",
            "Instrumental variables (the currents instrumented by those the model predicts "
            "from the positions); the naive least squares, with the noisy currents in the "
            "regressor, is biased towards smaller gains. A gain is identifiable when σ is at "
            f"most {100 * arm.settings.get('max_relative_sigma', 0.05):.3g} % of it.",
            "",
        ]
        with (tmp / "report.md").open("a", encoding="utf-8") as f:
            f.write("\n".join(lines))
        return written

    written = outdir.write_dir(out, build)
    rows = []
    for j, name in enumerate(joints):
        ok = gains["identifiable"][j]
        value = f"{gains['values'][j]:.4g}" if ok else "not identifiable"
        rows.append([name, value, f"{gains['sigma'][j]:.2g}"])
    print(f"drive gains (N·m/A) from {args.data} and {args.payload_run} ({mass:g} kg payload):")
    common.print_table(["actuator of", "K", "σ"], rows)
    bad = [joints[j] for j, ok in enumerate(gains["identifiable"]) if not ok]
    if bad:
        print(
            f"warning: the runs do not determine the gains of {', '.join(bad)} (σ above the "
            "threshold; e.g. an axis the payload's weight never loads): the model's torques "
            "there are in doubt; give them with --drive-gains if known"
        )
    print(f"results in {out}/ ({len(written)} files: model.json, payload.json, report.md)")
    return common.EXIT_OK


def _comparison_rows(
    method_runs: list[workflow.MethodRun],
    fit: prediction.LogGrid,
    val: prediction.LogGrid | None,
) -> list[dict[str, Any]]:
    """One row per method: status, convergence, time and its error tables."""
    rows = []
    for r in method_runs:
        row: dict[str, Any] = {"method": r.method, "seconds": r.seconds, "error": r.error}
        if r.result is None:
            row.update(status="failed", converged=None, epochs=None)
            row.update(identification=None, validation=None)
        else:
            model = r.result.model
            row.update(status="ok", converged=bool(model.converged), epochs=model.epochs)
            row["identification"] = fit.errors(fit.predict(model))
            row["validation"] = val.errors(val.predict(model)) if val is not None else None
        rows.append(row)
    return rows


def _converged(row: dict[str, Any]) -> str:
    """'yes' (with the epochs of the gradient methods) or 'NO' for the summary table."""
    epochs = f" ({row['epochs']} epochs)" if row["epochs"] is not None else ""
    return ("yes" if row["converged"] else "NO") + epochs


def _summary(
    main: workflow.Identification,
    table: list[dict[str, Any]],
    fit: prediction.LogGrid,
    val: prediction.LogGrid | None,
) -> None:
    robot = main.model.robot
    d = main.data
    print(f"{robot.name}: {robot.dof} joints, {len(d)} samples over {d.duration:.3g} s")
    if main.coulomb is not None:
        note = main.coulomb.get("note")
        identified = main.coulomb.get("identifiable", not note)
        print(
            f"Coulomb speed scale v_s = {main.coulomb['chosen']:.4g} rad/s"
            + (" (chosen by cross-validation)" if identified else f": NOT IDENTIFIABLE: {note}")
        )
    lam = lambda_view.paper_lambda(main.model)
    if lam is not None:
        sig = lam["sigma"] or [None] * len(lam["lambda"])
        cells = [
            f"λ{k + 1} = {v:.4g}" + (f" ± {s:.2g}" if s is not None else "") + f" {u}"
            for k, (v, s, u) in enumerate(zip(lam["lambda"], sig, lam["units"], strict=True))
        ]
        print("the paper's grouped parameters (lambda.json): " + ", ".join(cells))
    which, grid = ("validation", val) if val is not None else ("identification", fit)
    header = ["method", "converged", "time (s)", *list(robot.joint_names)]
    rows = []
    for r in table:
        if r["status"] != "ok":
            continue
        errors = r[which]
        rows.append(
            [r["method"], _converged(r), f"{r['seconds']:.3g}"]
            + [f"{x:.3g}%" if np.isfinite(x) else "-" for x in errors["percent"]]
        )
    print(
        f"torque-prediction error on the {which} data, % of the measured torque's RMS "
        f"({grid.describe()}):"
    )
    common.print_table(header, rows)
    ok = [r[which] for r in table if r["status"] == "ok"]
    if ok and not np.all(np.isfinite(ok[0]["percent"])):
        print(
            "-: the joint's measured torque reads 0 over the scored rows (a dead or unlogged "
            "channel): no percentage of it to give, and the model was fitted to a zero torque "
            "there"
        )
    _say_noise_floor(robot.joint_names, robot.joint_types, ok)
    still = measurements.barely_moving(robot, d.q)
    if still:
        print(f"warning: {measurements.barely_moving_warning(still)}")
    for r in table:
        if r["status"] == "ok" and not r["converged"]:
            print(
                f"warning: {r['method']} did not meet its stopping rule within {r['epochs']} "
                "epochs; its model is not at the method's optimum (raise max_epochs or use wls)"
            )
    for r in table:
        if r["status"] != "ok":
            print(f"{r['method']}: failed: {r['error']}")
    if len(table) > 1:
        default = workflow.DEFAULT_METHOD
        why = "" if main.model.method == default else f" (the default, {default}, failed)"
        print(f"model.json is the {main.model.method} model{why}")


def _say_noise_floor(joints: Sequence[str], types: str, errors: Sequence[dict[str, Any]]) -> None:
    """Names the joints whose large error % is the log's torque noise, not the model's: a
    98 % error on a wrist that barely moved says nothing about its parameters (every
    method's error near the noise)."""
    if not errors:
        return
    common.say_noise_floor(
        joints,
        types,
        np.asarray(errors[0]["noise_rms"], dtype=float),
        np.max([e["rms"] for e in errors], axis=0),
        np.min([e["percent"] for e in errors], axis=0),
    )
