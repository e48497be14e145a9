"""Shared fixtures: seeded random states of the PRRRP arm."""

from __future__ import annotations

import numpy as np
import pytest

import prrrp

#: A two-joint URDF arm (revolute about z, then y; limits on both joints).
TWO = """<robot name="two"><link name="base"/>
  <link name="l1"><inertial><mass value="2"/><origin xyz="0.1 0 0"/>
    <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>
  <link name="l2"><inertial><mass value="1"/><origin xyz="0 0.1 0"/>
    <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>
    <axis xyz="0 0 1"/><limit lower="-1" upper="1" velocity="2" effort="10"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>
    <origin xyz="0.3 0 0"/><axis xyz="0 1 0"/>
    <limit lower="-1" upper="1" velocity="2" effort="10"/></joint>
</robot>"""


def random_states(rng: np.random.Generator, n: int, scale: float = 1.0):
    """n random (q, qd, qdd) in the conventions of the notes: d1, d5 in m, angles over
    several turns, velocities and accelerations from moderate to large (scale)."""
    q = np.column_stack(
        [
            rng.uniform(-0.5, 0.5, n),
            rng.uniform(-3 * np.pi, 3 * np.pi, (n, 3)),
            rng.uniform(-0.2, 0.2, n),
        ]
    )
    qd = rng.normal(0.0, 1.0, (n, 5)) * scale
    qdd = rng.normal(0.0, 2.0, (n, 5)) * scale
    return q, qd, qdd


def paper_states(n: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """n random (q, qd, qdd) of the paper's arm within its joint limits (the limits its
    excitation is designed in), seeded."""
    import prrrp

    lim = prrrp.joint_limits()
    rng = np.random.default_rng(seed)
    lo, hi = np.asarray(lim["q_min"]), np.asarray(lim["q_max"])
    q = lo + (hi - lo) * rng.random((n, 5))
    qd = rng.uniform(-1, 1, (n, 5)) * np.asarray(lim["qd_max"])
    qdd = rng.uniform(-1, 1, (n, 5)) * np.asarray(lim["qdd_max"])
    return q, qd, qdd


def fourier_motion(seed: int, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """q, q̇, q̈ (exact derivatives) of seven joints at times t: five harmonics of 0.1 Hz
    per joint, sine and cosine amplitudes seeded."""
    rng = np.random.default_rng(seed)
    w = 2 * np.pi * 0.1 * np.arange(1, 6)
    a = rng.uniform(-1, 1, (7, 5)) * 0.8 / np.arange(1, 6)
    b = rng.uniform(-1, 1, (7, 5)) * 0.8 / np.arange(1, 6)
    s, c = np.sin(np.outer(t, w)), np.cos(np.outer(t, w))
    q = s @ a.T + c @ b.T
    qd = (c * w) @ a.T - (s * w) @ b.T
    qdd = -(s * w**2) @ a.T - (c * w**2) @ b.T
    return q, qd, qdd


def sine_motion(
    rng: np.random.Generator, t: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """q, q̇, q̈ (exact derivatives) of seven joints at times t: four sine harmonics of
    0.2 Hz per joint, amplitudes drawn from `rng` (which the caller goes on drawing from)."""
    w = 2 * np.pi * 0.2 * np.arange(1, 5)
    a = rng.normal(0, 0.4, (7, 4)) / np.arange(1, 5)
    s, c = np.sin(np.outer(t, w)), np.cos(np.outer(t, w))
    return s @ a.T, (c * w) @ a.T, -(s * w**2) @ a.T


def pin_configuration(model, q: np.ndarray) -> np.ndarray:
    """Pinocchio's configuration vector of joint angles q: continuous joints take
    (cos q, sin q)."""
    import math

    out = np.zeros(model.nq)
    for j in range(1, model.njoints):
        joint = model.joints[j]
        qi = q[joint.idx_v]
        if joint.nq == 2:
            out[joint.idx_q : joint.idx_q + 2] = [math.cos(qi), math.sin(qi)]
        else:
            out[joint.idx_q] = qi
    return out


def run_shell_block(block: str, cwd):
    """A README shell block, run by `bash -e` in `cwd` with this interpreter's scripts (the
    installed `prrrp`) first on PATH; fails the test with bash's stderr, else returns the
    finished process (its stdout and stderr)."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    env = dict(os.environ)
    env["PATH"] = str(Path(sys.executable).parent) + os.pathsep + env.get("PATH", "")
    run = subprocess.run(
        ["bash", "-e", "-c", block],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert run.returncode == 0, run.stderr
    return run


def close_to_scale(actual, expected, rtol: float) -> None:
    """Relative agreement, with the absolute floor set by the size of the whole quantity
    (entries that are zero in exact arithmetic come out as round-off in either library)."""
    expected = np.asarray(expected)
    atol = rtol * max(1.0, float(np.max(np.abs(expected))))
    np.testing.assert_allclose(actual, expected, rtol=rtol, atol=atol)


def shape_error_of_qd(model, n: int, bad: np.ndarray) -> prrrp.ShapeMismatchError:
    """The error of `model.inverse_dynamics` (n joints) with a `qd` of the wrong shape: a
    ShapeMismatchError (a ValueError) naming `qd` and the shapes it takes."""
    ok = np.zeros(n)
    expected = rf"`qd`.*expected \({n},\) or \(N, {n}\)"
    with pytest.raises(prrrp.ShapeMismatchError, match=expected) as e:
        model.inverse_dynamics(ok, bad, ok)
    assert isinstance(e.value, ValueError)
    assert e.value.what == "qd"
    return e.value


#: Friction of the paper's arm in `paper_friction_log`, per joint [fv, fc, fo].
PAPER_FRICTION = np.array(
    [[5.0, 8.0, 0.3], [0.4, 0.9, 0.02], [0.3, 0.7, 0.0], [0.2, 0.5, 0.0], [3.0, 6.0, 0.1]]
)


def paper_friction_log(seed: int):
    """The paper's arm (prismatic d1, d5; revolute θ2..θ4) with `PAPER_FRICTION`, run along a
    6 s multi-sine at 200 Hz with torque noise: the arm to identify (friction terms enabled,
    values unknown) and the raw log {t, q, tau}."""
    truth = prrrp.SerialChain.paper().with_friction(
        "viscous+coulomb+offset", PAPER_FRICTION, coulomb_smoothing=0.02
    )
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 6.0, 0.005)
    w = 2 * np.pi * 0.5 * np.arange(1, 4)
    a = rng.normal(0, 0.3, (5, 3)) / np.arange(1, 4)
    a[[0, 4]] *= 0.1  # the prismatic joints move centimetres
    s, c = np.sin(np.outer(t, w)), np.cos(np.outer(t, w))
    q, qd, qdd = s @ a.T + 0.3, (c * w) @ a.T, -(s * w**2) @ a.T
    tau = truth.inverse_dynamics(q, qd, qdd) + rng.normal(0, 0.05, q.shape)
    robot = prrrp.SerialChain.paper().with_friction("viscous+coulomb+offset", None)
    return robot, {"t": t, "q": q, "tau": tau}


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20170320)


@pytest.fixture
def robot() -> prrrp.Robot:
    return prrrp.Robot.paper()


@pytest.fixture
def states(rng):
    return random_states(rng, 50)
