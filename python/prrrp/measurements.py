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
) -> dict[str, np.ndarray]:
    """Joint measurements of ``robot`` from ``path``: a CSV file (``t, q1..qN, tau1..tauN``,
    optional ``qd1..qdN``, ``qdd1..qddN``; SI units; N from the robot, or from the header
    when ``robot`` is None) or a ROS 2 bag (folder or ``.mcap``; ``sensor_msgs/JointState``
    on ``topic``, joints matched to ``robot.joint_names`` by name; needs ``robot``).

    Returns ``t`` (S,) s, ``q`` and ``tau`` (S, N), and ``qd`` (and ``qdd``) when recorded.
    Time stamps may repeat (real logs do); time running backwards, a missing or misspelt
    column, a NaN, a missing topic or joint raise ``prrrp.csvio.InputError`` (a
    ``ValueError``) with a one-line message. Without ``need_tau`` a CSV file may lack the
    torque columns (the result then has no ``tau``).

    Geared arms (see ``prrrp.drives``): a CSV file may give motor currents ``i1..iN`` (A)
    instead of torques, converted with ``drive_gains`` (N·m/A per actuator, joint side);
    with ``motor_side`` the positions, velocities and torques are motor-side and mapped
    through the robot's gear ratios and coupling. Both need ``robot``.
    """
    if bags.is_bag(path):
        if robot is None:
            raise csvio.InputError(f"{path}: reading a bag needs the robot (its joint names)")
        raw = bags.read_joint_states(path, list(robot.joint_names), topic)
    else:
        raw = csvio.read_table(
            path, None if robot is None else robot.dof, real_log=True, need_tau=need_tau
        )
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
