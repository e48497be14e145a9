"""``prrrp simulate [--robot ROBOT] [--trajectory TRAJ.csv] --out DIR``: a robot (the built-in
``paper`` by default) tracking a trajectory in closed loop, with sensor noise →
``DIR/data.csv``; without ``--trajectory`` an exciting one is designed first
(``DIR/trajectory.csv``). The previous release's one-file spelling is dispatched to
:mod:`prrrp.cli.deprecated`."""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

import numpy as np

from prrrp import csvio, outdir, workflow
from prrrp.cli import common, deprecated, excite
from prrrp.cli.deprecated import DEFAULT_Q_NOISE, DEFAULT_TAU_NOISE, reference_for

#: ``prrrp simulate --help``.
HELP = "simulate a robot's measurement log along a trajectory (DIR/data.csv)"
DESCRIPTION = (
    "Runs the robot (its file's inertials and friction) along TRAJ.csv, or "
    "along an exciting trajectory designed first as `prrrp excite` does, under computed-"
    "torque control with sensor noise, and writes DIR/data.csv (t, q1..qN, tau1..tauN; "
    "SI units) for `prrrp identify`, and DIR/trajectory.csv when it designed one."
)

__all__ = [
    "DEFAULT_Q_NOISE",
    "DEFAULT_TAU_NOISE",
    "MAX_TRACKING_ERROR",
    "add_parser",
    "reference_for",
    "run",
]

#: Default bound on the largest tracking error |q - q_ref| of a simulated run, rad or m.
#: The robot's own model tracks to a few milliradians (the controller's 1 kHz zero-order
#: hold, brief sticking at reversals under Coulomb friction): 3.7e-3 rad on a UR5-like arm
#: with a 1.5e-4 kg·m² wrist and 0.4 N·m of Coulomb friction, below 5e-3 on the Panda.
#: A run off by more does not follow its trajectory and its data would mislead.
MAX_TRACKING_ERROR = workflow.MAX_TRACKING_ERROR
#: The designed trajectory's duration without --trajectory, s (as `prrrp excite`).
DEFAULT_DURATION_S = 10.0


def add_parser(sub: Any) -> None:
    p = common.add_command(
        sub, "simulate", run, help=HELP, description=DESCRIPTION, epilog=deprecated.SIMULATE_RULE
    )
    common.add_out_argument(p, help="the output folder (built aside and swapped in whole)")
    common.add_robot_arguments(p)
    p.add_argument(
        "--trajectory",
        metavar="TRAJ.csv",
        help="reference t, q1..qN, qd1..qdN, qdd1..qddN at a uniform rate (from `prrrp "
        "excite`) (default: none, one is designed: 100 Hz, 5 harmonics)",
    )
    p.add_argument(
        "--duration",
        type=common.number,
        default=None,
        metavar="S",
        help="seconds of the designed trajectory; not with --trajectory, whose file sets it "
        f"(default: {DEFAULT_DURATION_S:g})",
    )
    excite.add_limits_argument(p, note="; for the designed trajectory, not with --trajectory")
    p.add_argument(
        "--seed", type=common.seed, default=0, help="seed of the design and the noise (default: 0)"
    )
    p.add_argument(
        "--noise",
        type=common.number,
        default=1.0,
        metavar="SCALE",
        help=f"multiplies the sensor noise (std {workflow.DEFAULT_Q_NOISE:g} rad or m on "
        f"positions, {workflow.DEFAULT_TAU_NOISE:g} N·m or N on torques); 0 = noise-free "
        "(default: 1)",
    )
    p.add_argument(
        "--max-tracking-error",
        type=common.number,
        default=MAX_TRACKING_ERROR,
        metavar="E",
        help="largest |q - q_ref| allowed anywhere in the run, rad or m; a run that strays "
        "further is an error and writes nothing (default: %(default)g). The simulated "
        "controller is computed torque with the robot's own model, friction compensated "
        "from the reference velocity",
    )


def _trajectory(args: argparse.Namespace, robot: Any) -> tuple[dict[str, np.ndarray], bool]:
    """The reference to track, and whether it was designed here (no --trajectory)."""
    if args.trajectory:
        for option, why in (("duration", "sets it"), ("limits", "was designed within them")):
            if getattr(args, option) is not None:
                raise common.CliError(
                    f"--{option} is not used with --trajectory: the trajectory file {why}"
                )
        traj = csvio.read_table(args.trajectory, robot.dof, need_tau=False)
        if "qd" not in traj or "qdd" not in traj:
            raise common.CliError(
                f"{args.trajectory}: a trajectory needs qd1..qdN and qdd1..qddN columns"
            )
        _say_outside_limits(robot, traj)
        return traj, False
    limits = excite.limits(args.limits, robot.dof)
    duration = DEFAULT_DURATION_S if args.duration is None else args.duration
    if not (math.isfinite(duration) and duration > 0):
        raise common.CliError(f"--duration must be a positive number of seconds, got {duration}")
    # Designed as `prrrp excite` does by default: friction columns in W_b (the simulated
    # robot keeps its file's friction values).
    design_robot = workflow.load_robot(
        args.robot,
        base=args.base,
        tip=args.tip,
        friction=common.friction_terms(excite.DEFAULT_FRICTION),
    )
    progress = common.Progress()
    try:
        design = workflow.excite(
            design_robot,
            duration,
            seed=args.seed,
            limits=limits,
            progress=lambda done, total: progress("excitation", done, total),
        )
    finally:
        progress.close()
    return {k: design[k] for k in ("t", "q", "qd", "qdd")}, True


