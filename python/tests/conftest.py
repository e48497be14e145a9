"""Shared fixtures: seeded random states of the PRRRP arm."""

from __future__ import annotations

import numpy as np
import pytest

import prrrp


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


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20170320)


@pytest.fixture
def robot() -> prrrp.Robot:
    return prrrp.Robot.paper()


@pytest.fixture
def states(rng):
    return random_states(rng, 50)
