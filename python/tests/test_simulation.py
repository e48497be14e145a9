"""Simulators and preprocessing through the Python API, checked against the model."""

from __future__ import annotations

import numpy as np
import pytest

import prrrp

KEYS = ["q_ref", "qd_ref", "qdd_ref", "q", "qd", "qdd", "tau", "q_measured", "tau_measured"]


def sinusoids() -> prrrp.SinusoidReference:
    return prrrp.SinusoidReference(
        offset=[0.15, 0.0, 0.0, 0.0, 0.05],
        amplitude=[0.1, 1.2, 1.0, 0.9, 0.04],
        omega=[1.3, 1.7, 2.3, 2.9, 3.7],
        phase=[0.0, 0.5, 1.0, 1.5, 2.0],
    )


@pytest.fixture(scope="module")
def clean():
    zeros = np.zeros(5)
    return prrrp.simulate_closed_loop(sinusoids(), 6.0, q_noise=zeros, tau_noise=zeros)


def test_closed_loop_shapes(clean):
    n = 301
    assert clean["t"].shape == (n,)
    for k in KEYS:
        assert clean[k].shape == (n, 5), k
        assert clean[k].dtype == np.float64
    np.testing.assert_allclose(clean["t"], 0.02 * np.arange(n), atol=1e-12)


def test_closed_loop_obeys_the_model(clean):
    # The recorded torques, accelerations and states satisfy τ = M(q)q̈ + h(q, q̇).
    robot = prrrp.Robot.paper()
    tau = robot.inverse_dynamics(clean["q"], clean["qd"], clean["qdd"])
    np.testing.assert_allclose(tau, clean["tau"], atol=1e-9)
    # Noise-free measurements are the true signals; the controller tracks the reference.
    np.testing.assert_array_equal(clean["q_measured"], clean["q"])
    np.testing.assert_array_equal(clean["tau_measured"], clean["tau"])
    # Tracking is exact in continuous time; τ is held over each 1 ms RK4 substep, which
    # misses ≈ q⃛·h/2 ≲ 0.9·2.9³·5e-4 ≈ 0.01 rad/s² of acceleration, and kp = 400 turns that
    # into position errors of order 1e-4 rad at most.
    np.testing.assert_allclose(clean["q"], clean["q_ref"], atol=3e-4)
    q_ref, _, _ = sinusoids().eval(clean["t"])
    np.testing.assert_array_equal(q_ref, clean["q_ref"])


def test_closed_loop_excitation_reference():
    exc = prrrp.optimise_excitation(duration=2.0, max_evaluations=60)
    rec = prrrp.simulate_closed_loop(exc, 2.0)
    assert rec["q"].shape == (101, 5)
    # Tracking error from holding τ over each 1 ms substep (see above): the missed
    # acceleration is ≈ q⃛·h/2, over kp = 400; allow 3× for the transient of the PD loop.
    t = np.linspace(0.0, 2.0, 4001)
    jerk = np.abs(np.diff(exc.eval(t)[2], axis=0) / (t[1] - t[0])).max()
    bound = 3 * jerk * 0.5e-3 / 400
    assert np.abs(rec["q"] - rec["q_ref"]).max() < bound


def test_closed_loop_noise_is_seeded_and_sized():
    a = prrrp.simulate_closed_loop(sinusoids(), 4.0, seed=3)
    b = prrrp.simulate_closed_loop(sinusoids(), 4.0, seed=3)
    c = prrrp.simulate_closed_loop(sinusoids(), 4.0, seed=4)
    np.testing.assert_array_equal(a["tau_measured"], b["tau_measured"])
    assert not np.array_equal(a["tau_measured"], c["tau_measured"])
    sigma = np.array([0.5, 1.0, 1.0, 1.0, 0.5]) * 1e-2
    rec = prrrp.simulate_closed_loop(sinusoids(), 4.0, q_noise=np.zeros(5), tau_noise=sigma)
    std = (rec["tau_measured"] - rec["tau"]).std(axis=0)
    # 201 samples: the sample std is within ±30 % of σ with overwhelming probability.
    np.testing.assert_allclose(std, sigma, rtol=0.3)


def test_closed_loop_controller_mismatch_leaves_tracking_error():
    lam = prrrp.Robot.paper().base_parameters()
    zeros = np.zeros(5)
    rec = prrrp.simulate_closed_loop(
        sinusoids(), 3.0, controller_lam=0.5 * lam, q_noise=zeros, tau_noise=zeros
    )
    assert np.abs(rec["q"] - rec["q_ref"]).max() > 1e-4


