"""``prrrp simulate --robot ROBOT --trajectory traj.csv --out data.csv``: any robot tracking
a trajectory in closed loop, with sensor noise, written as a measurement CSV."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from prrrp import csvio, workflow
from prrrp.cli.common import EXIT_FAILED, EXIT_OK, CliError, check_output_file

#: Default bound on the largest tracking error |q - q_ref| of a simulated run, rad or m.
#: The robot's own model tracks to a few milliradians (the controller's 1 kHz zero-order
#: hold, brief sticking at reversals under Coulomb friction): 3.7e-3 rad on a UR5-like arm
#: with a 1.5e-4 kg·m² wrist and 0.4 N·m of Coulomb friction, below 5e-3 on the Panda.
#: A run off by more does not follow its trajectory and its data would mislead.
MAX_TRACKING_ERROR = workflow.MAX_TRACKING_ERROR


def add_arguments(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("any robot (with --robot)")
    g.add_argument(
        "--robot",
        metavar="ROBOT",
        help='robot file (.urdf or .toml) or "paper" (default: the paper\'s arm)',
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
    g.add_argument(
        "--max-tracking-error",
        type=float,
        default=MAX_TRACKING_ERROR,
        metavar="E",
        help="largest |q - q_ref| allowed anywhere in the run, rad or m; a run that strays "
        "further is an error and writes no file (default: %(default)g). The simulated "
        "controller is computed torque with the robot's own model, friction compensated "
        "from the reference velocity",
    )


def run(args: argparse.Namespace) -> int:
    if not args.trajectory:
        raise CliError("--trajectory TRAJ.csv is required with --robot (see `prrrp excite`)")
    if args.duration is not None:
        raise CliError("--duration is not used with --robot: the trajectory file sets it")
    bound = args.max_tracking_error
    if not (np.isfinite(bound) and bound > 0):
        raise CliError(f"--max-tracking-error must be a positive number, got {bound}")
    out = Path(args.out)
    check_output_file(out)
    robot = workflow.load_robot(args.robot, base=args.base, tip=args.tip)
    traj = csvio.read_table(args.trajectory, robot.dof, need_tau=False)
    if "qd" not in traj or "qdd" not in traj:
        raise CliError(f"{args.trajectory}: a trajectory needs qd1..qdN and qdd1..qddN columns")
    try:
        rec = workflow.simulate(
            robot, traj, noise=args.noise, seed=args.seed, max_tracking_error=bound
        )
    except workflow.TrackingError as e:
        raise CliError(
            f"the simulated {robot.name} strays {e.error:.3g} rad or m from the trajectory "
            f"(joint {e.joint + 1}, {e.joint_name}, at t = {e.t:g} s), more than "
            f"--max-tracking-error {bound:g}; no data written. Check the trajectory against "
            "the robot's limits and its inertials and friction",
            EXIT_FAILED,
        ) from None
    except ValueError as e:
        if "prrrp" in type(e).__module__:
            raise
        raise CliError(f"{args.trajectory}: {e}") from None
    err = rec["tracking_error"].max()
    groups = csvio.columns(robot.dof)
    table = np.column_stack([rec["t"], rec["q"], rec["tau"]])
    csvio.write_table_atomic(out, ["t", *groups["q"], *groups["tau"]], table)
    print(
        f"results in {out} ({len(rec['t'])} samples of {robot.name}, {robot.dof} joints; "
        f"largest tracking error {err:.2e} rad or m, bound {bound:g}; noise x{args.noise:g})"
    )
    return EXIT_OK
