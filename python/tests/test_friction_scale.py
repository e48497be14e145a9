"""The Coulomb speed scale from Python: a 7-joint Panda whose friction turns over within
0.03 rad/s; the scale is found from the data and pays off on a different trajectory."""

import importlib.metadata

import numpy as np
import pytest

import prrrp

ROBOTS = importlib.metadata.distribution("example-robot-data").locate_file(
    "cmeel.prefix/share/example-robot-data/robots"
)
FRICTION = np.tile([0.3, 0.8, 0.05], (7, 1))  # fv, fc, fo per joint


def panda(v_s):
    chain = prrrp.SerialChain.from_urdf(
        str(ROBOTS / "panda_description/urdf/panda.urdf"), tip="panda_link8"
    )
    return chain.with_friction("viscous+coulomb+offset", FRICTION, coulomb_smoothing=v_s)


def data(chain, seed, seconds, noise):
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, seconds, 0.01)
    w = 2 * np.pi * 0.2 * np.arange(1, 5)
    a = rng.normal(0, 0.4, (7, 4)) / np.arange(1, 5)
    s, c = np.sin(np.outer(t, w)), np.cos(np.outer(t, w))
    q, qd, qdd = s @ a.T, (c * w) @ a.T, -(s * w**2) @ a.T
    tau = chain.inverse_dynamics(q, qd, qdd) + rng.normal(0, noise, q.shape)
    return prrrp.Dataset(t, q, qd, qdd, tau)


def held_out(v_s, train, test):
    model = prrrp.identify(panda(v_s), train)
    err = model.predict(test.q, test.qd, test.qdd) - test.tau
    return np.sqrt((err**2).mean(axis=0) / (test.tau**2).mean(axis=0))


def test_coulomb_scale_is_found_and_pays_off():
    truth = panda(0.03)
    train, test = data(truth, 1, 20.0, 0.02), data(truth, 2, 10.0, 0.0)
    report = panda(0.0).coulomb_scale(train)
    assert report["note"] is None
    assert 0.015 <= report["chosen"] <= 0.06, report
    assert len(report["cv_rms"]) == len(report["candidates"])
    found, hard = held_out(report["chosen"], train, test), held_out(0.0, train, test)
    assert found.max() < 0.5 * hard.max(), (found, hard)


def test_coulomb_scale_bad_input():
    chain = panda(0.0)
    train = data(chain, 3, 5.0, 0.02)
    with pytest.raises(prrrp.InvalidParameterError, match="candidate"):
        chain.coulomb_scale(train, candidates=[-1.0])
    viscous = chain.with_friction("viscous", FRICTION)
    with pytest.raises(prrrp.InvalidParameterError, match="Coulomb"):
        viscous.coulomb_scale(train)