def test_open_loop_is_rk4_with_zero_order_hold(clean):
    # With one substep each sample is one classical RK4 step of the forward dynamics with
    # τ held: recompute it independently in numpy.
    robot = prrrp.Robot.paper()
    tau = clean["tau"][:6]
    dt = 0.02
    rec = prrrp.simulate_open_loop(clean["q"][0], clean["qd"][0], tau, substeps=1)
    assert set(rec) == {"t", "q", "qd", "qdd", "tau", "q_measured", "tau_measured"}
    assert rec["q"].shape == (6, 5)

    def f(q, qd, u):
        return qd, robot.forward_dynamics(q, qd, u)

    q, qd = clean["q"][0], clean["qd"][0]
    for k in range(5):
        u = tau[k]
        k1 = f(q, qd, u)
        k2 = f(q + dt / 2 * k1[0], qd + dt / 2 * k1[1], u)
        k3 = f(q + dt / 2 * k2[0], qd + dt / 2 * k2[1], u)
        k4 = f(q + dt * k3[0], qd + dt * k3[1], u)
        q = q + dt / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
        qd = qd + dt / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
        np.testing.assert_allclose(rec["q"][k + 1], q, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(rec["qd"][k + 1], qd, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(
        robot.inverse_dynamics(rec["q"], rec["qd"], rec["qdd"]), rec["tau"], atol=1e-9
    )


def test_open_loop_free_fall_of_joint_1():
    # Zero torque: the arm falls along z at g (joint 1 carries everything, d1 = -g t²/2
    # while the other joints stay at rest).
    n = 11
    rec = prrrp.simulate_open_loop(np.zeros(5), np.zeros(5), np.zeros((n, 5)))
    t = rec["t"]
    np.testing.assert_allclose(rec["q"][:, 0], -0.5 * 9.81 * t**2, atol=1e-10)
    np.testing.assert_allclose(rec["q"][:, 1:4], 0.0, atol=1e-12)


def test_simulation_errors(clean):
    with pytest.raises(TypeError, match="reference"):
        prrrp.simulate_closed_loop("nope", 1.0)
    with pytest.raises(prrrp.ShapeMismatchError, match="lam"):
        prrrp.simulate_closed_loop(sinusoids(), 1.0, lam=np.ones(7))
    with pytest.raises(prrrp.ShapeMismatchError, match="q_noise"):
        prrrp.simulate_closed_loop(sinusoids(), 1.0, q_noise=np.ones(3))
    with pytest.raises(prrrp.InvalidParameterError):
        prrrp.simulate_closed_loop(sinusoids(), 1.0, dt=-0.1)
    with pytest.raises(prrrp.NotPositiveDefiniteError):
        prrrp.simulate_closed_loop(sinusoids(), 1.0, lam=-np.ones(8))
    tau = np.zeros((5, 5))
    tau[3, 2] = np.nan
    with pytest.raises(prrrp.NonFiniteError) as e:
        prrrp.simulate_open_loop(np.zeros(5), np.zeros(5), tau)
    assert e.value.row == 3
    with pytest.raises(prrrp.ShapeMismatchError, match="tau"):
        prrrp.simulate_open_loop(np.zeros(5), np.zeros(5), np.zeros(5))


def test_preprocess_recovers_derivatives(clean):
    out = prrrp.preprocess(clean["t"], clean["q"], clean["tau"])
    n = len(out["t"])
    # Default trim: ⌈3·50/5⌉ = 30 samples at each end.
    assert n == 301 - 60
    for k in ("q", "qd", "qdd", "tau"):
        assert out[k].shape == (n, 5)
    np.testing.assert_allclose(out["t"], clean["t"][30:-30], atol=1e-12)
    _, qd, qdd = sinusoids().eval(out["t"])
    # 5 Hz cutoff against content ≤ 0.6 Hz, dt = 0.02: a few per mille of the amplitude.
    amp = np.abs(qdd).max(axis=0)
    assert np.all(np.abs(out["qdd"] - qdd).max(axis=0) < 0.01 * amp)
    assert np.all(np.abs(out["qd"] - qd).max(axis=0) < 0.01 * np.abs(qd).max(axis=0))


def test_preprocess_options_and_errors(clean):
    out = prrrp.preprocess(clean["t"], clean["q"], clean["tau"], trim=10, decimate=2)
    assert len(out["t"]) == len(range(10, 291, 2))
    t, q, tau = clean["t"].copy(), clean["q"].copy(), clean["tau"].copy()
    q[17, 3] = np.nan
    with pytest.raises(prrrp.NonFiniteError, match="q") as e:
        prrrp.preprocess(t, q, tau)
    assert e.value.row == 17
    t2 = t.copy()
    t2[40] = t2[39]
    with pytest.raises(prrrp.NonIncreasingTimeError) as e2:
        prrrp.preprocess(t2, clean["q"], tau)
    assert e2.value.row == 40
    with pytest.raises(prrrp.ShapeMismatchError, match="tau"):
        prrrp.preprocess(t, clean["q"], tau[:-1])
    with pytest.raises(prrrp.ShapeMismatchError, match="t"):
        prrrp.preprocess(np.zeros((3, 1)), clean["q"], tau)
    with pytest.raises(prrrp.TooFewSamplesError):
        prrrp.preprocess(t[:40], clean["q"][:40], tau[:40])
    with pytest.raises(prrrp.InvalidParameterError):
        prrrp.preprocess(t, clean["q"], tau, order=3)
