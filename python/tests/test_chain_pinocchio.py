"""`prrrp.SerialChain` against Pinocchio: the PUMA 560 (6R) rebuilt independently from its
published data (tests/pinocchio_puma560.py), and the PRRRP arm as a chain against the
closed-form `prrrp.Robot`."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pinocchio_puma560 as puma
import pytest
from conftest import close_to_scale, random_states
from pinocchio_prrrp import from_robot

import prrrp

RTOL = 1e-9


def close(actual, expected, rtol=RTOL):
    close_to_scale(actual, expected, rtol)


def crba(model, data, q):
    m = pin.crba(model, data, q)
    return np.triu(m) + np.triu(m, 1).T


@pytest.fixture(scope="module")
def chain():
    return prrrp.SerialChain.puma560()


@pytest.fixture(scope="module")
def pinocchio_model():
    model = puma.build()
    return model, model.createData()


@pytest.fixture(params=[1.0, 10.0], ids=["moderate", "fast"])
def states(request):
    rng = np.random.default_rng(560 + int(request.param))
    n = 40
    q = rng.uniform(-2 * np.pi, 2 * np.pi, (n, 6))
    qd = rng.normal(0.0, 1.0, (n, 6)) * request.param
    qdd = rng.normal(0.0, 2.0, (n, 6)) * request.param
    return q, qd, qdd


def test_published_data_and_names(chain):
    """The chain holds the published table; names follow Pinocchio's parameter order."""
    assert chain.dof == 6
    assert chain.num_params == 60
    assert chain.joint_types == "RRRRRR"
    assert chain.convention == "standard"
    close(chain.dh, [[a, alpha, d, 0.0] for d, a, alpha in puma.DH], rtol=1e-15)
    close(chain.parameters, puma.standard_parameters(), rtol=1e-15)
    close(chain.gravity, [0.0, 0.0, -9.81], rtol=1e-15)
    names = chain.parameter_names
    assert names[:10] == ["m1", "mx1", "my1", "mz1", "Ixx1", "Ixy1", "Iyy1", "Ixz1", "Iyz1", "Izz1"]
    assert names[-1] == "Izz6"


def test_mass_matrix(chain, pinocchio_model, states):
    model, data = pinocchio_model
    q, _, _ = states
    mm = chain.mass_matrix(q)
    assert mm.shape == (len(q), 6, 6)
    for k in range(len(q)):
        close(mm[k], crba(model, data, q[k]))
    close(chain.mass_matrix(q[0]), mm[0], rtol=0)


def test_inverse_dynamics(chain, pinocchio_model, states):
    model, data = pinocchio_model
    q, qd, qdd = states
    tau = chain.inverse_dynamics(q, qd, qdd)
    assert tau.shape == (len(q), 6)
    assert tau.dtype == np.float64
    for k in range(len(q)):
        close(tau[k], pin.rnea(model, data, q[k], qd[k], qdd[k]))


def test_nonlinear_effects_and_gravity(chain, pinocchio_model, states):
    model, data = pinocchio_model
    q, qd, _ = states
    h = chain.nonlinear_effects(q, qd)
    g = chain.gravity_torques(q)
    for k in range(len(q)):
        close(h[k], pin.nonLinearEffects(model, data, q[k], qd[k]))
        close(g[k], pin.computeGeneralizedGravity(model, data, q[k]))


def test_forward_dynamics(chain, pinocchio_model, states):
    model, data = pinocchio_model
    q, qd, _ = states
    tau = np.random.default_rng(3).normal(0.0, 20.0, q.shape)
    qdd = chain.forward_dynamics(q, qd, tau)
    for k in range(len(q)):
        # M(q) of the PUMA reaches cond ≈ 1e3 on these states; aba and Cholesky differ by
        # round-off amplified by it.
        m = crba(model, data, q[k])
        close(qdd[k], pin.aba(model, data, q[k], qd[k], tau[k]), rtol=RTOL * np.linalg.cond(m))


