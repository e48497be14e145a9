"""Measurements of any robot: read a CSV file or a ROS 2 bag, and turn it into an
identification data set (``prrrp.Dataset``), preprocessing it when velocities and
accelerations are not given.

>>> import prrrp
>>> raw = prrrp.read_measurements("log.csv", robot)            # doctest: +SKIP
>>> data, report = prrrp.measurements_to_dataset(raw)         # doctest: +SKIP
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from typing import Any

import numpy as np

from prrrp import bags, csvio, drives
from prrrp._prrrp import Dataset, SerialChain, preprocess_log

#: Settings of ``prrrp.preprocess_log`` that a preprocessing record may carry (and that
#: ``prrrp predict`` re-applies from an identified model).
PREPROCESS_KEYS = (
    "rate_hz",
    "cutoff_hz",
    "order",
    "filter_torque",
    "trim_s",
    "decimate_to_hz",
    "max_gap_s",
)


def read_measurements(
    path: str | os.PathLike[str],
    robot: SerialChain | None = None,
    *,
    topic: str = bags.DEFAULT_TOPIC,
    need_tau: bool = True,
    drive_gains: list[float] | None = None,
    motor_side: bool = False,
    currents: bool = False,
) -> dict[str, np.ndarray]:
    """Joint measurements of ``robot`` from ``path``: a CSV file (``t, q1..qN, tau1..tauN``,
    optional ``qd1..qdN``, ``qdd1..qddN``; SI units; N from the robot, or from the header
    when ``robot`` is None) or a ROS 2 bag (folder or ``.mcap``; ``sensor_msgs/JointState``
    on ``topic``, joints matched to ``robot.joint_names`` by name; needs ``robot``).

    Returns ``t`` (S,) s, ``q`` and ``tau`` (S, N), and ``qd`` (and ``qdd``) when recorded.
    Time stamps may repeat (real logs do); time running backwards, a missing or misspelt
    column, a NaN, a missing topic or joint, and rows a median 0.5 s or more apart when
    q̇ and q̈ must be derived (time not in seconds: :data:`SLOWEST_STEP_S`) raise
    ``prrrp.csvio.InputError`` (a ``ValueError``) with a one-line message. Without
    ``need_tau`` a CSV file may lack the torque columns (the result then has no ``tau``).

    Geared arms (see ``prrrp.drives``): a CSV file may give motor currents ``i1..iN`` (A)
    instead of torques, converted with ``drive_gains`` (N·m/A per actuator, joint side);
    with ``motor_side`` the positions, velocities and torques are motor-side and mapped
    through the robot's gear ratios and coupling. Both need ``robot``. With ``currents`` the
    currents are kept unconverted in ``tau`` (A), to identify the gains from.
    """
    if bags.is_bag(path):
        if robot is None:
            raise csvio.InputError(f"{path}: reading a bag needs the robot (its joint names)")
        raw = bags.read_joint_states(path, list(robot.joint_names), topic)
    else:
        raw = csvio.read_table(
            path, None if robot is None else robot.dof, real_log=True, need_tau=need_tau
        )
    _check_time_unit(path, raw)
    if robot is None:
        if "current" in raw or drive_gains is not None or motor_side:
            raise csvio.InputError(f"{path}: converting drive data needs the robot")
        return raw
    # A log read for prediction (need_tau False) may hold torques where the model was
    # identified from currents: the recorded gains are then simply unused.
    return drives.to_joint_side(
        raw,
        robot,
        drive_gains=drive_gains,
        motor_side=motor_side,
        source=str(path),
        strict=need_tau,
        currents=currents,
    )


def median_step(t: np.ndarray) -> float | None:
    """The median interval between time stamps that differ (s); None without two."""
    steps = np.diff(np.asarray(t, dtype=float))
    steps = steps[steps > 0]
    return float(np.median(steps)) if steps.size else None


#: Median time step (s) from which a log whose q̇ and q̈ must be derived is taken to have
#: its time in another unit: 0.5 s is 2 Hz, slower than any robot log that dynamics can
#: be identified from, and 1 kHz logged in milliseconds gives 1.
SLOWEST_STEP_S = 0.5


#: Median time step (s) below which a log's time is taken to be in another unit: 10 µs
#: is 100 kHz, ten times the fastest joint-state stream of an arm controller (EtherCAT
#: drives at 8–16 kHz); seconds divided by 1e6 by mistake give 1e-8 for a 100 Hz log,
#: which every cut-off's start-up transient outlasts.
FASTEST_STEP_S = 1e-5


def _check_time_unit(path: str | os.PathLike[str], raw: dict[str, np.ndarray]) -> None:
    """InputError for a log whose rows are so far apart, or so close together, that its
    time cannot be in seconds (or q̇, q̈ could not be derived from it), unless it gives
    both q̇ and q̈ (a table of static poses may number its rows)."""
    if "qd" in raw and "qdd" in raw:
        return
    step = median_step(raw["t"])
    if step is not None and step < FASTEST_STEP_S:
        raise csvio.InputError(
            f"{path}: rows are a median {step:.3g} s apart ({1 / step:.3g} Hz), faster than "
            "any robot log; t must be in seconds: if it was divided by 1e3 or 1e6, multiply "
            "it back"
        )
    if step is not None and step >= SLOWEST_STEP_S:
        raise csvio.InputError(
            f"{path}: rows are a median {step:g} s apart ({1 / step:.3g} Hz), too slow to "
            "derive q̇ and q̈ from q; t must be in seconds: if it is in milliseconds, "
            "microseconds or nanoseconds, divide it by 1e3, 1e6 or 1e9 (or give the columns "
            "qd1.. and qdd1..)"
        )


def measurements_to_dataset(
    raw: dict[str, np.ndarray], preprocessing: dict[str, Any] | None = None
) -> tuple[Dataset, dict[str, Any] | None]:
    """An identification data set from measurements. When ``qd`` and ``qdd`` are both given
    they are used as they are (report None); otherwise the log goes through
    ``prrrp.preprocess_log`` (repeated rows dropped, resampled, filtered, differentiated,
    trimmed) with the settings in ``preprocessing`` (keys of :data:`PREPROCESS_KEYS`; others
    are ignored) and its report is returned."""
    if "qd" in raw and "qdd" in raw:
        return Dataset(raw["t"], raw["q"], raw["qd"], raw["qdd"], raw["tau"]), None
    settings = {
        k: v
        for k, v in (preprocessing or {}).items()
        if k in PREPROCESS_KEYS and v is not None and not _nan(v)
    }
    return preprocess_log(raw["t"], raw["q"], raw["tau"], qd=raw.get("qd"), **settings)


def _nan(v: Any) -> bool:
    return isinstance(v, float) and math.isnan(v)


#: A joint whose position spans less than this over the data (rad or m) is named as one
#: that barely moves, whatever the fit: about a degree, too little travel for its speed
#: to leave the Coulomb band (v_s of a few 0.01 rad/s) or its inertia to be seen, so the
#: parameters only its motion determines are not determined (a UR5 stand-in whose three
#: wrist joints moved only by encoder noise fitted to a cond(W) of 3e5 with σ of 8750 %
#: and 70–80 % torque errors on those joints, without a word).
BARELY_MOVING_SPAN = 0.02


def barely_moving(robot: SerialChain, q: np.ndarray, span: float = BARELY_MOVING_SPAN) -> list[str]:
    """The joints of ``robot`` whose positions ``q`` (S, N) span less than ``span`` (rad
    or m), each as ``"name (spans X rad)"``; empty when every joint moves."""
    q = np.asarray(q, dtype=float)
    if q.ndim != 2 or len(q) == 0:
        return []
    spans = q.max(axis=0) - q.min(axis=0)
    return [
        f"{name} (spans {spans[j]:.2g} {'m' if robot.joint_types[j] == 'P' else 'rad'})"
        for j, name in enumerate(robot.joint_names)
        if spans[j] < span
    ]


def barely_moving_warning(joints: Sequence[str]) -> str:
    """The one-line warning for :func:`barely_moving`'s joints (empty for none)."""
    if not joints:
        return ""
    return (
        f"joints that barely move in the data: {', '.join(joints)}: the parameters only "
        "their motion determines are not determined (large σ), and their torque errors say "
        "little about the model; move these joints through a wider range"
    )
