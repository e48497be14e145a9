"""`prrrp.Dataset`, `prrrp.torque_prediction`, `prrrp.validate` and `prrrp.sensitivity`,
each checked against numpy computations on independent quantities (the closed-form model
through `Robot.inverse_dynamics`, `Robot.mass_matrix`, the simulator)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import random_states

import prrrp


def rms(a, b):
    return np.sqrt(np.mean((np.asarray(a) - np.asarray(b)) ** 2, axis=0))


@pytest.fixture
def columns(rng):
    n = 40
    q, qd, qdd = random_states(rng, n)
    t = 0.02 * np.arange(n)
    tau = prrrp.Robot.paper().inverse_dynamics(q, qd, qdd) + rng.normal(0.0, 0.1, (n, 5))
    return t, q, qd, qdd, tau


def test_dataset_round_trip(columns):
    t, q, qd, qdd, tau = columns
    d = prrrp.Dataset(t, q, qd, qdd, tau)
    assert len(d) == 40
    assert prrrp.Dataset.MIN_SAMPLES == 8
    for name, want in zip(["t", "q", "qd", "qdd", "tau"], columns, strict=True):
        got = getattr(d, name)
        assert got.dtype == np.float64
        np.testing.assert_array_equal(got, want)
    assert d.duration == pytest.approx(t[-1] - t[0])
    part = d[5:25]
    assert len(part) == 20
    np.testing.assert_array_equal(part.q, q[5:25])
    np.testing.assert_array_equal(part.t, t[5:25])
    np.testing.assert_array_equal(d[-10:].tau, tau[-10:])
    np.testing.assert_array_equal(d.slice(0, 8).qd, qd[:8])
    # A negative index was an OverflowError of the conversion.
    with pytest.raises(prrrp.InvalidParameterError, match="start"):
        d.slice(-5, 30)
    back = prrrp.Dataset.from_dict(d.to_dict())
    np.testing.assert_array_equal(back.qdd, qdd)
    assert "samples=40" in repr(d)


def test_dataset_from_preprocess_output():
    rng = np.random.default_rng(2)
    t = 0.02 * np.arange(300)
    q = np.column_stack([np.sin(t * (k + 1)) for k in range(5)]) + rng.normal(0, 1e-5, (300, 5))
    tau = rng.normal(size=(300, 5))
    data = prrrp.Dataset.from_dict(prrrp.preprocess(t, q, tau))
    assert len(data) > 200


def test_dataset_errors(columns):
    t, q, qd, qdd, tau = columns
    with pytest.raises(prrrp.ShapeMismatchError, match="qd"):
        prrrp.Dataset(t, q, qd[:-1], qdd, tau)
    with pytest.raises(prrrp.ShapeMismatchError, match=r"`tau`.*\(N, 5\)"):
        prrrp.Dataset(t, q, qd, qdd, tau[:, :4])
    bad = qdd.copy()
    bad[7, 2] = np.nan
    with pytest.raises(prrrp.NonFiniteError) as e:
        prrrp.Dataset(t, q, qd, bad, tau)
    assert e.value.row == 7
    t_bad = t.copy()
    t_bad[12] = t_bad[11]
    with pytest.raises(prrrp.NonIncreasingTimeError) as e:
        prrrp.Dataset(t_bad, q, qd, qdd, tau)
    assert e.value.row == 12
    with pytest.raises(prrrp.TooFewSamplesError) as e:
        prrrp.Dataset(t[:3], q[:3], qd[:3], qdd[:3], tau[:3])
    assert (e.value.needed, e.value.got) == (8, 3)
    d = prrrp.Dataset(t, q, qd, qdd, tau)
    with pytest.raises(prrrp.TooFewSamplesError):
        d[0:3]
    with pytest.raises(prrrp.InvalidParameterError):
        d[::2]
    with pytest.raises(prrrp.ShapeMismatchError):
        d[3]
    with pytest.raises(prrrp.ShapeMismatchError, match="tau"):
        prrrp.Dataset.from_dict({"t": t, "q": q, "qd": qd, "qdd": qdd})


def test_torque_prediction_against_numpy(columns):
    t, q, qd, qdd, tau = columns
    robot = prrrp.Robot.paper()
    lam = robot.base_parameters() * np.linspace(0.9, 1.1, 8)
    cols = {"t": t, "q": q, "qd": qd, "qdd": qdd, "tau": tau}
    for data in [prrrp.Dataset(t, q, qd, qdd, tau), cols]:
        out = prrrp.torque_prediction(data, lam)
        predicted = robot.inverse_dynamics(q, qd, qdd, lam=lam)
        np.testing.assert_allclose(out["predicted"], predicted, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(out["rms"], rms(tau, predicted), rtol=1e-12)
        want = 100 * np.sqrt(np.sum((tau - predicted) ** 2, 0) / np.sum(tau**2, 0))
        np.testing.assert_allclose(out["relative_percent"], want, rtol=1e-12)
    # Gravity enters the prediction: at another g, F1 changes by λ1·Δg (λ8 cancels in F1+F5).
    low = prrrp.torque_prediction(cols, lam, gravity=1.0)
    shift = out["predicted"] - low["predicted"]
    np.testing.assert_allclose(shift[:, 0] + shift[:, 4], lam[0] * 8.81, rtol=1e-12)
    with pytest.raises(prrrp.NonFiniteError):
        prrrp.torque_prediction(cols, lam * np.nan)
    with pytest.raises(prrrp.ShapeMismatchError, match="lam"):
        prrrp.torque_prediction(cols, lam[:5])


def test_validate_against_numpy():
    robot = prrrp.Robot.paper()
    truth = robot.base_parameters()
    off = truth * np.array([1.05, 0.95, 1.1, 1.0, 0.9, 1.02, 1.0, 1.2])
    report = prrrp.validate({"exact": truth, "off": off}, duration=4.0)
    run = report["truth"]
    assert [m["method"] for m in report["methods"]] == ["exact", "off"]
    for m, lam in zip(report["methods"], [truth, off], strict=True):
        np.testing.assert_array_equal(m["lam"], lam)
        # Torque prediction on the true robot's noise-free states, against its measured τ.
        predicted = robot.inverse_dynamics(run["q"], run["qd"], run["qdd"], lam=lam)
        np.testing.assert_allclose(m["torque"]["predicted"], predicted, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(
            m["torque"]["rms"], rms(run["tau_measured"], predicted), rtol=1e-12
        )
        # Trajectory indices against the true run.
        np.testing.assert_allclose(m["indices"]["rms"], rms(run["q"], m["q"]), rtol=1e-12)
        np.testing.assert_allclose(
            m["relative_error_percent"], 100 * np.abs(lam - truth) / truth, rtol=1e-12
        )
        assert np.all(m["indices"]["ai"] <= 1.0)
    # The wrong λ predicts worse torques.
    exact, off_m = report["methods"]
    assert np.all(off_m["torque"]["rms"][:4] > exact["torque"]["rms"][:4])
    # The list form and relative_errors=False.
    plain = prrrp.validate([("off", off)], duration=2.0, relative_errors=False)
    assert plain["methods"][0]["relative_error_percent"] is None
    with pytest.raises(prrrp.InvalidParameterError, match="estimates"):
        prrrp.validate(3.0)
    with pytest.raises(prrrp.ShapeMismatchError):
        prrrp.validate({"bad": truth[:3]})


# The core's default validation reference, written from its documentation: periods 5, 4,
# 3.5, 3, 2.5 s, starting at rest (phase -π/2).
REFERENCE = {
    "offset": [0.15, 0.2, -0.3, 0.1, 0.05],
    "amplitude": [0.1, 1.2, 1.1, 1.2, 0.03],
    "omega": 2 * np.pi / np.array([5.0, 4.0, 3.5, 3.0, 2.5]),
    "phase": np.full(5, -np.pi / 2),
}


def test_sensitivity_non_physical_iff_mass_matrix_indefinite():
    robot = prrrp.Robot.paper()
    lam0 = robot.base_parameters()
    s = prrrp.sensitivity()
    np.testing.assert_allclose(s["factors"], np.linspace(0.5, 1.5, 11), rtol=1e-12)
    np.testing.assert_allclose(s["ranges"], np.column_stack([0.5 * lam0, 1.5 * lam0]))
    assert s["rms"].shape == (8, 11, 5)
    assert s["physical"].shape == (8, 11)
    assert s["physical"].dtype == np.bool_
    # The configurations the motion visits: the reference (tracking errors are small).
    ref = prrrp.SinusoidReference(**REFERENCE)
    q, _, _ = ref.eval(np.arange(0.0, 10.0 + 1e-9, 0.02))
    for i in range(8):
        for k, f in enumerate(s["factors"]):
            lam = lam0.copy()
            lam[i] *= f
            m = robot.mass_matrix(q, lam=np.tile(lam, (len(q), 1)))
            indefinite = np.linalg.eigvalsh(m).min() <= 0.0
            assert s["physical"][i, k] == (not indefinite), (i, f)
            assert np.isnan(s["rms"][i, k]).all() == indefinite
    # The paper's ±50 % makes some λ non-physical (Table 6's ranges are the physical ones).
    assert not s["physical"].all()
    # At the nominal factor the varied robot is the nominal one.
    np.testing.assert_array_equal(s["rms"][:, 5], 0.0)


def test_sensitivity_rms_against_simulator():
    robot = prrrp.Robot.paper()
    lam0 = robot.base_parameters()
    s = prrrp.sensitivity(points=3, range=0.3, duration=3.0, threads=1)
    ref = prrrp.SinusoidReference(**REFERENCE)
    zero = np.zeros(5)
    nominal = prrrp.simulate_closed_loop(ref, 3.0, lam=lam0, q_noise=zero, tau_noise=zero)
    lam = lam0.copy()
    lam[2] *= 1.3
    varied = prrrp.simulate_closed_loop(
        ref, 3.0, lam=lam, controller_lam=lam0, q_noise=zero, tau_noise=zero
    )
    np.testing.assert_allclose(s["rms"][2, 2], rms(nominal["q"], varied["q"]), rtol=1e-12)
    with pytest.raises(prrrp.InvalidParameterError, match="range"):
        prrrp.sensitivity(range=1.5)
    with pytest.raises(prrrp.InvalidParameterError, match="points"):
        prrrp.sensitivity(points=1)