def test_regressor_times_parameters_is_rnea(chain, pinocchio_model, states):
    model, data = pinocchio_model
    q, qd, qdd = states
    y = chain.regressor(q, qd, qdd)
    assert y.shape == (len(q), 6, 60)
    tau = y @ puma.standard_parameters()
    for k in range(len(q)):
        close(tau[k], pin.rnea(model, data, q[k], qd[k], qdd[k]))


def test_frame_map_agrees_with_pinocchio_inertia_transform():
    """The numpy frame change used below equals Pinocchio's SE3 action on the links'
    inertias (so that the regressor comparison rests on Pinocchio, not on our algebra)."""
    t = puma.frame_map()
    pi = puma.standard_parameters()
    model = puma.build()
    for i in range(6):
        want = model.inertias[i + 1].toDynamicParameters()
        close(t[10 * i : 10 * i + 10] @ pi, want, rtol=1e-12)


def test_regressor_equals_pinocchio_joint_torque_regressor(chain, pinocchio_model, states):
    """Pinocchio's regressor has 10 columns per body in its joint frame; ours in the DH link
    frame: Y_ours = Y_pin @ T with T the per-link frame change."""
    model, data = pinocchio_model
    q, qd, qdd = states
    t = puma.frame_map()
    y = chain.regressor(q, qd, qdd)
    for k in range(len(q)):
        y_pin = pin.computeJointTorqueRegressor(model, data, q[k], qd[k], qdd[k])
        close(y[k], y_pin @ t)


def test_single_sample_and_broadcasting(chain, states):
    q, qd, qdd = states
    tau = chain.inverse_dynamics(q, qd, qdd)
    close(chain.inverse_dynamics(q[3], qd[3], qdd[3]), tau[3], rtol=0)
    # A single sample broadcasts against a batch.
    tau0 = chain.inverse_dynamics(q, qd[0], np.zeros(6))
    for k in range(len(q)):
        close(tau0[k], chain.inverse_dynamics(q[k], qd[0], np.zeros(6)), rtol=0)
    # Lists and Fortran-ordered arrays are accepted.
    close(chain.inverse_dynamics(q[3].tolist(), qd[3], qdd[3]), tau[3], rtol=0)
    close(chain.mass_matrix(np.asfortranarray(q)), chain.mass_matrix(q), rtol=0)


def numerical_rank(w: np.ndarray) -> int:
    """Rank after scaling non-zero columns to unit norm (numpy SVD, relative 1e-9)."""
    norms = np.linalg.norm(w, axis=0)
    w = w[:, norms > 1e-12 * norms.max()]
    w = w / np.linalg.norm(w, axis=0)
    s = np.linalg.svd(w, compute_uv=False)
    return int(np.sum(s > 1e-9 * s[0]))


def pinocchio_stacked_regressor(model, q, qd, qdd) -> np.ndarray:
    data = model.createData()
    return np.vstack(
        [pin.computeJointTorqueRegressor(model, data, q[k], qd[k], qdd[k]) for k in range(len(q))]
    )


def test_puma_base_parameters(chain, pinocchio_model, states):
    model, data = pinocchio_model
    q, qd, qdd = states
    base = chain.base_parameters()
    # tests/chain_base.rs asserts 36 as well; here the rank of Pinocchio's own stacked
    # regressor decides.
    rng = np.random.default_rng(36)
    qr, qdr, qddr = (rng.uniform(-3, 3, (60, 6)) for _ in range(3))
    assert base.count == numerical_rank(pinocchio_stacked_regressor(model, qr, qdr, qddr)) == 36
    assert len(base) == 36
    assert base.map.shape == (36, 60)
    assert len(base.combinations) == 36
    assert base.independent_names == [chain.parameter_names[j] for j in base.independent]
    assert sorted([*base.independent, *base.dependent]) == list(range(60))
    pi = chain.parameters
    beta = base.base_values(pi)
    close(base.map @ pi, beta, rtol=1e-12)
    yb = chain.base_regressor(q, qd, qdd)
    assert yb.shape == (len(q), 6, 36)
    close(yb, chain.regressor(q, qd, qdd)[:, :, base.independent], rtol=0)
    tau = yb @ beta
    for k in range(len(q)):
        close(tau[k], pin.rnea(model, data, q[k], qd[k], qdd[k]))
    # W·π = W_b·β for any π, not only the chain's own: the map is exact.
    other = np.random.default_rng(1).normal(size=60)
    close(yb @ base.base_values(other), chain.regressor(q, qd, qdd) @ other)


