"""``prrrp simulate --robot ROBOT --trajectory traj.csv --out data.csv``: any robot tracking
a trajectory in closed loop, with sensor noise, written as a measurement CSV."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from prrrp import csvio, workflow
from prrrp.cli.common import EXIT_OK, CliError, check_output_file


def add_arguments(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("any robot (with --robot)")
    g.add_argument(
        "--robot", metavar="ROBOT", help="robot file (.urdf or .toml) (default: the paper's arm)"
    )
    g.add_argument(
        "--base", metavar="LINK", help="URDF: first link of the chain (default: the root link)"
    )
    g.add_argument(
        "--tip",
        metavar="LINK",
        help="URDF: last link of the chain (default: the end of the movable joints)",
    )
    g.add_argument(
        "--trajectory",
        metavar="TRAJ.csv",
        help="reference t, q1..qN, qd1..qdN, qdd1..qddN (from `prrrp excite`); required with "
        "--robot (default: none)",
    )


def run(args: argparse.Namespace) -> int:
    if not args.trajectory:
        raise CliError("--trajectory TRAJ.csv is required with --robot (see `prrrp excite`)")
    if args.duration is not None:
        raise CliError("--duration is not used with --robot: the trajectory file sets it")
    out = Path(args.out)
    check_output_file(out)
    robot = workflow.load_robot(args.robot, base=args.base, tip=args.tip)
    traj = csvio.read_table(args.trajectory, robot.dof, need_tau=False)
    if "qd" not in traj or "qdd" not in traj:
        raise CliError(f"{args.trajectory}: a trajectory needs qd1..qdN and qdd1..qddN columns")
    try:
        rec = workflow.simulate(robot, traj, noise=args.noise, seed=args.seed)
    except ValueError as e:
        if "prrrp" in type(e).__module__:
            raise
        raise CliError(f"{args.trajectory}: {e}") from None
    groups = csvio.columns(robot.dof)
    table = np.column_stack([rec["t"], rec["q"], rec["tau"]])
    csvio.write_table_atomic(out, ["t", *groups["q"], *groups["tau"]], table)
    err = np.abs(rec["q_true"] - traj["q"][: len(rec["t"])]).max()
    print(
        f"results in {out} ({len(rec['t'])} samples of {robot.name}, {robot.dof} joints; "
        f"largest tracking error {err:.2e} rad or m; noise x{args.noise:g})"
    )
    return EXIT_OK
