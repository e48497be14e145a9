"""``prrrp simulate``: an optimised excitation run on the simulated paper robot, written as a
measurement CSV."""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

import numpy as np

import prrrp
from prrrp import csvio
from prrrp.cli import simulate_robot
from prrrp.cli.common import (
    EXIT_OK,
    CliError,
    Progress,
    attr,
    check_output_file,
    nonempty_path,
    seed,
)

#: The core's default sensor noise (prrrp_core::SensorNoise::default): standard deviations
#: of the measured positions (m, rad) and generalised forces (N, N·m) per joint. ``--noise``
#: scales both.
DEFAULT_Q_NOISE = (1e-5, 1e-4, 1e-4, 1e-4, 1e-5)
DEFAULT_TAU_NOISE = (0.5, 0.03, 0.015, 0.007, 0.05)


def add_parser(sub: Any) -> None:
    p = sub.add_parser(
        "simulate",
        help="write a simulated measurement file (CSV) of the paper's arm or any robot",
        description="Optimises an excitation trajectory, runs it on the simulated paper robot "
        "under PD control with sensor noise, and writes the measured t, q1..q5, tau1..tau5 as "
        "CSV (SI units: s, m/rad, N/N·m) for `prrrp identify`.",
    )
    p.add_argument(
        "--out", required=True, type=nonempty_path, metavar="DATA.csv", help="CSV file to write"
    )
    p.add_argument(
        "--seed", type=seed, default=0, help="seed of the excitation and noise (default: 0)"
    )
    p.add_argument(
        "--noise",
        type=float,
        default=1.0,
        metavar="SCALE",
        help="multiplies the default sensor noise (std 1e-5 m / 1e-4 rad on positions, "
        "0.5 N .. 0.007 N·m on forces); 0 = noise-free (default: 1)",
    )
    p.add_argument(
        "--duration",
        type=float,
        default=None,
        metavar="S",
        help="simulated time, s (default: the excitation's duration, 10 s; longer: the "
        "excitation is played forward and backward in turn, see Excitation.reflected)",
    )
    simulate_robot.add_arguments(p)
    p.set_defaults(func=run)


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


def run(args: argparse.Namespace) -> int:
    if args.robot:
        return simulate_robot.run(args)
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
    return EXIT_OK
