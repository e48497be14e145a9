"""Logs of geared arms on the joint side: motor currents through drive gains, and motor-side
angles and torques through the robot's gear ratios and coupling (``SerialChain.actuators``).

- Currents ``i1..iN`` (A) with joint-side drive gains K (N·m/A per actuator: torque constant
  times gear ratio): τ = Cᵀ·(K∘i).
- Motor-side logs (``motor_side``): angles θ, velocities and accelerations map as
  q = C⁻¹·(θ/r), torques at the motor shaft as τ = Cᵀ·(r∘τ_motor), with the gear ratios r
  (``gear_ratios`` under ``[actuators]`` in the robot file) and the coupling C.

>>> raw = prrrp.read_measurements("log.csv", robot, drive_gains=[52.0] * 6)  # doctest: +SKIP
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from prrrp._prrrp import SerialChain
from prrrp.csvio import InputError


def parse_gains(text: str, n: int) -> list[float]:
    """``--drive-gains K1,...,KN`` as N finite, non-zero numbers (N·m/A)."""
    parts = [p.strip() for p in text.split(",") if p.strip()]
    try:
        gains = [float(p) for p in parts]
    except ValueError:
        raise InputError(
            f"--drive-gains must be {n} comma-separated numbers (N·m/A), got {text!r}"
        ) from None
    if len(gains) != n:
        raise InputError(
            f"--drive-gains has {len(gains)} values; the robot has {n} actuators (one gain each, "
            "N·m/A on the joint side)"
        )
    bad = [g for g in gains if not (math.isfinite(g) and g != 0)]
    if bad:
        raise InputError(f"--drive-gains: {bad[0]} is not a finite, non-zero gain (N·m/A)")
    return gains


def to_joint_side(
    raw: dict[str, np.ndarray],
    robot: SerialChain,
    *,
    drive_gains: Sequence[float] | None = None,
    motor_side: bool = False,
    source: str = "the log",
    strict: bool = True,
) -> dict[str, np.ndarray]:
    """``raw`` (``prrrp.read_measurements``' dict) on the joint side of ``robot``: motor-side
    positions, velocities, accelerations and torques mapped when ``motor_side``, motor
    currents (key ``current``) turned into torques with ``drive_gains``. Raises InputError
    when currents come without gains (or, if ``strict``, gains with a log of torques), or
    ``motor_side`` without the robot's gear ratios."""
    out = dict(raw)
    n = robot.dof
    if motor_side:
        if robot.actuators["gear_ratios"] is None:
            raise InputError(
                "--motor-side needs the robot's gear ratios: add gear_ratios = [...] (motor "
                "angle per joint angle, one per actuator) under [actuators] in the robot file"
            )
        for key in ("q", "qd", "qdd"):
            if key in out:
                out[key] = np.asarray(robot.joint_positions_from_motor(out[key]))
        if "tau" in out:
            out["tau"] = np.asarray(robot.joint_torques_from_motor(out["tau"]))
    if "current" in out:
        if drive_gains is None:
            raise InputError(
                f"{source} has motor currents i1..i{n} instead of torques: give the drive gains "
                f"--drive-gains K1,...,K{n} (N·m/A on the joint side, one per actuator)"
            )
        gains = np.asarray(drive_gains, dtype=float)
        out["tau"] = np.asarray(robot.joint_torques_from_currents(out.pop("current"), gains))
    elif strict and drive_gains is not None and "tau" in raw:
        raise InputError(
            f"drive gains were given but {source} has torques tau1..tau{n}, not motor currents "
            f"i1..i{n}; drop --drive-gains"
        )
    return out


def record(drive_gains: Sequence[float] | None, motor_side: bool) -> dict[str, Any] | None:
    """What an identified model records about the drive conversion, so that ``prrrp
    predict`` converts new logs the same way (None when nothing was converted)."""
    if drive_gains is None and not motor_side:
        return None
    return {
        "drive_gains": None if drive_gains is None else [float(g) for g in drive_gains],
        "motor_side": bool(motor_side),
    }


def recorded(model: Any) -> dict[str, Any]:
    """The keyword arguments of :func:`to_joint_side` an identified model recorded."""
    pre = getattr(model, "preprocessing", None)
    drives = pre.get("drives") if isinstance(pre, dict) else None
    if not isinstance(drives, dict):
        return {}
    return {
        "drive_gains": drives.get("drive_gains"),
        "motor_side": bool(drives.get("motor_side", False)),
    }
