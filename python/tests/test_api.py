"""The Python API: shapes of single samples and batches, broadcasting, input conversion,
and physics identities that need no other library."""

from __future__ import annotations

import copy
import pickle
import sys
import threading
import time

import numpy as np
import pytest

import prrrp

# (method name, number of joint-space arguments, output shape of one sample)
METHODS = [
    ("mass_matrix", 1, (5, 5)),
    ("gravity", 1, (5,)),
    ("coriolis", 2, (5,)),
    ("nonlinear_effects", 2, (5,)),
    ("inverse_dynamics", 3, (5,)),
    ("forward_dynamics", 3, (5,)),
    ("regressor", 3, (5, 8)),
    ("kinetic_energy", 2, ()),
    ("potential_energy", 1, ()),
]


def call(robot, name, nargs, q, qd, qdd, **kw):
    return getattr(robot, name)(*(q, qd, qdd)[:nargs], **kw)


@pytest.mark.parametrize(("name", "nargs", "shape"), METHODS)
def test_single_and_batch_shapes_agree(robot, states, name, nargs, shape):
    q, qd, qdd = states
    batch = call(robot, name, nargs, q, qd, qdd)
    assert isinstance(batch, np.ndarray)
    assert batch.dtype == np.float64
    assert batch.shape == (len(q), *shape)
    for k in (0, 17, len(q) - 1):
        single = call(robot, name, nargs, q[k], qd[k], qdd[k])
        if shape == ():
            assert isinstance(single, float)
        else:
            assert single.shape == shape
        # The same code runs per sample: bit-identical.
        np.testing.assert_array_equal(single, batch[k])


def test_module_regressor_shapes(states):
    q, qd, qdd = states
    assert prrrp.regressor(q[0], qd[0], qdd[0]).shape == (5, 8)
    assert prrrp.regressor(q, qd, qdd).shape == (len(q), 5, 8)


def test_empty_batch(robot):
    z = np.zeros((0, 5))
    assert robot.inverse_dynamics(z, z, z).shape == (0, 5)
    assert robot.mass_matrix(z).shape == (0, 5, 5)
    assert prrrp.regressor(z, z, z).shape == (0, 5, 8)


def test_single_samples_broadcast_against_a_batch(robot, states):
    q, qd, qdd = states
    tau = robot.inverse_dynamics(q, qd[3], qdd)
    expected = robot.inverse_dynamics(q, np.broadcast_to(qd[3], q.shape), qdd)
    np.testing.assert_array_equal(tau, expected)


def test_lambda_batch(robot, states):
    """A λ per sample (e.g. an estimator's trajectory of estimates)."""
    q, qd, qdd = states
    lam = robot.base_parameters() * np.linspace(0.5, 2.0, len(q))[:, None]
    tau = robot.inverse_dynamics(q, qd, qdd, lam=lam)
    for k in (0, 9, len(q) - 1):
        np.testing.assert_array_equal(
            tau[k], robot.inverse_dynamics(q[k], qd[k], qdd[k], lam=lam[k])
        )


def test_inputs_convertible_to_float_are_accepted(robot, states):
    q, qd, qdd = states
    expected = robot.inverse_dynamics(q[:4], qd[:4], qdd[:4])
    as_list = robot.inverse_dynamics(q[:4].tolist(), qd[:4].tolist(), tuple(map(tuple, qdd[:4])))
    np.testing.assert_array_equal(as_list, expected)
    ints = np.arange(5)
    np.testing.assert_array_equal(
        robot.inverse_dynamics(ints, ints, ints),
        robot.inverse_dynamics(ints.astype(float), ints.astype(float), ints.astype(float)),
    )
    q32 = q[:4].astype(np.float32)
    np.testing.assert_array_equal(robot.mass_matrix(q32), robot.mass_matrix(q32.astype(np.float64)))


def test_strided_and_fortran_inputs(robot, states):
    q, qd, qdd = states
    expected = robot.inverse_dynamics(q, qd, qdd)
    wide = np.zeros((len(q), 10))
    wide[:, ::2] = q
    np.testing.assert_array_equal(
        robot.inverse_dynamics(wide[:, ::2], np.asfortranarray(qd), qdd[::1]), expected
    )
    np.testing.assert_array_equal(
        robot.inverse_dynamics(q[::-1], qd[::-1], qdd[::-1]), expected[::-1]
    )


