"""``prrrp predict``: an identified model's joint torques for the states of a measurement file."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np

import prrrp
from prrrp import bags, csvio, drives
from prrrp.cli.common import (
    EXIT_OK,
    CliError,
    check_output_file,
    nonempty_path,
    print_table,
)
from prrrp.measurements import measurements_to_dataset, read_measurements


def add_parser(sub: Any) -> None:
    p = sub.add_parser(
        "predict",
        help="joint torques of an identified model for recorded states",
        description="Loads MODEL.json (written by `prrrp identify --robot ... --out DIR`) and "
        "writes the model's joint torques for the states of DATA (a CSV file t, q1..qN and "
        "optionally tau1..tauN, qd1..qdN, qdd1..qddN, or a ROS 2 bag) as t, tau1..tauN. When "
        "DATA has qd and qdd columns they are used as given; otherwise they are derived with "
        "the model's recorded preprocessing. When DATA has measured torques, prints the "
        "per-joint RMS error.",
    )
    p.add_argument("model", metavar="MODEL.json", help="identified model")
    p.add_argument("data", metavar="DATA", help="measurement CSV file or ROS 2 bag")
    p.add_argument(
        "--out", required=True, type=nonempty_path, metavar="TAU.csv", help="CSV file to write"
    )
    p.add_argument(
        "--topic",
        default=bags.DEFAULT_TOPIC,
        help=f"JointState topic of a bag (default: {bags.DEFAULT_TOPIC})",
    )
    p.set_defaults(func=run)


def predict_file(
    model: prrrp.IdentifiedModel, path: str, topic: str = bags.DEFAULT_TOPIC
) -> dict[str, np.ndarray]:
    """The torques ``model`` predicts for the states recorded in ``path``: ``t`` (S,),
    ``tau`` (S, N) and, when the file has measured torques, ``measured`` (S, N) on the same
    time grid (after the model's preprocessing when the file has no q̇, q̈)."""
    robot = model.robot
    raw = read_measurements(path, robot, topic=topic, need_tau=False, **drives.recorded(model))
    measured = "tau" in raw
    if not measured:
        raw["tau"] = np.zeros_like(raw["q"])
    data, _ = measurements_to_dataset(raw, _recorded_settings(model))
    tau = np.asarray(model.predict(data.q, data.qd, data.qdd))
    out = {"t": np.asarray(data.t), "tau": tau}
    if measured:
        out["measured"] = np.asarray(data.tau)
    return out


def _recorded_settings(model: prrrp.IdentifiedModel) -> dict[str, Any]:
    pre = model.preprocessing or {}
    settings = pre.get("settings") if isinstance(pre, dict) else None
    return settings if isinstance(settings, dict) else {}


def run(args: argparse.Namespace) -> int:
    out = Path(args.out)
    check_output_file(out)
    try:
        model = prrrp.IdentifiedModel.load(args.model)
    except prrrp.PrrrpError as e:
        raise CliError(f"{args.model}: not an identified model ({e})") from None
    pred = predict_file(model, args.data, args.topic)
    n = pred["tau"].shape[1]
    names = ["t", *csvio.columns(n)["tau"]]
    table = np.column_stack([pred["t"], pred["tau"]])
    csvio.write_text_atomic(out, csvio.format_table(names, table))
    if "measured" not in pred:
        print(f"{len(table)} samples; torques in {out}")
        return EXIT_OK
    err = pred["tau"] - pred["measured"]
    rms = np.sqrt(np.mean(err**2, axis=0))
    ref = np.sqrt(np.mean(pred["measured"] ** 2, axis=0))
    joints = list(model.robot.joint_names)
    print(f"{len(table)} samples of {args.data}: torque-prediction error per joint")
    rows = [
        [j, f"{r:.4g}", f"{100 * r / f:.3g}" if f > 0 else "-"]
        for j, r, f in zip(joints, rms, ref, strict=True)
    ]
    print_table(["joint", "RMS (N·m, N)", "% of RMS τ"], rows)
    print(f"torques in {out}")
    return EXIT_OK
