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

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from prrrp._prrrp import MAX_FACTOR, MIN_FACTOR, SerialChain, is_factor
from prrrp.csvio import InputError


def parse_gains(text: str, n: int) -> list[float]:
    """``--drive-gains K1,...,KN`` as N finite, non-zero numbers (N·m/A), or a JSON file
    holding them: a ``model.json`` with identified ``drive_gains`` (``prrrp identify
    --payload-run``), an object ``{"drive_gains": [...]}`` or a list."""
    if text.strip().endswith(".json") or Path(text).is_file():
        return _gains_from_file(text, n)
    parts = [p.strip() for p in text.split(",")]
    try:
        # An empty part ("1,,1") is a missing gain, not a separator to skip.
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
    bad = [g for g in gains if not is_factor(abs(g))]
    if bad:
        raise InputError(
            f"--drive-gains: {bad[0]} is not a gain (N·m/A): each must be between "
            f"{MIN_FACTOR:g} and {MAX_FACTOR:g} in magnitude (negative for a reversed motor)"
        )
    return gains


def _gains_from_file(text: str, n: int) -> list[float]:
    path = Path(text)
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError(f"--drive-gains: {text}: no such file") from None
    except (OSError, ValueError) as e:
        raise InputError(f"--drive-gains: {text} is not a readable JSON file ({e})") from None
    values: Any = doc
    if isinstance(values, dict):
        values = values.get("drive_gains", values.get("values"))
    if isinstance(values, dict):
        flags = values.get("identifiable") or []
        bad = [k + 1 for k, ok in enumerate(flags) if not ok]
        if bad:
            raise InputError(
                f"--drive-gains: {text} says the data did not determine the gains of actuators "
                f"{bad}; give all gains as K1,...,K{n} (N·m/A)"
            )
        values = values.get("values")
    if not isinstance(values, list):
        raise InputError(
            f"--drive-gains: {text} holds no drive gains (a list, drive_gains or "
            "drive_gains.values)"
        )
    return parse_gains(",".join(str(v) for v in values), n)


def to_joint_side(
    raw: dict[str, np.ndarray],
    robot: SerialChain,
    *,
    drive_gains: Sequence[float] | None = None,
    motor_side: bool = False,
    source: str = "the log",
    strict: bool = True,
    currents: bool = False,
) -> dict[str, np.ndarray]:
    """``raw`` (``prrrp.read_measurements``' dict) on the joint side of ``robot``: motor-side
    positions, velocities, accelerations and torques mapped when ``motor_side``, motor
    currents (key ``current``) turned into torques with ``drive_gains``. Raises InputError
    when currents come without gains (or, if ``strict``, gains with a log of torques), or
    ``motor_side`` without the robot's gear ratios. With ``currents`` the log must hold
    currents and they are kept as they are, in ``tau`` (A), for identifying the gains."""
    out = dict(raw)
    n = robot.dof
    if motor_side:
        if robot.actuators["gear_ratios"] is None:
            # Also reached from a model file's recorded conversion, where no option exists.
            raise InputError(
                "motor-side data (--motor-side, or as the model's log was) need the robot's "
                "gear ratios: add gear_ratios = [...] (motor angle per joint angle, one per "
                "actuator) under [actuators] in the robot file"
            )
        for key in ("q", "qd", "qdd"):
            if key in out:
                out[key] = np.asarray(robot.joint_positions_from_motor(out[key]))
        if "tau" in out:
            out["tau"] = np.asarray(robot.joint_torques_from_motor(out["tau"]))
    if currents:
        if "current" not in out:
            raise InputError(
                f"{source} has no motor currents i1..i{n}: identifying drive gains needs current "
                "logs of both runs"
            )
        out["tau"] = out.pop("current")
        return out
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
            f"drive gains were given (--drive-gains, or the model's log was of currents) but "
            f"{source} has torques tau1..tau{n}, not motor currents i1..i{n}; give a log of "
            "currents, or drop --drive-gains"
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
    """The keyword arguments of :func:`to_joint_side` an identified model recorded: the
    gains it was given, or else those it identified (``model.drive_gains``)."""
    pre = getattr(model, "preprocessing", None)
    drives = pre.get("drives") if isinstance(pre, dict) else None
    identified = getattr(model, "drive_gains", None)
    if not isinstance(drives, dict):
        if isinstance(identified, dict):
            return {"drive_gains": identified["values"], "motor_side": False}
        return {}
    gains = drives.get("drive_gains")
    if gains is None and isinstance(identified, dict):
        gains = identified["values"]
    return {
        "drive_gains": gains,
        "motor_side": bool(drives.get("motor_side", False)),
    }