def test_base_parameters_from_table_3(robot):
    """λ from the physical parameters with the (corrected) Table 3 formulas, written out
    here independently, and the values quoted in the notes."""
    m1, m2, m3, m4, m5 = robot.mass
    _, l2, l3, l4, _ = robot.length
    lc2, lc3, lc4 = robot.com
    i2, i3, i4 = robot.inertia_zz
    expected = [
        m1 + m2 + m3 + m4,
        m2 * lc2**2 + (m3 + m4 + m5) * l2**2 + i2,
        m3 * lc3**2 + (m4 + m5) * l3**2 + i3,
        l2 * (m3 * lc3 + (m4 + m5) * l3),
        m4 * lc4**2 + m5 * l4**2 + i4,
        l2 * (m4 * lc4 + m5 * l4),
        l3 * (m4 * lc4 + m5 * l4),
        m5,
    ]
    lam = robot.base_parameters()
    assert lam.shape == (8,)
    np.testing.assert_allclose(lam, expected, rtol=1e-15)
    quoted = [4.297000, 0.108632, 0.067712, 0.066061, 0.026792, 0.025141, 0.025141, 0.511400]
    np.testing.assert_allclose(lam, quoted, atol=5e-7)


def test_paper_parameters(robot):
    np.testing.assert_array_equal(robot.mass, [1.228, 1.023, 1.023, 1.023, 0.5114])
    np.testing.assert_array_equal(robot.length, [0.524, 0.2, 0.2, 0.2, 0.14])
    np.testing.assert_array_equal(robot.com, [0.0229] * 3)
    np.testing.assert_array_equal(robot.inertia_zz, [0.0058] * 3)
    assert robot.g == 9.81
    assert prrrp.Robot() == robot
    assert len(robot.dh_table()) == 5
    assert robot.dh_table()[3]["alpha"] == pytest.approx(np.pi)


def test_constructor_keywords():
    r = prrrp.Robot(mass=[1, 2, 3, 4, 5], gravity=3.7)
    np.testing.assert_array_equal(r.mass, [1, 2, 3, 4, 5])
    np.testing.assert_array_equal(r.length, prrrp.Robot.paper().length)
    assert r.g == 3.7
    assert r != prrrp.Robot.paper()
    with pytest.raises(TypeError):
        prrrp.Robot([1, 2, 3, 4, 5])  # keyword-only


def test_pickle_copy_repr():
    r = prrrp.Robot(mass=[1.5, 2, 3, 4, 5], com=[0.01, 0.02, 0.03], gravity=1.62)
    assert pickle.loads(pickle.dumps(r)) == r
    assert copy.deepcopy(r) == r
    assert eval(repr(r), {"Robot": prrrp.Robot}) == r


def test_forward_inverts_inverse(robot, states):
    q, qd, qdd = states
    tau = robot.inverse_dynamics(q, qd, qdd)
    np.testing.assert_allclose(robot.forward_dynamics(q, qd, tau), qdd, rtol=1e-9, atol=1e-9)


