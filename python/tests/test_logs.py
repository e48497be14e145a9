"""prrrp.preprocess_log on a degraded 7-joint log (jittered clock, repeated rows, torque
offsets) against the analytic trajectory, and Dataset of any joint count."""

import numpy as np
import pytest

import prrrp


def analytic(t, n):
    k = np.arange(1, n + 1)
    w = 2 * np.pi * 0.3 * k  # 0.3 ... 2.1 Hz
    q = 0.5 * np.sin(np.outer(t, w))
    qd = 0.5 * w * np.cos(np.outer(t, w))
    qdd = -0.5 * w**2 * np.sin(np.outer(t, w))
    return q, qd, qdd


def jittered_log(n=7, seconds=8.0, seed=0):
    rng = np.random.default_rng(seed)
    steps = rng.uniform(0.7e-3, 1.3e-3, int(seconds / 1e-3))
    steps[::97] = 8.8e-3  # occasional long steps
    t = np.concatenate([[0.0], np.cumsum(steps)])
    t = t[t < seconds]
    repeat = rng.random(len(t)) < 0.05
    repeat[0] = False
    idx = np.arange(len(t))
    for i in np.flatnonzero(repeat):  # in order, so that runs of repeats chain
        idx[i] = idx[i - 1]  # an exact copy of the previous row, time stamp included
    q, _, _ = analytic(t[idx], n)
    offsets = np.linspace(-0.5, 0.5, n)
    tau = q * 3.0 + offsets
    return t[idx], q, tau, int(repeat.sum())


def test_degraded_log_is_cleaned_and_differentiated():
    t, q, tau, repeats = jittered_log()
    data, report = prrrp.preprocess_log(t, q, tau, decimate_to_hz=200.0, max_gap_s=0.02)
    assert report["repeated_rows"] == repeats
    assert report["output_rate_hz"] == pytest.approx(200.0)
    assert data.dof == 7
    q_true, qd_true, qdd_true = analytic(data.t, 7)
    # 10 Hz cut-off on harmonics up to 2.1 Hz: the pass band is flat to ~1e-4; linear
    # interpolation at ~1 kHz adds < 1e-5 rad. Tolerances are a few times those budgets.
    assert np.abs(data.q - q_true).max() < 2e-3
    assert np.abs(data.qd - qd_true).max() < 2e-2 * np.abs(qd_true).max()
    assert np.abs(data.qdd - qdd_true).max() < 5e-2 * np.abs(qdd_true).max()
    assert np.abs(data.tau - (3.0 * data.q + np.linspace(-0.5, 0.5, 7))).max() < 1e-2


def test_backwards_time_names_the_row():
    t, q, tau, _ = jittered_log(seconds=1.0)
    t = t.copy()
    t[300] = t[299] - 1e-3
    with pytest.raises(prrrp.NonIncreasingTimeError) as e:
        prrrp.preprocess_log(t, q, tau)
    assert e.value.row == 300


def test_dataset_of_any_joint_count():
    t = 0.01 * np.arange(30)
    z = np.zeros((30, 7))
    data = prrrp.Dataset(t, z, z, z, z)
    assert data.dof == 7
    assert data.q.shape == (30, 7)
    assert data[5:20].dof == 7
    with pytest.raises(prrrp.ShapeMismatchError):
        prrrp.Dataset(t, z, z, z, np.zeros((30, 6)))
