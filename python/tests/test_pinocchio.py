"""Independent cross-check of the PRRRP dynamics against Pinocchio (pin from PyPI).

Pinocchio computes the rigid-body dynamics of the arm built joint by joint from the physical
parameters (tests/pinocchio_prrrp.py); prrrp computes them in closed form from the 8 base
parameters λ. They must agree to round-off on random states, for the paper's robot and for
robots with other parameters.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from conftest import close_to_scale, random_states
from pinocchio_prrrp import from_robot

import prrrp

RTOL = 1e-10


def close(actual, expected, rtol=RTOL):
    close_to_scale(actual, expected, rtol)


def other_robot(seed: int) -> prrrp.Robot:
    r = np.random.default_rng(seed)
    return prrrp.Robot(
        mass=r.uniform(0.3, 3.0, 5),
        length=r.uniform(0.1, 0.6, 5),
        com=r.uniform(0.0, 0.1, 3),
        inertia_zz=r.uniform(1e-3, 2e-2, 3),
        gravity=r.uniform(1.0, 11.0),
    )


ROBOTS = {
    "paper": prrrp.Robot.paper(),
    "other-1": other_robot(1),
    "other-2": other_robot(2),
}


@pytest.fixture(params=list(ROBOTS))
def case(request):
    robot = ROBOTS[request.param]
    model = from_robot(robot)
    return robot, model, model.createData()


@pytest.fixture(params=[1.0, 10.0], ids=["moderate", "fast"])
def batch(request):
    rng = np.random.default_rng(7 + int(request.param))
    return random_states(rng, 40, scale=request.param)


def close_per_sample(ours, theirs, model, data, *inputs):
    """``ours[k]`` against Pinocchio's ``theirs(model, data, x1[k], x2[k], ...)`` for the
    ``inputs`` x1, x2, ... at every sample k of the batch."""
    for k in range(len(inputs[0])):
        close(ours[k], theirs(model, data, *(x[k] for x in inputs)))


def crba(model, data, q):
    m = pin.crba(model, data, q)
    # Pinocchio fills only the upper triangle.
    return np.triu(m) + np.triu(m, 1).T


def test_mass_matrix(case, batch):
    robot, model, data = case
    q, _, _ = batch
    close_per_sample(robot.mass_matrix(q), crba, model, data, q)


def test_nonlinear_effects(case, batch):
    robot, model, data = case
    q, qd, _ = batch
    close_per_sample(robot.nonlinear_effects(q, qd), pin.nonLinearEffects, model, data, q, qd)


def test_gravity_and_coriolis(case, batch):
    robot, model, data = case
    q, qd, _ = batch
    g = robot.gravity(q)
    c = robot.coriolis(q, qd)
    for k in range(len(q)):
        g_pin = pin.computeGeneralizedGravity(model, data, q[k])
        close(g[k], g_pin)
        close(c[k], pin.nonLinearEffects(model, data, q[k], qd[k]) - g_pin)


def test_inverse_dynamics(case, batch):
    robot, model, data = case
    q, qd, qdd = batch
    close_per_sample(robot.inverse_dynamics(q, qd, qdd), pin.rnea, model, data, q, qd, qdd)


def test_forward_dynamics(case, batch, rng):
    robot, model, data = case
    q, qd, _ = batch
    tau = rng.normal(0.0, 5.0, q.shape)
    close_per_sample(robot.forward_dynamics(q, qd, tau), pin.aba, model, data, q, qd, tau)


def test_regressor_times_lambda(case, batch):
    robot, model, data = case
    q, qd, qdd = batch
    phi = prrrp.regressor(q, qd, qdd, gravity=robot.g)
    close_per_sample(phi @ robot.base_parameters(), pin.rnea, model, data, q, qd, qdd)


def test_model_at_a_user_lambda(batch):
    """The paper robot's model evaluated at another robot's λ is that other robot (same
    gravity): the `lam` keyword path, checked against Pinocchio's model of the other."""
    other = prrrp.Robot(
        mass=[2.0, 0.7, 1.4, 0.9, 0.3],
        length=[0.5, 0.25, 0.2, 0.15, 0.1],
        com=[0.05, 0.03, 0.02],
        inertia_zz=[0.01, 0.004, 0.002],
    )
    model = from_robot(other)
    data = model.createData()
    lam = other.base_parameters()
    paper = prrrp.Robot.paper()
    q, qd, qdd = batch
    tau = paper.inverse_dynamics(q, qd, qdd, lam=lam)
    mm = paper.mass_matrix(q, lam=lam)
    qdd_fd = paper.forward_dynamics(q, qd, tau, lam=lam)
    for k in range(len(q)):
        close(tau[k], pin.rnea(model, data, q[k], qd[k], qdd[k]))
        close(mm[k], crba(model, data, q[k]))
    close(qdd_fd, qdd, rtol=1e-9)


def test_inverse_derivatives(case, batch):
    robot, model, data = case
    q, qd, qdd = batch
    d = robot.inverse_derivatives(q, qd, qdd)
    for k in range(len(q)):
        dq, dv, _ = pin.computeRNEADerivatives(model, data, q[k], qd[k], qdd[k])
        close(d.dtau_dq[k], dq)
        close(d.dtau_dqd[k], dv)


def test_forward_derivatives(case, batch, rng):
    robot, model, data = case
    q, qd, _ = batch
    tau = rng.normal(0.0, 5.0, q.shape)
    d = robot.forward_derivatives(q, qd, tau)
    for k in range(len(q)):
        ddq_dq, ddq_dv, _ = pin.computeABADerivatives(model, data, q[k], qd[k], tau[k])
        close(d.qdd[k], pin.aba(model, data, q[k], qd[k], tau[k]))
        close(d.dqdd_dq[k], ddq_dq, rtol=1e-9)
        close(d.dqdd_dqd[k], ddq_dv, rtol=1e-9)
        # ∂q̈/∂λ = −M⁻¹·Φ(q, q̇, q̈), with M from Pinocchio.
        phi = prrrp.regressor(q[k], qd[k], d.qdd[k], gravity=robot.g)
        close(d.dqdd_dlambda[k], -np.linalg.solve(crba(model, data, q[k]), phi), rtol=1e-9)
