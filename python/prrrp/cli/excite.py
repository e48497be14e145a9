"""``prrrp excite [--robot ROBOT] --duration S --out DIR``: an exciting trajectory for a robot
(the built-in ``paper`` by default), within its limits, starting and ending at rest →
``DIR/trajectory.csv``. The previous release's one-file spelling (``--out TRAJ.csv``) is
kept by :mod:`prrrp.cli.deprecated`'s rule."""

from __future__ import annotations

import argparse
import math
from typing import Any

import numpy as np

from prrrp import csvio, outdir, workflow
from prrrp._prrrp import MAX_FACTOR, MIN_FACTOR, is_factor
from prrrp.cli import common, deprecated

#: ``prrrp excite --help``.
HELP = "design an exciting trajectory for a robot (DIR/trajectory.csv)"
DESCRIPTION = (
    "Designs per-joint Fourier series (Swevers 1997) whose coefficients "
    "minimise cond(W_b) of the robot's base regressor (friction columns included when "
    "asked), starting and ending at rest, within the position, velocity and acceleration "
    "limits of the robot file, and writes DIR/trajectory.csv: t, q1..qN, qd1..qdN, "
    "qdd1..qddN (SI units), for `prrrp simulate --trajectory`."
)

LIMIT_KEYS = ("lower", "upper", "velocity", "acceleration")
#: The file written into --out.
TRAJECTORY = "trajectory.csv"
#: The friction columns of W_b the design keeps well conditioned by default.
DEFAULT_FRICTION = "viscous,coulomb,offset"
#: Options repeated in the deprecation notice, with their defaults.
EXCITE_DEFAULTS = (
    ("duration", 10.0),
    ("seed", 0),
    ("harmonics", 5),
    ("base_freq", None),
    ("rate", 100.0),
    ("friction", DEFAULT_FRICTION),
    ("limits", None),
    ("evaluations", 2000),
)


def add_parser(sub: Any) -> None:
    p = common.add_command(
        sub, "excite", run, help=HELP, description=DESCRIPTION, epilog=deprecated.FILE_RULE
    )
    common.add_robot_arguments(p)
    common.add_out_argument(p, help="the output folder (built aside and swapped in whole)")
    p.add_argument(
        "--duration", type=common.number, default=10.0, metavar="S", help="seconds (default: 10)"
    )
    p.add_argument(
        "--seed", type=common.seed, default=0, help="seed of the random shapes (default: 0)"
    )
    p.add_argument("--harmonics", type=int, default=5, metavar="K", help="per joint (default: 5)")
    p.add_argument(
        "--base-freq",
        type=common.number,
        default=None,
        metavar="HZ",
        help="base frequency; the duration must be a whole number of its periods "
        "(default: 1/duration)",
    )
    p.add_argument(
        "--rate", type=common.number, default=100.0, metavar="HZ", help="samples/s (default: 100)"
    )
    p.add_argument(
        "--friction",
        metavar="TERMS",
        default=DEFAULT_FRICTION,
        help=f"friction columns of W_b: viscous, coulomb, offset or none (default: "
        f"{DEFAULT_FRICTION})",
    )
    add_limits_argument(p)
    p.add_argument(
        "--evaluations",
        type=int,
        default=2000,
        metavar="N",
        help="cost evaluations (default: 2000)",
    )


def add_limits_argument(p: argparse.ArgumentParser, note: str = "") -> None:
    """``--limits K=V,...`` of the commands that design a trajectory (read by
    :func:`limits`)."""
    p.add_argument(
        "--limits",
        metavar="K=V,...",
        help="override the file's limits for every joint, e.g. velocity=2,acceleration=8 "
        f"(keys: lower, upper in rad/m; velocity; acceleration){note} (default: the file's)",
    )


def limits(text: str | None, n: int) -> dict[str, np.ndarray] | None:
    """The per-joint limits of ``--limits`` for ``n`` joints, None without it."""
    if not text:
        return None
    out: dict[str, np.ndarray] = {}
    for item in text.split(","):
        key, sep, value = item.partition("=")
        key = key.strip()
        if not sep or key not in LIMIT_KEYS:
            raise common.CliError(
                f"--limits: '{item}' is not KEY=VALUE with KEY {common.options(LIMIT_KEYS)}"
            )
        try:
            v = common.number(value)
        except argparse.ArgumentTypeError as e:
            raise common.CliError(f"--limits: {key}: {e}") from None
        # A bound on |q̇| or |q̈| of 1e-300 designed a trajectory with cond(W) = 6e299.
        if key in ("velocity", "acceleration") and not is_factor(v):
            raise common.CliError(
                f"--limits: {key} must be between {MIN_FACTOR:g} and {MAX_FACTOR:g} "
                f"(rad/s{'²' if key == 'acceleration' else ''} or m/s"
                f"{'²' if key == 'acceleration' else ''}), got {value.strip()}"
            )
        out[key] = np.full(n, v)
    return out