def test_inverse_dynamics_decomposes(robot, states):
    """τ = M·q̈ + C·q̇ + G, and the nonlinear effects are τ at q̈ = 0."""
    q, qd, qdd = states
    tau = robot.inverse_dynamics(q, qd, qdd)
    m = robot.mass_matrix(q)
    h = robot.nonlinear_effects(q, qd)
    np.testing.assert_allclose(tau, np.einsum("nij,nj->ni", m, qdd) + h, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(h, robot.coriolis(q, qd) + robot.gravity(q), rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(
        h, robot.inverse_dynamics(q, qd, np.zeros(5)), rtol=1e-13, atol=1e-13
    )


def test_mass_matrix_symmetric_positive_definite(robot, states):
    m = robot.mass_matrix(states[0])
    np.testing.assert_allclose(m, np.swapaxes(m, 1, 2), rtol=0, atol=1e-15)
    assert np.all(np.linalg.eigvalsh(m) > 0)


def test_kinetic_energy_is_quadratic_form(robot, states):
    q, qd, _ = states
    t = robot.kinetic_energy(q, qd)
    np.testing.assert_allclose(
        t, 0.5 * np.einsum("ni,nij,nj->n", qd, robot.mass_matrix(q), qd), rtol=1e-13
    )


def test_power_balance(robot, rng):
    """d/dt (T + U) = q̇ᵀ·τ along a smooth motion (central differences in time)."""
    t = np.linspace(0.0, 1.0, 2001)
    dt = t[1] - t[0]
    a = rng.normal(0, 1, (3, 5))
    q = a[0] * np.sin(2 * t)[:, None] + a[1] * np.cos(3 * t)[:, None] + a[2] * t[:, None] ** 2
    qd = np.gradient(q, dt, axis=0, edge_order=2)
    qdd = np.gradient(qd, dt, axis=0, edge_order=2)
    energy = robot.kinetic_energy(q, qd) + robot.potential_energy(q)
    power = np.einsum("ni,ni->n", qd, robot.inverse_dynamics(q, qd, qdd))
    de = np.gradient(energy, dt)
    np.testing.assert_allclose(de[5:-5], power[5:-5], atol=1e-4 * np.max(np.abs(power)))


def test_regressor_times_lambda_is_inverse_dynamics(robot, states):
    q, qd, qdd = states
    tau = prrrp.regressor(q, qd, qdd) @ robot.base_parameters()
    np.testing.assert_allclose(tau, robot.inverse_dynamics(q, qd, qdd), rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(robot.regressor(q, qd, qdd), prrrp.regressor(q, qd, qdd))


def test_regressor_gravity_keyword(states):
    q, qd, qdd = states
    r = prrrp.Robot(gravity=1.62)
    np.testing.assert_array_equal(
        prrrp.regressor(q, qd, qdd, gravity=1.62), r.regressor(q, qd, qdd)
    )
    zero_g = prrrp.regressor(q[0], qd[0], np.zeros(5), gravity=0.0)
    assert zero_g[0, 0] == 0.0


def test_observation_matrix_stacks_regressors(states):
    q, qd, qdd = states
    w = prrrp.observation_matrix(q, qd, qdd)
    assert w.shape == (5 * len(q), 8)
    np.testing.assert_array_equal(w, prrrp.regressor(q, qd, qdd).reshape(-1, 8))
    s = prrrp.singular_values(w)
    np.testing.assert_allclose(s, np.linalg.svd(w, compute_uv=False), rtol=1e-10)
    assert prrrp.condition_number(w) == pytest.approx(s[0] / s[-1], rel=1e-12)
    assert prrrp.condition_number(np.zeros((10, 8))) == np.inf


def test_derivatives_unpack_and_match_finite_differences(robot, states):
    q, qd, qdd = states[0][0], states[1][0], states[2][0]
    dq, dqd = robot.inverse_derivatives(q, qd, qdd)
    assert dq.shape == dqd.shape == (5, 5)
    h = 1e-6
    for j in range(5):
        e = np.zeros(5)
        e[j] = h
        fd = (robot.inverse_dynamics(q + e, qd, qdd) - robot.inverse_dynamics(q - e, qd, qdd)) / (
            2 * h
        )
        np.testing.assert_allclose(dq[:, j], fd, atol=1e-7)
    tau = robot.inverse_dynamics(q, qd, qdd)
    f = robot.forward_derivatives(q, qd, tau)
    qdd_f, _, _, dl = f
    assert len(f) == 4
    np.testing.assert_allclose(qdd_f, qdd, atol=1e-9)
    lam = robot.base_parameters()
    for j in range(8):
        e = np.zeros(8)
        e[j] = 1e-6 * lam[j]
        fd = (
            robot.forward_dynamics(q, qd, tau, lam=lam + e)
            - robot.forward_dynamics(q, qd, tau, lam=lam - e)
        ) / (2 * e[j])
        np.testing.assert_allclose(dl[:, j], fd, rtol=1e-5, atol=1e-6)
    batch = robot.forward_derivatives(states[0], states[1], robot.inverse_dynamics(*states))
    assert batch.dqdd_dlambda.shape == (len(states[0]), 5, 8)


def test_batch_releases_the_gil(robot, rng):
    """While one thread is inside a long batch call, another thread keeps running Python
    code. With the GIL held, the observer could run only before the call or after it."""
    from conftest import random_states

    q, qd, qdd = random_states(rng, 1_000_000)
    state = {"start": None, "end": None}

    def work():
        state["start"] = time.perf_counter()
        robot.inverse_dynamics(q, qd, qdd)
        state["end"] = time.perf_counter()

    seen = []
    worker = threading.Thread(target=work)
    worker.start()
    while worker.is_alive():
        seen.append(time.perf_counter())
    worker.join()
    start, end = state["start"], state["end"]
    inside = [t for t in seen if start < t < end]
    assert inside, "the observer thread never ran during the batch call"
    # With the GIL held the observer could only slip in within a switch interval (5 ms) of
    # the call's ends. The inputs are converted with the GIL held (about half of the call
    # in an unoptimised build), so require a fifth of the call, and well over the interval.
    span = inside[-1] - inside[0]
    assert span > max(0.2 * (end - start), 4 * sys.getswitchinterval()), (span, end - start)


def test_threads_share_a_robot(robot, rng):
    """Batches release the GIL; concurrent calls on one (immutable) robot agree."""
    from conftest import random_states

    q, qd, qdd = random_states(rng, 20000)
    expected = robot.inverse_dynamics(q, qd, qdd)
    results = [None] * 4

    def work(i):
        results[i] = robot.inverse_dynamics(q, qd, qdd)

    threads = [threading.Thread(target=work, args=(i,)) for i in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for r in results:
        np.testing.assert_array_equal(r, expected)
