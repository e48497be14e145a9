"""The stand-in for real UR10e runs with and without a payload (issue 27): the UR10 of
example-robot-data in Pinocchio (the independent rigid-body library), with rotor inertias
(``model.armature``), viscous + Coulomb friction and offsets per joint, and a 2.8 kg
payload fixed to the flange (``tool0``) with its centre of mass a few cm off the flange, in
two mountings. Torques are Pinocchio's inverse dynamics of the loaded or bare arm plus the
friction, with sensor noise; currents are τ/K + noise.

The truth is expressed in the frame prrrp reports the payload in: the chain's last link,
``wrist_3_link`` (Pinocchio's joint-6 frame), whose fixed children (``ee_link``, ``tool0``)
are merged into it.
"""

from __future__ import annotations

import importlib.metadata
import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

ROBOTS = importlib.metadata.distribution("example-robot-data").locate_file(
    "cmeel.prefix/share/example-robot-data/robots"
)
UR10 = str(ROBOTS / "ur_description/urdf/ur10_robot.urdf")

#: Joint-side rotor inertias (kg·m²): a ~10⁻⁴ kg·m² rotor through a 101:1 gear on the
#: shoulder and elbow, smaller on the wrist.
ARMATURE = np.array([1.0, 1.0, 0.5, 0.12, 0.12, 0.12])
FV = np.array([8.0, 7.0, 4.0, 1.2, 1.0, 1.0])  # N·m·s/rad
FC = np.array([9.0, 8.5, 5.0, 2.0, 2.0, 1.8])  # N·m
FO = np.array([0.5, -0.8, 0.3, 0.1, -0.05, 0.08])  # N·m
V_S = 0.02  # rad/s: the Coulomb term's speed scale
TAU_NOISE = np.array([0.8, 0.8, 0.5, 0.15, 0.15, 0.15])  # N·m, joint torque sensors
Q_NOISE = 2e-5  # rad, encoders
#: Joint-side drive gains (N·m/A), of the UR10e's order.
GAINS = np.array([13.6, 13.1, 12.4, 9.8, 10.4, 10.9])

MASS = 2.805  # kg
#: tool0 in wrist_3_link: 0.0922 m along y, its z axis along wrist_3's y.
TOOL_IN_WRIST = pin.SE3(pin.rpy.rpyToMatrix(-math.pi / 2, 0.0, 0.0), np.array([0.0, 0.0922, 0.0]))


@dataclass(frozen=True)
class Mounting:
    """A payload mounting: centre of mass (m) and principal moments (kg·m²) about it in
    tool0's frame, and a rotation of the box about tool0's z (rad)."""

    com_tool: tuple[float, float, float]
    moments: tuple[float, float, float]
    yaw: float

    def inertia(self) -> pin.Inertia:
        """The payload in wrist_3_link's frame (Pinocchio's joint-6 frame)."""
        r = pin.rpy.rpyToMatrix(0.0, 0.0, self.yaw)
        i_tool = r @ np.diag(self.moments) @ r.T
        rot = TOOL_IN_WRIST.rotation
        com = TOOL_IN_WRIST.act(np.array(self.com_tool))
        return pin.Inertia(MASS, com, rot @ i_tool @ rot.T)

    def truth(self) -> dict[str, np.ndarray]:
        """Mass, COM (wrist_3 frame) and inertia about the COM [Ixx, Ixy, Iyy, Ixz, Iyz, Izz]."""
        ine = self.inertia()
        i = ine.inertia
        return {
            "mass": MASS,
            "com": np.array(ine.lever),
            "inertia": np.array([i[0, 0], i[0, 1], i[1, 1], i[0, 2], i[1, 2], i[2, 2]]),
        }


#: Two mountings of the same 2.8 kg part: a box 10 × 12 × 16 cm standing on the flange 3 cm
#: off its axis, and the same box turned and shifted.
MOUNTINGS = {
    "A": Mounting((0.03, 0.0, 0.06), (0.0094, 0.0083, 0.0057), 0.0),
    "B": Mounting((-0.01, -0.04, 0.05), (0.0057, 0.0094, 0.0083), 0.7),
}


