"""Least squares and the online estimators recovering λ on simulated data."""

from __future__ import annotations

import numpy as np
import pytest

import prrrp

TRUTH = prrrp.Robot.paper().base_parameters()


@pytest.fixture(scope="module")
def data():
    """Noise-free closed-loop tracking of a sum-of-sinusoids reference (true signals)."""
    ref = prrrp.SinusoidReference(
        offset=[0.15, 0.0, 0.0, 0.0, 0.05],
        amplitude=[0.1, 1.2, 1.0, 0.9, 0.04],
        omega=[1.3, 1.7, 2.3, 2.9, 3.7],
        phase=[0.0, 0.5, 1.0, 1.5, 2.0],
    )
    zeros = np.zeros(5)
    return prrrp.simulate_closed_loop(ref, 8.0, q_noise=zeros, tau_noise=zeros)


def cols(d):
    return d["q"], d["qd"], d["qdd"], d["tau"]


def test_least_squares_exact_on_true_signals(data):
    res = prrrp.least_squares(*cols(data))
    # τ = Φλ holds to rounding on the true signals: λ comes back to ~cond·ε.
    np.testing.assert_allclose(res.lam, TRUTH, rtol=1e-8)
    assert res.lam.shape == res.std.shape == res.rsd_percent.shape == (8,)
    assert res.singular_values.shape == (8,)
    assert res.joint_variances.shape == (5,)
    assert res.samples == 401
    w = prrrp.observation_matrix(data["q"], data["qd"], data["qdd"])
    s = np.linalg.svd(w, compute_uv=False)
    np.testing.assert_allclose(res.singular_values, s, rtol=1e-10)
    assert res.cond == pytest.approx(s[0] / s[-1], rel=1e-10)
    assert res.sigma2 < 1e-20
    assert "LeastSquaresResult" in repr(res)


def test_least_squares_on_preprocessed_positions(data):
    # The paper's pipeline: only q and τ measured, q̇, q̈ from filtered differences.
    d = prrrp.preprocess(data["t"], data["q"], data["tau"])
    res = prrrp.least_squares(d["q"], d["qd"], d["qdd"], d["tau"])
    np.testing.assert_allclose(res.lam, TRUTH, rtol=0.01)


def test_least_squares_noisy_std_covers_error():
    ref = prrrp.optimise_excitation(duration=6.0, max_evaluations=200, seed=2)
    # Equal torque noise on every joint: the model of ordinary least squares holds, λ̂ is
    # unbiased with the reported σ, and 5σ covers every entry.
    sigma = np.full(5, 0.01)
    rec = prrrp.simulate_closed_loop(ref, 6.0, q_noise=np.zeros(5), tau_noise=sigma, seed=5)
    res = prrrp.least_squares(rec["q"], rec["qd"], rec["qdd"], rec["tau_measured"])
    assert np.all(np.abs(res.lam - TRUTH) < 5 * res.std)
    assert res.sigma2 == pytest.approx(0.01**2, rel=0.2)
    np.testing.assert_allclose(res.rsd_percent, 100 * res.std / np.abs(res.lam))
    # Different noise per joint (the default sensors): weighted least squares.
    rec = prrrp.simulate_closed_loop(ref, 6.0, q_noise=np.zeros(5), seed=6)
    wres = prrrp.least_squares(rec["q"], rec["qd"], rec["qdd"], rec["tau_measured"], weighted=True)
    assert np.all(np.abs(wres.lam - TRUTH) < 5 * wres.std)


