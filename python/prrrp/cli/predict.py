"""``prrrp predict``: an identified model's joint torques at every row of a measurement file."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np

import prrrp
from prrrp import bags, csvio, drives, prediction
from prrrp.cli import common
from prrrp.measurements import read_measurements

#: ``prrrp predict --help``.
HELP = "joint torques of an identified model for recorded states"
DESCRIPTION = (
    "Loads MODEL.json (written by `prrrp identify DATA --out DIR`) and "
    "writes the model's joint torques at every row of DATA (a CSV file t, q1..qN and "
    "optionally tau1..tauN, qd1..qdN, qdd1..qddN, or a ROS 2 bag) as t, tau1..tauN, edge: "
    "the time stamps of DATA, row for row. When DATA has qd and qdd columns they are used "
    "as given; otherwise the log is processed with the model's recorded preprocessing, "
    "the model is evaluated on the processed signals and its torque interpolated to each "
    "row's time stamp; rows in the filter's edge transient (a few cut-off periods at each "
    "end) are predicted from signals the filter has not settled on and marked edge = 1. "
    "When DATA has measured torques, prints the per-joint RMS error against them (edge "
    "rows and repeated time stamps left out, and counted)."
)


def add_parser(sub: Any) -> None:
    p = common.add_command(sub, "predict", run, help=HELP, description=DESCRIPTION)
    p.add_argument("model", metavar="MODEL.json", help="identified model")
    p.add_argument("data", metavar="DATA", help="measurement CSV file or ROS 2 bag")
    common.add_out_argument(p, "TAU.csv", "CSV file to write")
    common.add_topic_argument(p)


def predict_file(
    model: prrrp.IdentifiedModel, path: str, topic: str = bags.DEFAULT_TOPIC
) -> prediction.LogGrid:
    """The log at ``path`` prepared with ``model``'s recorded preprocessing for predictions
    at its rows (:mod:`prrrp.prediction`); ``.predict(model)`` gives the torques."""
    robot = model.robot
    raw = read_measurements(path, robot, topic=topic, need_tau=False, **drives.recorded(model))
    return prediction.prepare(raw, prediction.recorded_settings(model))


def load_model(path: str) -> prrrp.IdentifiedModel:
    """``IdentifiedModel.load`` with its errors as one-line CLI errors."""
    try:
        model = prrrp.IdentifiedModel.load(path)
    except prrrp.PrrrpError as e:
        raise common.CliError(
            f"{path}: not a usable identified model: {common.describe(e)}"
        ) from None
    try:
        prediction.recorded_settings(model)
    except ValueError as e:
        raise common.CliError(f"{path}: {e}") from None
    return model


def run(args: argparse.Namespace) -> int:
    out = Path(args.out)
    common.check_output_file(out)
    model = load_model(args.model)
    grid = predict_file(model, args.data, args.topic)
    tau = grid.predict(model)
    n = tau.shape[1]
    names = ["t", *csvio.columns(n)["tau"], "edge"]
    table = np.column_stack([grid.t, tau, grid.edge.astype(float)])
    csvio.write_table_atomic(out, names, table, integer_columns=("edge",))
    edges = int(grid.edge.sum())
    note = ""
    if edges:
        note = (
            f"; {edges} rows in the filter's edge transient (the first and last "
            f"{grid.report['trim_s']:.3g} s) are predicted from unsettled filter output "
            "(edge = 1)"
        )
    if grid.measured is None:
        print(f"{len(table)} rows (every row of {args.data}){note}; torques in {out}")
        return common.EXIT_OK
    errors = grid.errors(tau)
    joints = list(model.robot.joint_names)
    print(f"{len(table)} rows (every row of {args.data}){note}")
    print(f"torque-prediction error per joint against the measured torque ({grid.describe()}):")
    rows = [
        [j, f"{r:.4g}", f"{p:.3g}" if np.isfinite(p) else "-"]
        for j, r, p in zip(joints, errors["rms"], errors["percent"], strict=True)
    ]
    common.print_table(["joint", "RMS (N·m, N)", "% of measured RMS"], rows)
    say_mismatch(errors["percent"])
    print(f"torques in {out}")
    return common.EXIT_OK


#: Error (% of the measured RMS torque) from which a joint's prediction is no better than
#: predicting zero torque (100 %) would be, give or take the noise.
MISMATCH_PERCENT = 90.0


def say_mismatch(percent: np.ndarray) -> None:
    """Prints a note when every joint with a measured torque is predicted no better than
    zero torque would be: a model identified on another kind of log (a motor-side model
    read joint-side positions as motor angles and printed 98-100 % with nothing else),
    another joint order, other units or torque signs, not a poor model."""
    scored = percent[np.isfinite(percent)]
    if scored.size and np.all(scored >= MISMATCH_PERCENT):
        print(
            f"every joint's error is {MISMATCH_PERCENT:g} % or more, no better than predicting "
            "zero torque: the log is likely not the kind the model was identified from. "
            "Check the joint order, units and torque signs, and whether positions and "
            "torques are logged on the side (motor or joint) and in the quantity (torque or "
            "current) the model expects"
        )
