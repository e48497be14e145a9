"""method="physical" on the Panda: the estimate is a set of rigid bodies, predicts held-out
torques as well as least squares, and its URDF — loaded by Pinocchio, the independent
reference — gives the same joint torques as the identified model."""

from __future__ import annotations

import importlib.metadata

import numpy as np
import pinocchio as pin
import pytest

import prrrp

URDF = str(
    importlib.metadata.distribution("example-robot-data").locate_file(
        "cmeel.prefix/share/example-robot-data/robots/panda_description/urdf/panda.urdf"
    )
)
FRICTION = np.tile([0.3, 0.4, 0.05], (7, 1))


@pytest.fixture(scope="module")
def truth():
    chain = prrrp.SerialChain.from_urdf(URDF, tip="panda_link8")
    return chain.with_friction("viscous+coulomb+offset", FRICTION, coulomb_smoothing=0.02)


def data(truth, seed, seconds, noise):
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, seconds, 0.01)
    w = 2 * np.pi * 0.1 * np.arange(1, 6)
    a = rng.uniform(-1, 1, (7, 5)) * 0.8 / np.arange(1, 6)
    s, c = np.sin(np.outer(t, w)), np.cos(np.outer(t, w))
    q, qd, qdd = s @ a.T, (c * w) @ a.T, -(s * w**2) @ a.T
    tau = truth.inverse_dynamics(q, qd, qdd) + rng.normal(0, noise, q.shape)
    return prrrp.Dataset(t, q, qd, qdd, tau)


@pytest.fixture(scope="module")
def models(truth):
    train = data(truth, 1, 20.0, 0.1)
    return {m: prrrp.identify(truth, train, m) for m in ("ls", "physical")}


def test_physical_estimate_is_rigid_bodies_and_predicts(truth, models):
    phys = models["physical"]
    pi = phys.standard_parameters
    assert pi is not None
    assert models["ls"].standard_parameters is None
    rebuilt = prrrp.SerialChain.from_urdf(phys.to_urdf())
    assert rebuilt.is_physically_consistent()
    assert (pi[70:].reshape(7, 3)[:, :2] >= -1e-9).all()  # fv, fc >= 0
    val = data(truth, 2, 10.0, 0.0)
    errs = {}
    for m, model in models.items():
        e = model.predict(val.q, val.qd, val.qdd) - val.tau
        errs[m] = np.sqrt((e**2).mean())
    assert errs["physical"] <= 1.1 * errs["ls"], errs


def test_urdf_of_the_estimate_matches_in_pinocchio(models):
    phys = models["physical"]
    pi = phys.standard_parameters
    model = pin.buildModelFromXML(phys.to_urdf())
    d = model.createData()
    rng = np.random.default_rng(5)
    fv, fc, fo = pi[70:].reshape(7, 3).T
    for _ in range(5):
        q, qd, qdd = rng.uniform(-1, 1, (3, 7))
        rigid = pin.rnea(model, d, q, qd, qdd)
        friction = fv * qd + fc * np.tanh(qd / 0.02) + fo
        np.testing.assert_allclose(
            rigid + friction, phys.predict(q, qd, qdd), atol=1e-8 * (1 + np.abs(rigid).max())
        )


def test_base_parameter_models_have_no_urdf(models):
    with pytest.raises(prrrp.InvalidParameterError, match="physical"):
        models["ls"].to_urdf()