def test_least_squares_errors(data):
    q, qd, qdd, tau = cols(data)
    with pytest.raises(prrrp.TooFewSamplesError):
        prrrp.least_squares(q[:1], qd[:1], qdd[:1], tau[:1])
    with pytest.raises(prrrp.ShapeMismatchError, match="tau"):
        prrrp.least_squares(q, qd, qdd, tau[:-1])
    with pytest.raises(prrrp.ShapeMismatchError, match="qd"):
        prrrp.least_squares(q, qd[:, :4], qdd, tau)
    with pytest.raises(prrrp.ShapeMismatchError, match="q"):
        prrrp.least_squares(q[0], qd, qdd, tau)
    bad = qdd.copy()
    bad[7, 1] = np.nan
    with pytest.raises(prrrp.NonFiniteError) as e:
        prrrp.least_squares(q, qd, bad, tau)
    assert e.value.row == 7
    # A trajectory where only joint 1 moves excites neither the planar links nor λ8 apart
    # from λ1: rank deficient, with the unidentifiable directions.
    n = 50
    t = np.linspace(0, 1, n)
    q1 = np.zeros((n, 5))
    q1[:, 0] = np.sin(t)
    qdd1 = np.zeros((n, 5))
    qdd1[:, 0] = -np.sin(t)
    with pytest.raises(prrrp.RankDeficientError) as e2:
        prrrp.least_squares(q1, np.zeros((n, 5)), qdd1, np.zeros((n, 5)))
    assert e2.value.directions
    assert e2.value.cond > 1e10 or not np.isfinite(e2.value.cond)
    assert isinstance(e2.value, ValueError)


def test_rls_matches_least_squares(data):
    rls = prrrp.Rls(0.5 * TRUTH)
    lam = rls.run(*cols(data))
    # P₀ = 1e6·I regularises by ‖λ − λ₀‖²/1e6: negligible against 401·5 exact equations.
    np.testing.assert_allclose(lam, TRUTH, rtol=1e-4)
    np.testing.assert_array_equal(rls.estimate, lam)


def test_step_equals_run(data):
    q, qd, qdd, tau = cols(data)
    a, b = prrrp.Rls(0.5 * TRUTH), prrrp.Rls(0.5 * TRUTH)
    for k in range(30):
        last = a.step(q[k], qd[k], qdd[k], tau[k])
    lam, hist = b.run(q[:30], qd[:30], qdd[:30], tau[:30], history_every=10)
    np.testing.assert_array_equal(last, lam)
    assert hist.shape == (3, 8)
    np.testing.assert_array_equal(hist[-1], lam)
    a.reset()
    np.testing.assert_array_equal(a.estimate, 0.5 * TRUTH)


def test_adaline_train_converges(data):
    ada = prrrp.Adaline(0.7 * TRUTH)
    err = ada.train(*cols(data), 30)
    assert err.shape == (30,)
    # Consistent equations: the normalised LMS (Kaczmarz) error shrinks epoch after epoch.
    assert err[-1] < 0.1 * err[0]
    rel0 = np.abs(0.7 * TRUTH - TRUTH) / TRUTH
    rel = np.abs(ada.estimate - TRUTH) / TRUTH
    assert rel.max() < 0.5 * rel0.max()
    with pytest.raises(prrrp.InvalidParameterError, match="rule"):
        prrrp.Adaline(rule="nope")
    d = prrrp.Adaline(0.7 * TRUTH, rule="delta")
    assert d.run(*cols(data)).shape == (8,)


def test_hopfield_reduces_error(data):
    hop = prrrp.Hopfield(0.7 * TRUTH)
    lam, hist = hop.run(*cols(data), history_every=100)
    assert hist.shape == (4, 8)
    assert np.abs(lam - TRUTH).max() < np.abs(0.7 * TRUTH - TRUTH).max()
    err = hop.train(*cols(data), 2)
    assert err.shape == (2,)


def test_ekf_from_positions(data):
    ekf = prrrp.Ekf(0.8 * TRUTH)
    lam = ekf.run(*cols(data))
    assert lam.shape == (8,)
    assert ekf.parameter_std.shape == (8,)
    assert ekf.skipped_updates == 0
    # Noise-free positions: the dominant mass parameters λ1, λ8 are found within a few %
    # (Euler discretisation biases the small planar ones by O(h), see EkfConfig).
    np.testing.assert_allclose(lam[[0, 7]], TRUTH[[0, 7]], rtol=0.05)
    with pytest.raises(prrrp.InvalidParameterError, match="measurement"):
        prrrp.Ekf(measurement="torques")