#: Bytes per number of the CSV text written (a full-precision float and its comma).
CSV_BYTES_PER_VALUE = 22


def _check_size(duration: float, rate: float, n: int) -> None:
    """Refuses, before the (slow) design, a trajectory whose arrays would not fit in memory
    or whose CSV prrrp could not read back."""
    samples = duration * rate
    if not (math.isfinite(samples) and samples > 0):
        return  # workflow.excite says what is wrong with the numbers
    if samples > workflow.MAX_SAMPLES:
        raise common.CliError(
            f"--rate {rate:g} Hz × --duration {duration:g} s = {samples:.3g} samples; at most "
            f"{workflow.MAX_SAMPLES:.0e}: lower --rate or --duration"
        )
    columns = 1 + 3 * n
    text = samples * columns * CSV_BYTES_PER_VALUE
    if text > csvio.MAX_FILE_BYTES:
        raise common.CliError(
            f"--rate {rate:g} Hz × --duration {duration:g} s = {samples:.3g} samples × {n} "
            f"joints make a CSV of about {text / 2**30:.3g} GiB, more than the "
            f"{csvio.MAX_FILE_BYTES / 2**30:.3g} GiB prrrp reads back: lower --rate or --duration"
        )
    # The arrays, and the table the CSV is written from: twice the trajectory's size.
    workflow.check_memory(round(samples) + 1, n, 2 * columns, "--rate or --duration")


def run(args: argparse.Namespace) -> int:
    old = deprecated.file_spelling(args)
    out = deprecated.check_out(args, old)
    args.robot = args.robot or common.DEFAULT_ROBOT
    robot = workflow.load_robot(
        args.robot, base=args.base, tip=args.tip, friction=common.friction_terms(args.friction)
    )
    limits_ = limits(args.limits, robot.dof)
    _check_size(args.duration, args.rate, robot.dof)
    progress = common.Progress()
    try:
        design = workflow.excite(
            robot,
            args.duration,
            harmonics=args.harmonics,
            base_frequency=args.base_freq,
            rate=args.rate,
            seed=args.seed,
            limits=limits_,
            progress=lambda done, total: progress("excitation", done, total),
            max_evaluations=args.evaluations,
        )
    except ValueError as e:
        if "prrrp" in type(e).__module__:
            raise
        raise common.CliError(str(e)) from None
    finally:
        progress.close()
    groups = csvio.columns(robot.dof)
    names = ["t", *groups["q"], *groups["qd"], *groups["qdd"]]
    table = np.column_stack([design["t"], design["q"], design["qd"], design["qdd"]])
    if old:
        csvio.write_table_atomic(out, names, table)
    else:
        outdir.write_dir(out, lambda tmp: csvio.write_table_atomic(tmp / TRAJECTORY, names, table))
    print(
        f"cond(W_b) {design['cond_initial']:.4g} -> {design['cond_final']:.4g} "
        f"({design['evaluations']} evaluations); limit usage per joint:"
    )
    usage = np.asarray(design["limit_usage"])
    rows = [
        [j, *("-" if not np.isfinite(x) else f"{100 * x:.0f}%" for x in usage[i])]
        for i, j in enumerate(robot.joint_names)
    ]
    common.print_table(["joint", "position", "velocity", "acceleration"], rows)
    where = out if old else out / TRAJECTORY
    print(f"trajectory in {where} ({len(table)} samples over {args.duration:g} s)")
    if old:
        new = ["prrrp", "excite", *deprecated.robot_options(args)]
        for name, default in EXCITE_DEFAULTS:
            new += deprecated.option(args, name, default)
        new += ["--out", deprecated.folder_for(args.out)]
        deprecated.notice(new, f"a folder: DIR/{TRAJECTORY}")
    return common.EXIT_OK
