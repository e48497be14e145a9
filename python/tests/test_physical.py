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


def test_feasibility_report_by_hand():
    # One link: a 2 kg point mass 0.5 m along x — physical (pseudo-inertia rank 1); then a
    # body whose inertia breaks the triangle inequality (Ixx + Iyy < Izz).
    urdf = """<robot name="one"><link name="base"/>
      <link name="l1"><inertial><mass value="2"/><origin xyz="0.5 0 0"/>
        <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>
      <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>
        <axis xyz="0 0 1"/><limit lower="-1" upper="1" velocity="1" effort="1"/></joint>
    </robot>"""
    chain = prrrp.SerialChain.from_urdf(urdf).with_friction("viscous", [[0.1, 0, 0]])
    r = chain.feasibility()
    assert r["consistent"]
    link = r["links"][0]
    assert link["link"] == "l1"
    assert link["mass"] == pytest.approx(2.0)
    assert link["min_eigenvalue"] == pytest.approx(0.0, abs=1e-12)
    bad = chain.parameters.copy()
    bad[4] = bad[6] = 0.01  # Ixx = Iyy = 0.01 about the link frame, plus m·0.25 on Iyy, Izz
    bad[9] = 1.0  # Izz far above Ixx + Iyy
    r = chain.feasibility(bad)
    assert not r["consistent"]
    assert r["non_physical_links"] == ["l1"]
    assert min(r["links"][0]["triangle_margins"]) < 0
    neg = chain.parameters.copy()
    neg[-1] = -0.1
    assert not chain.feasibility(neg)["friction"][0]["consistent"]


def test_least_squares_base_values_checked_for_rigid_bodies(truth, models):
    exact = truth.base_parameters().base_values(truth.parameters)
    assert truth.base_feasibility(exact)["feasible"]
    # Base values no rigid bodies have: the truth with one link's mass negated.
    pi = truth.parameters.copy()
    pi[30:40] *= -1.0
    r = truth.base_feasibility(truth.base_parameters().base_values(pi))
    assert not r["feasible"]
    assert r["max_relative_mismatch"] > 1e-3