def test_base_parameters_options(chain):
    default = chain.base_parameters()
    again = chain.base_parameters(seed=7, samples=50, rank_tolerance=1e-7)
    assert again.count == default.count
    assert again.rank_tolerance == 1e-7
    assert "Iyy1" in default.combinations[0]


def test_observation_matrix_stacks_regressors(chain, states):
    q, qd, qdd = states
    w = chain.observation_matrix(q, qd, qdd)
    assert w.shape == (6 * len(q), 60)
    close(w, np.vstack(list(chain.regressor(q, qd, qdd))), rtol=0)


def test_friction_columns(states):
    q, qd, qdd = states
    rigid = prrrp.SerialChain.puma560()
    fp = np.array([[4.9, 0.8, 0.1], [8.4, 1.2, -0.2], [4.0, 0.6, 0.05]] * 2)
    chain = prrrp.SerialChain(
        rigid.dh,
        "RRRRRR",
        inertial=rigid.inertial,
        friction=["viscous", "coulomb", "offset"],
        friction_params=fp,
    )
    assert chain.num_params == 78
    assert chain.parameter_names[60:63] == ["fv1", "fc1", "fo1"]
    assert chain.friction == ("viscous", "coulomb", "offset")
    want = fp[:, 0] * qd + fp[:, 1] * np.sign(qd) + fp[:, 2]
    close(chain.inverse_dynamics(q, qd, qdd) - rigid.inverse_dynamics(q, qd, qdd), want)
    y = chain.regressor(q, qd, qdd)
    assert y.shape == (len(q), 6, 78)
    close(y @ chain.parameters, chain.inverse_dynamics(q, qd, qdd))
    # Friction is not gravity.
    close(chain.gravity_torques(q), rigid.gravity_torques(q), rtol=0)
    base = chain.base_parameters()
    assert base.count == 36 + 18
    close(
        chain.base_regressor(q, qd, qdd) @ base.base_values(chain.parameters), y @ chain.parameters
    )
    # Smoothed Coulomb sign.
    smooth = prrrp.SerialChain(
        rigid.dh,
        "RRRRRR",
        inertial=rigid.inertial,
        friction="coulomb",
        friction_params=fp,
        coulomb_smoothing=0.05,
    )
    close(
        smooth.inverse_dynamics(q, qd, qdd) - rigid.inverse_dynamics(q, qd, qdd),
        fp[:, 1] * np.tanh(qd / 0.05),
    )


def test_constructor_round_trip_and_pickle(chain, states):
    import copy
    import pickle

    q, qd, qdd = states
    rebuilt = prrrp.SerialChain(
        chain.dh, list(chain.joint_types), inertial=chain.inertial, gravity=chain.gravity
    )
    close(rebuilt.inverse_dynamics(q, qd, qdd), chain.inverse_dynamics(q, qd, qdd), rtol=0)
    for c in [pickle.loads(pickle.dumps(chain)), copy.deepcopy(chain)]:
        close(c.inverse_dynamics(q, qd, qdd), chain.inverse_dynamics(q, qd, qdd), rtol=0)
    assert "SerialChain(dof=6" in repr(chain)