def _say_outside_limits(robot: Any, traj: dict[str, np.ndarray]) -> None:
    """Warns of the joints a given trajectory takes past the robot file's limits (a designed
    one stays within them): the simulation runs, but the same trajectory on the arm would
    hit its stops or its drives' limits."""
    lim = robot.limits
    past = []
    for j, name in enumerate(robot.joint_names):
        q, qd = traj["q"][:, j], np.abs(traj["qd"][:, j])
        unit = "m" if robot.joint_types[j] == "P" else "rad"
        lo, hi, v = lim["lower"][j], lim["upper"][j], lim["velocity"][j]
        if np.isfinite(lo) and q.min() < lo:
            past.append(f"{name} q down to {q.min():.3g} {unit} (lower {lo:.3g})")
        if np.isfinite(hi) and q.max() > hi:
            past.append(f"{name} q up to {q.max():.3g} {unit} (upper {hi:.3g})")
        if np.isfinite(v) and qd.max() > v:
            past.append(f"{name} |q̇| up to {qd.max():.3g} {unit}/s (limit {v:.3g})")
    if past:
        print(
            f"warning: the trajectory leaves the robot file's limits: {'; '.join(past)}; "
            "simulated all the same, but do not run it on the arm (`prrrp excite` designs "
            "within them)"
        )


def run(args: argparse.Namespace) -> int:
    old = deprecated.file_spelling(args)
    if old and not (args.robot or args.trajectory):
        return deprecated.simulate_paper(args)
    bound = args.max_tracking_error
    if not (np.isfinite(bound) and bound > 0):
        raise common.CliError(f"--max-tracking-error must be a positive number, got {bound}")
    # Above MAX_FACTOR the noise alone is beyond any arm, and ×1e300 wrote a log whose
    # values prrrp's own readers refuse (1e100 or more).
    common.check_factor("--noise", args.noise, low=0.0)
    out = deprecated.check_out(args, old)
    args.robot = args.robot or common.DEFAULT_ROBOT
    robot = workflow.load_robot(args.robot, base=args.base, tip=args.tip)
    traj, designed = _trajectory(args, robot)
    try:
        rec = workflow.simulate(
            robot, traj, noise=args.noise, seed=args.seed, max_tracking_error=bound
        )
    except workflow.TrackingError as e:
        raise common.CliError(
            e.describe("--max-tracking-error", "--max-tracking-error") + " (no data written)",
            common.EXIT_FAILED,
        ) from None
    except ValueError as e:
        if "prrrp" in type(e).__module__:
            raise
        raise common.CliError(f"{args.trajectory or 'the designed trajectory'}: {e}") from None
    groups = csvio.columns(robot.dof)
    data_names = ["t", *groups["q"], *groups["tau"]]
    data = np.column_stack([rec["t"], rec["q"], rec["tau"]])
    if old:
        csvio.write_table_atomic(out, data_names, data)
    else:

        def build(tmp: Path) -> None:
            csvio.write_table_atomic(tmp / "data.csv", data_names, data)
            if designed:
                names = ["t", *groups["q"], *groups["qd"], *groups["qdd"]]
                table = np.column_stack([traj["t"], traj["q"], traj["qd"], traj["qdd"]])
                csvio.write_table_atomic(tmp / "trajectory.csv", names, table)

        outdir.write_dir(out, build)
    where = out if old else out / "data.csv"
    print(
        f"results in {where} ({len(rec['t'])} samples of {robot.name}, {robot.dof} joints; "
        f"largest tracking error {rec['tracking_error'].max():.2e} rad or m, bound "
        f"{bound:g}; noise x{args.noise:g})"
    )
    if old:
        new = ["prrrp", "simulate", *deprecated.robot_options(args)]
        new += [*deprecated.option(args, "trajectory"), *deprecated.option(args, "seed", 0)]
        new += deprecated.option(args, "noise", 1.0)
        new += ["--out", deprecated.folder_for(args.out)]
        notice_what = "a folder: DIR/data.csv"
        deprecated.notice(new, notice_what)
    return common.EXIT_OK
