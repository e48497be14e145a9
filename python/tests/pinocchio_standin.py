"""A stand-in for a recorded log of a real arm, simulated with Pinocchio (the independent
reference): the built robot differs from its robot file.

The "true" arm is the URDF's with every link perturbed by amounts CAD models are off by
(mass ×exp(N(0, 0.25)), centre of mass ±2 cm per axis, second moments about it ×exp(N(0,
0.3)) on principal axes turned by ~0.1 rad, no link thinner than 10 % of its length), plus
viscous, smooth Coulomb (v_s = 0.03 rad/s) and offset friction. It follows a multi-sine
like a real identification run's, not an ideal one: two joints chosen at random barely
move. The log holds what a robot records — joint positions with encoder noise (1e-4 rad)
and joint torques with sensor noise (0.15 N·m on the proximal joints, 0.05 N·m on the
others) at 500 Hz — and is identified the way `prrrp identify` does (filtered,
differentiated, trimmed). Held-out errors are scored against the measured noisy torques
of a second trajectory.
"""

from __future__ import annotations

import dataclasses
import importlib.metadata

import numpy as np
import pinocchio as pin

import prrrp
from prrrp import workflow

ROBOTS = importlib.metadata.distribution("example-robot-data").locate_file(
    "cmeel.prefix/share/example-robot-data/robots"
)
#: URDF path and tip link of the arms of example-robot-data used here.
ARMS = {
    "panda": ("panda_description/urdf/panda.urdf", "panda_link8"),
    "ur5": ("ur_description/urdf/ur5_robot.urdf", None),
    "kinova": ("kinova_description/robots/kinova.urdf", None),
}
COULOMB_SCALE = 0.03  # rad/s


@dataclasses.dataclass
class Log:
    """A simulated log: the robot file's chain with friction columns (the prior), the raw
    identification log, the held-out data set and its measured torques, the truth."""

    robot: prrrp.SerialChain
    train: dict[str, np.ndarray]
    held_out: prrrp.Dataset
    held_out_tau: np.ndarray
    true_masses: np.ndarray
    true_parameters: np.ndarray


def _true_model(path: str, names: list[str], rng: np.random.Generator) -> pin.Model:
    full = pin.buildModelFromUrdf(path)
    lock = [full.getJointId(j) for j in full.names[1:] if j not in names]
    model = pin.buildReducedModel(full, lock, pin.neutral(full)) if lock else full
    for i in range(1, model.njoints):
        y = model.inertias[i]
        mass = y.mass * np.exp(rng.normal(0, 0.25))
        com = y.lever + rng.normal(0, 0.02, 3)
        # Second moments about the centre of mass, Σ = ½·tr(I)·1 − I: any Σ ⪰ 0 is a rigid
        # body, so the truth stays physical.
        sigma = 0.5 * np.trace(y.inertia) * np.eye(3) - y.inertia
        w, v = np.linalg.eigh(sigma)
        w = np.maximum(w, 1e-2 * w.max()) * np.exp(rng.normal(0, 0.3, 3)) * mass / y.mass
        r = pin.exp3(rng.normal(0, 0.1, 3)) @ v
        sigma = r @ np.diag(w) @ r.T
        model.inertias[i] = pin.Inertia(mass, com, np.trace(sigma) * np.eye(3) - sigma)
    return model


def _multisine(rng, n, seconds, rate, amplitude, f0=0.1, harmonics=5):
    t = np.arange(0.0, seconds, 1.0 / rate)
    w = 2 * np.pi * f0 * np.arange(1, harmonics + 1)
    a, b = (
        rng.uniform(-1, 1, (2, n, harmonics))
        / np.arange(1, harmonics + 1)
        * amplitude[None, :, None]
    )
    s, c = np.sin(np.outer(t, w)), np.cos(np.outer(t, w))
    q = s @ a.T + c @ b.T
    qd = (c * w) @ a.T - (s * w) @ b.T
    qdd = -(s * w**2) @ a.T - (c * w**2) @ b.T
    return t, q, qd, qdd


def _torques(model: pin.Model, q, qd, qdd) -> np.ndarray:
    data = model.createData()
    config = pin.neutral(model)
    out = np.empty_like(q)
    for k in range(len(q)):
        for j in range(1, model.njoints):
            joint = model.joints[j]
            x = q[k, joint.idx_v]
            if joint.nq == 2:  # continuous joint: (cos, sin)
                config[joint.idx_q : joint.idx_q + 2] = np.cos(x), np.sin(x)
            else:
                config[joint.idx_q] = x
        out[k] = pin.rnea(model, data, config, qd[k], qdd[k])
    return out


def simulate_log(arm: str, seed: int, seconds: float = 20.0, rate: float = 500.0) -> Log:
    """The stand-in log of ``arm`` (a key of :data:`ARMS`) with seed ``seed``."""
    rng = np.random.default_rng(seed)
    rel, tip = ARMS[arm]
    path = str(ROBOTS / rel)
    chain = prrrp.SerialChain.from_urdf(path, tip=tip)
    n = chain.dof
    model = _true_model(path, list(chain.joint_names), rng)
    fv, fc, fo = rng.uniform(0.05, 0.5, n), rng.uniform(0.1, 0.8, n), rng.normal(0, 0.2, n)
    amplitude = np.full(n, 0.9)
    amplitude[rng.choice(n, 2, replace=False)] = rng.uniform(0.05, 0.15, 2)
    lower, upper = np.asarray(chain.limits["lower"]), np.asarray(chain.limits["upper"])
    centre = np.clip(0.5 * (lower + upper), -2, 2) if np.isfinite(lower).all() else np.zeros(n)
    tau_noise = np.where(np.arange(n) <= n // 2, 0.15, 0.05)

    def record(duration):
        t, q, qd, qdd = _multisine(rng, n, duration, rate, amplitude)
        q = q + centre
        tau = _torques(model, q, qd, qdd) + fv * qd + fc * np.tanh(qd / COULOMB_SCALE) + fo
        return {
            "t": t,
            "q": q + rng.normal(0, 1e-4, q.shape),
            "tau": tau + rng.normal(0, 1, tau.shape) * tau_noise,
        }

    train, val = record(seconds), record(seconds / 2)
    held_out, _ = prrrp.measurements_to_dataset(val, {})
    rows = np.searchsorted(val["t"], np.asarray(held_out.t) - 0.5 / rate)
    truth = np.concatenate(
        [model.inertias[i].toDynamicParameters() for i in range(1, model.njoints)]
        + [np.column_stack([fv, fc, fo]).ravel()]
    )
    return Log(
        robot=workflow.load_robot(path, tip=tip, friction="viscous+coulomb+offset"),
        train=train,
        held_out=held_out,
        held_out_tau=val["tau"][rows],
        true_masses=np.array([model.inertias[i].mass for i in range(1, model.njoints)]),
        true_parameters=truth,
    )


def held_out_rms(model: prrrp.IdentifiedModel, log: Log) -> float:
    """RMS over all joints of the model's torque minus the measured held-out torque (N·m)."""
    d = log.held_out
    err = np.asarray(model.predict(d.q, d.qd, d.qdd)) - log.held_out_tau
    return float(np.sqrt(np.mean(err**2)))