def pin_model(payload: Mounting | None) -> pin.Model:
    model = pin.buildModelFromUrdf(UR10)
    model.armature = ARMATURE.copy()
    if payload is not None:
        model.inertias[6] = model.inertias[6] + payload.inertia()
    return model


def trajectory(seed: int, duration: float, rate: float):
    """t, q, q̇, q̈ of five harmonics per joint (exact derivatives), within the UR10's
    travel and at most ~1.5 rad/s."""
    rng = np.random.default_rng(seed)
    amplitude = np.array([1.6, 0.9, 1.2, 1.6, 1.6, 2.0])
    offset = np.array([0.0, -1.3, 1.2, -1.2, -1.5, 0.0])
    t = np.arange(0.0, duration, 1.0 / rate)
    w = 2 * np.pi * 0.1 * np.arange(1, 6) * rng.uniform(0.95, 1.05)
    a = rng.uniform(-1, 1, (6, 5)) / np.arange(1, 6)
    a *= (amplitude / np.abs(a).sum(axis=1))[:, None]
    ph = rng.uniform(0, 2 * np.pi, (6, 5))
    arg = t[:, None, None] * w[None, None, :] + ph[None]
    q = offset + (a * np.sin(arg)).sum(axis=2)
    qd = (a * w * np.cos(arg)).sum(axis=2)
    qdd = -(a * w**2 * np.sin(arg)).sum(axis=2)
    return t, q, qd, qdd


def torques(model: pin.Model, q, qd, qdd, offsets: np.ndarray = FO) -> np.ndarray:
    data = model.createData()
    tau = np.array(
        [pin.rnea(model, data, a, b, c).copy() for a, b, c in zip(q, qd, qdd, strict=True)]
    )
    return tau + FV * qd + FC * np.tanh(qd / V_S) + offsets


def run(
    seed: int,
    payload: Mounting | None,
    noise_seed: int,
    duration: float = 40.0,
    rate: float = 100.0,
) -> dict[str, np.ndarray]:
    """One run: the trajectory of ``seed`` (the same for the unloaded and loaded runs),
    measured positions and torques with the noise of ``noise_seed``. The loaded run's
    friction offsets drift by 10 % (warm joints), which a payload fit must absorb."""
    t, q, qd, qdd = trajectory(seed, duration, rate)
    offsets = FO * (1.1 if payload is not None else 1.0)
    tau = torques(pin_model(payload), q, qd, qdd, offsets)
    rng = np.random.default_rng(noise_seed)
    return {
        "t": t,
        "q": q + Q_NOISE * rng.standard_normal(q.shape),
        "tau": tau + TAU_NOISE * rng.standard_normal(tau.shape),
        "tau_true": tau,
        "q_true": q,
        "qd": qd,
        "qdd": qdd,
    }


def currents(tau_true: np.ndarray, rel_noise: float, seed: int) -> np.ndarray:
    """Motor currents τ/K plus white noise of ``rel_noise`` × each current's RMS."""
    i = tau_true / GAINS
    rms = np.sqrt(np.mean(i**2, axis=0))
    rng = np.random.default_rng(seed)
    return i + rel_noise * rms * rng.standard_normal(i.shape)


def csv_text(t: np.ndarray, q: np.ndarray, cols: dict[str, np.ndarray]) -> str:
    names = ["t", *(f"q{j + 1}" for j in range(6))]
    blocks = [t[:, None], q]
    for prefix, v in cols.items():
        names += [f"{prefix}{j + 1}" for j in range(6)]
        blocks.append(v)
    table = np.hstack(blocks)
    lines = [",".join(names)] + [",".join(f"{x:.9g}" for x in row) for row in table]
    return "\n".join(lines) + "\n"
