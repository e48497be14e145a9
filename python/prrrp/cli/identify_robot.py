"""``prrrp identify DATA --robot ROBOT --out DIR``: any robot from its URDF/TOML file and a
log (CSV or ROS 2 bag) → ``DIR/model.json``, ``DIR/report.md`` and figures."""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

import prrrp
from prrrp import bags, model_report, outdir, workflow
from prrrp.cli.common import (
    EXIT_OK,
    CliError,
    Progress,
    first_line,
    friction_terms,
    print_table,
)
from prrrp.measurements import measurements_to_dataset, read_measurements


def add_arguments(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("any robot (with --robot)")
    g.add_argument("--robot", metavar="ROBOT", help="robot file (.urdf or .toml)")
    g.add_argument("--base", metavar="LINK", help="URDF: first link of the chain (default: root)")
    g.add_argument("--tip", metavar="LINK", help="URDF: last link of the chain")
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
    g.add_argument("--cutoff", type=float, metavar="HZ", help="low-pass cut-off of the log, Hz")
    g.add_argument("--rate", type=float, metavar="HZ", help="resampling rate of the log, Hz")
    g.add_argument("--decimate", type=float, metavar="HZ", help="output rate after filtering")
    g.add_argument(
        "--topic",
        default=bags.DEFAULT_TOPIC,
        help=f"JointState topic of a ROS 2 bag (default: {bags.DEFAULT_TOPIC})",
    )


def _coulomb_scale(text: str) -> str | float:
    if text == "auto":
        return text
    try:
        v = float(text)
    except ValueError:
        raise CliError(f"--coulomb-scale must be auto or a number (rad/s), got {text!r}") from None
    if not (math.isfinite(v) and v >= 0):
        raise CliError(f"--coulomb-scale must be finite and >= 0 rad/s, got {text}")
    return v


def run(args: argparse.Namespace) -> int:
    if not args.out:
        raise CliError("--out DIR is required with --robot (the model, report and figures)")
    out = Path(args.out)
    robot = workflow.load_robot(
        args.robot, base=args.base, tip=args.tip, friction=friction_terms(args.friction)
    )
    scale = _coulomb_scale(args.coulomb_scale)
    pre = {"cutoff_hz": args.cutoff, "rate_hz": args.rate, "decimate_to_hz": args.decimate}
    raw = read_measurements(args.data, robot, topic=args.topic)
    val = None
    if args.validate:
        val_raw = read_measurements(args.validate, robot, topic=args.topic)
        val, _ = measurements_to_dataset(val_raw, pre)
    methods = list(workflow.METHODS) if args.method == "all" else [args.method]
    progress = Progress()
    runs: dict[str, workflow.Identification] = {}
    failures: dict[str, str] = {}
    try:
        for k, method in enumerate(methods):
            progress("identify", k, len(methods))
            try:
                runs[method] = workflow.identify_measurements(
                    robot, raw, method, coulomb_scale=scale, preprocessing=pre
                )
            except (prrrp.PrrrpError, ValueError) as e:
                if len(methods) == 1:
                    raise
                failures[method] = first_line(e)
        progress("identify", len(methods), len(methods))
    finally:
        progress.close()
    if not runs:
        raise CliError("; ".join(f"{m}: {e}" for m, e in failures.items()))
    main = runs.get("ls") or next(iter(runs.values()))

    def build(tmp: Path) -> list[Path]:
        written = []
        for method, r in runs.items():
            name = "model.json" if len(runs) == 1 else f"model-{method}.json"
            r.model.save(tmp / name)
            written.append(tmp / name)
        if len(runs) > 1:
            main.model.save(tmp / "model.json")
        sources = {"robot": str(args.robot), "data": str(args.data)}
        if args.validate:
            sources["validation"] = str(args.validate)
        written += main.report(tmp, validation=val, sources=sources)
        physical = runs.get("physical")
        if physical is not None:
            (tmp / "robot.urdf").write_text(physical.model.to_urdf(), encoding="utf-8")
            written.append(tmp / "robot.urdf")
            if physical is not main:
                report_dir = tmp / "physical"
                report_dir.mkdir()
                written += physical.report(report_dir, validation=val, sources=sources)
        return written

    written = outdir.write_dir(out, build)
    _summary(main, runs, failures, val)
    print(f"results in {out}/ ({len(written)} files: model.json, report.md, figures)")
    return EXIT_OK


def _converged(model: Any) -> str:
    """'yes' (with the epochs of the gradient methods) or 'NO' for the summary table."""
    epochs = f" ({model.epochs} epochs)" if model.epochs is not None else ""
    return ("yes" if model.converged else "NO") + epochs


def _summary(
    main: workflow.Identification,
    runs: dict[str, workflow.Identification],
    failures: dict[str, str],
    val: Any,
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
    check = val if val is not None else d
    which = "validation" if val is not None else "identification"
    header = ["method", "converged", *list(robot.joint_names)]
    rows = []
    for method, r in runs.items():
        p = model_report.prediction_table(r.model, check)
        rows.append([method, _converged(r.model), *(f"{x:.3g}%" for x in p["percent"])])
    print(f"torque-prediction error on the {which} data (% of RMS torque):")
    print_table(header, rows)
    for method, r in runs.items():
        if not r.model.converged:
            print(
                f"warning: {method} did not meet its stopping rule within {r.model.epochs} "
                "epochs; its model is not at the method's optimum (raise max_epochs or use ls)"
            )
    for method, e in failures.items():
        print(f"{method}: failed: {e}")