def test_modified_dh_planar_arm_against_pinocchio():
    """A 3R arm in modified (Craig) DH, built in Pinocchio from Craig's convention: joint i
    sits at Rx(alpha_{i-1})·Tx(a_{i-1}) from joint i-1 and turns about its own z."""
    rows = [(0.0, 0.0, 0.1), (0.3, np.pi / 2, 0.0), (0.25, -0.4, 0.05)]  # (a, alpha, d)
    rng = np.random.default_rng(11)
    bodies = []
    for _ in rows:
        m = rng.uniform(0.5, 2.0)
        c = rng.uniform(-0.1, 0.1, 3)
        a = rng.normal(size=(3, 3))
        bodies.append((m, c, 0.01 * (a @ a.T) + 0.01 * np.eye(3)))
    inertial = []
    model = pin.Model()
    model.gravity.linear = np.array([0.0, -9.81, 0.0])
    parent = 0
    for (a, alpha, d), (m, c, i_c) in zip(rows, bodies, strict=True):
        placement = pin.SE3(puma.rot_x(alpha), np.array([a, 0.0, 0.0]))
        placement = placement * pin.SE3(np.eye(3), np.array([0.0, 0.0, d]))
        parent = model.addJoint(parent, pin.JointModelRZ(), placement, f"j{parent + 1}")
        model.appendBodyToJoint(parent, pin.Inertia(m, c, i_c), pin.SE3.Identity())
        i_o = i_c + m * (c @ c * np.eye(3) - np.outer(c, c))
        inertial.append(np.concatenate([[m], m * c, puma.pack(i_o)]))
    chain = prrrp.SerialChain(
        [[a, alpha, d, 0.0] for a, alpha, d in rows],
        "RRR",
        convention="modified",
        inertial=inertial,
        gravity=[0.0, -9.81, 0.0],
    )
    data = model.createData()
    q, qd, qdd = (rng.normal(size=(20, 3)) for _ in range(3))
    tau = chain.inverse_dynamics(q, qd, qdd)
    mm = chain.mass_matrix(q)
    y = chain.regressor(q, qd, qdd)
    for k in range(20):
        close(tau[k], pin.rnea(model, data, q[k], qd[k], qdd[k]))
        close(mm[k], crba(model, data, q[k]))
        # Modified DH: link frame = joint frame, so the regressors agree column by column.
        close(y[k], pin.computeJointTorqueRegressor(model, data, q[k], qd[k], qdd[k]))


# --- the PRRRP arm as a chain ----------------------------------------------------------


def test_paper_chain_equals_closed_form_robot():
    chain = prrrp.SerialChain.paper()
    robot = prrrp.Robot.paper()
    assert chain.dof == 5
    assert chain.joint_types == "PRRRP"
    q, qd, qdd = random_states(np.random.default_rng(5), 60, scale=3.0)
    close(chain.inverse_dynamics(q, qd, qdd), robot.inverse_dynamics(q, qd, qdd), rtol=1e-10)
    close(chain.mass_matrix(q), robot.mass_matrix(q), rtol=1e-10)
    close(chain.nonlinear_effects(q, qd), robot.nonlinear_effects(q, qd), rtol=1e-10)
    close(chain.gravity_torques(q), robot.gravity(q), rtol=1e-10)


def test_paper_chain_against_pinocchio_and_base_count():
    chain = prrrp.SerialChain.paper()
    model = from_robot(prrrp.Robot.paper())
    data = model.createData()
    q, qd, qdd = random_states(np.random.default_rng(6), 40)
    tau = chain.inverse_dynamics(q, qd, qdd)
    for k in range(len(q)):
        close(tau[k], pin.rnea(model, data, q[k], qd[k], qdd[k]))
    base = chain.base_parameters()
    # The paper's 8 λ plus one lateral first moment the paper drops (tests/chain_base.rs);
    # independently, the rank of Pinocchio's stacked regressor of the hand-built arm.
    qr, qdr, qddr = random_states(np.random.default_rng(9), 60)
    assert base.count == numerical_rank(pinocchio_stacked_regressor(model, qr, qdr, qddr)) == 9
    beta = base.base_values(chain.parameters)
    close(base.map @ chain.parameters, beta, rtol=1e-12)
    close(chain.base_regressor(q, qd, qdd) @ beta, tau)