def test_ekf_covariances_are_settable(data):
    q, qd, qdd, tau = cols(data)
    lam0 = 0.9 * TRUTH
    ekf = prrrp.Ekf(lam0)
    # Documented defaults: P0 = diag(1e-3², 1.0², (0.5·|λ0|)²), x0 = [0, 0, λ0].
    want = np.concatenate([np.full(5, 1e-6), np.full(5, 1.0), (0.5 * lam0) ** 2])
    np.testing.assert_allclose(ekf.covariance, np.diag(want), rtol=1e-15)
    np.testing.assert_array_equal(ekf.state, np.concatenate([np.zeros(10), lam0]))

    p0 = np.diag(want * 0.25)
    p0[10, 11] = p0[11, 10] = 0.1 * np.sqrt(p0[10, 10] * p0[11, 11])
    ekf.set_initial_covariance(p0)
    np.testing.assert_array_equal(ekf.covariance, p0)

    # A measurement noise of 1e12 makes the update negligible: λ is constant in the model,
    # so one step leaves λ̂ at λ0 and adds exactly Q_λ to P_λλ.
    ekf.set_measurement_noise(np.full(5, 1e12), np.full(5, 1e12))
    qv = np.concatenate([np.full(10, 1e-9), np.full(8, 1e-4) * lam0**2])
    ekf.set_process_noise(qv)
    before = ekf.covariance[10:, 10:].copy()
    lam = ekf.step(q[0], qd[0], qdd[0], tau[0])
    np.testing.assert_allclose(lam, lam0, rtol=1e-9)
    np.testing.assert_allclose(ekf.covariance[10:, 10:], before + np.diag(qv[10:]), rtol=1e-9)
    cov = ekf.covariance
    np.testing.assert_array_equal(cov, cov.T)

    # A precise position sensor instead pulls the position state onto the measurement.
    sharp = prrrp.Ekf(lam0, init_from_first_measurement=False)
    sharp.set_measurement_noise(np.full(5, 1e-12), np.full(5, 1.0))
    sharp.step(q[0], qd[0], qdd[0], tau[0])
    # q_post = z·P/(P + R) from q_prior = 0 with P = 1e-6 and R = 1e-12; P0 is diagonal,
    # so q̇ stays 0 and the prediction keeps q_post.
    np.testing.assert_allclose(sharp.state[:5], q[0], rtol=2e-6)

    with pytest.raises(prrrp.ShapeMismatchError, match="p0"):
        ekf.set_initial_covariance(np.eye(17))
    asym = np.eye(18)
    asym[0, 1] = 0.5
    with pytest.raises(prrrp.InvalidParameterError, match="symmetric"):
        ekf.set_initial_covariance(asym)
    with pytest.raises(prrrp.NotPositiveDefiniteError):
        ekf.set_initial_covariance(-np.eye(18))
    with pytest.raises(prrrp.InvalidParameterError):
        ekf.set_process_noise(-np.ones(18))
    with pytest.raises(prrrp.InvalidParameterError):
        ekf.set_measurement_noise(np.zeros(5), np.ones(5))
    with pytest.raises(prrrp.ShapeMismatchError, match="velocities"):
        ekf.set_measurement_noise(np.ones(5), np.ones(4))


def test_estimator_errors(data):
    q, qd, qdd, tau = cols(data)
    rls = prrrp.Rls()
    with pytest.raises(prrrp.ShapeMismatchError, match="lam0"):
        prrrp.Rls(np.ones(3))
    with pytest.raises(prrrp.ShapeMismatchError, match="tau"):
        rls.step(q[0], qd[0], qdd[0], tau[:2])
    bad = tau.copy()
    bad[12, 0] = np.inf
    with pytest.raises(prrrp.NonFiniteError) as e:
        rls.run(q, qd, qdd, bad)
    assert e.value.row == 12
    with pytest.raises(prrrp.InvalidParameterError, match="history_every"):
        rls.run(q, qd, qdd, tau, history_every=0)
