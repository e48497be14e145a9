"""Simulation and torque-prediction validation of any chain (`simulate_chain`,
`ChainTrajectory`, `validate_model`), checked against Pinocchio and physics: the recorded
noiseless torques equal `pinocchio.rnea` (plus the friction law) at the recorded states,
exact-model tracking converges with the step, a perfect model validates with RMS 0 and
agreement index 1, and bad inputs raise typed errors."""

import importlib.metadata
import itertools

import numpy as np
import pytest

import prrrp

pin = pytest.importorskip("pinocchio")

ROBOTS_DIR = importlib.metadata.distribution("example-robot-data").locate_file(
    "cmeel.prefix/share/example-robot-data/robots"
)
PANDA = str(ROBOTS_DIR / "panda_description/urdf/panda.urdf")
FINGERS = ["panda_finger_joint1", "panda_finger_joint2"]
# Viscous, Coulomb (tanh over 0.1 rad/s) and offset per joint, smaller on the light wrist.
FRICTION = np.array([[0.6, 0.4, 0.05]] * 4 + [[0.1, 0.05, 0.01]] * 2 + [[0.02, 0.01, 0.005]])
SMOOTHING = 0.1


@pytest.fixture(scope="module")
def panda():
    return prrrp.SerialChain.from_urdf(PANDA, tip="panda_link8").with_friction(
        "viscous+coulomb+offset", FRICTION, coulomb_smoothing=SMOOTHING
    )


@pytest.fixture(scope="module")
def pin_panda():
    model = pin.buildModelFromUrdf(PANDA)
    ids = [model.getJointId(j) for j in FINGERS]
    model = pin.buildReducedModel(model, ids, pin.neutral(model))
    return model, model.createData()


def fourier(n, scale=0.5, harmonics=3):
    """A 0.2 Hz Fourier excitation starting at rest (sum a = 0, sum l*b = 0)."""
    a = scale * np.tile([0.6, -0.2, -0.4], (n, 1)) * (1 + 0.1 * np.arange(n))[:, None]
    b = scale * np.tile([0.3, 0.15, -0.2], (n, 1)) * (1 + 0.1 * np.arange(n))[:, None]
    offsets = 0.1 * np.arange(n) - 0.2
    return prrrp.ChainTrajectory.fourier(2 * np.pi * 0.2, offsets, a, b)


def friction_torque(qd):
    fv, fc, fo = FRICTION.T
    return fv * qd + fc * np.tanh(qd / SMOOTHING) + fo


def test_recorded_torque_is_pinocchio_rnea_plus_friction(panda, pin_panda):
    model, data = pin_panda
    rec = prrrp.simulate_chain(panda, fourier(7), 3.0, rate=100.0)
    assert rec.dof == 7
    assert len(rec) == 301
    assert rec.q.shape == rec.tau.shape == (301, 7)
    for k in range(len(rec)):
        ref = pin.rnea(model, data, rec.q[k], rec.qd[k], rec.qdd[k]) + friction_torque(rec.qd[k])
        np.testing.assert_allclose(rec.tau[k], ref, rtol=0, atol=1e-9 * (1 + np.abs(ref).max()))
    # Without noise settings the measured signals are the true ones.
    np.testing.assert_array_equal(rec.q_measured, rec.q)
    np.testing.assert_array_equal(rec.tau_measured, rec.tau)
    assert rec.qd_measured is None


def test_exact_model_tracking_goes_to_zero_with_the_step(panda):
    ref = fourier(7)
    errs = [
        np.abs(r.q - r.q_ref).max()
        for r in (prrrp.simulate_chain(panda, ref, 3.0, substeps=s) for s in (10, 20, 40))
    ]
    assert errs[0] < 1e-3
    # The controller's zero-order hold is the only error: first order in the step.
    for a, b in itertools.pairwise(errs):
        assert 0.4 < b / a < 0.6, errs
    # A controller with 30 % lighter links (and no friction model) tracks far worse.
    params = 0.7 * panda.parameters[: 10 * 7]
    wrong = prrrp.SerialChain.from_urdf(panda.to_urdf(np.r_[params, panda.parameters[70:]]))
    assert wrong.dof == 7
    rec = prrrp.simulate_chain(panda, ref, 3.0, controller=wrong)
    assert np.abs(rec.q - rec.q_ref).max() > 10 * errs[0]


def test_noise_statistics_and_seed(panda):
    q_std = 1e-4 * np.arange(1, 8)
    tau_std = 0.05 * np.arange(1, 8)
    kw = {"q_noise": q_std, "qd_noise": 1e-3, "tau_noise": tau_std, "seed": 3}
    rec = prrrp.simulate_chain(panda, fourier(7), 8.0, **kw)
    for meas, true, std in (
        (rec.q_measured, rec.q, q_std),
        (rec.qd_measured, rec.qd, np.full(7, 1e-3)),
        (rec.tau_measured, rec.tau, tau_std),
    ):
        e = meas - true
        # 801 samples: relative spread of the sample std 2.5 %, of the mean 0.035 sigma.
        np.testing.assert_allclose(e.std(axis=0, ddof=1) / std, 1.0, atol=0.1)
        assert np.all(np.abs(e.mean(axis=0)) < 0.15 * std)
    again = prrrp.simulate_chain(panda, fourier(7), 8.0, **kw)
    np.testing.assert_array_equal(again.tau_measured, rec.tau_measured)
    other = prrrp.simulate_chain(panda, fourier(7), 8.0, **{**kw, "seed": 4})
    assert not np.array_equal(other.q_measured, rec.q_measured)
    np.testing.assert_array_equal(other.q, rec.q)
    data, report = rec.measured_dataset(decimate_to_hz=50.0)
    assert isinstance(data, prrrp.Dataset)
    assert data.dof == 7
    assert report["measured_velocity"]


def test_reference_from_arrays_and_trajectory_derivatives(panda):
    ref = fourier(7)
    t = np.linspace(0.0, 4.0, 401)
    q, qd, qdd = ref.eval(t)
    assert q.shape == (401, 7)
    # Velocity and acceleration are the derivatives of position (central differences).
    h = 1e-5
    qp, qdp, _ = ref.eval(t + h)
    qm, qdm, _ = ref.eval(t - h)
    np.testing.assert_allclose((qp - qm) / (2 * h), qd, atol=1e-7)
    np.testing.assert_allclose((qdp - qdm) / (2 * h), qdd, atol=1e-6)
    # The same motion given as arrays (tuple, dict or Dataset) is followed the same way.
    a = prrrp.simulate_chain(panda, (t, q, qd, qdd), 3.0)
    b = prrrp.simulate_chain(panda, {"t": t, "q": q, "qd": qd, "qdd": qdd}, 3.0)
    np.testing.assert_array_equal(a.q, b.q)
    exact = prrrp.simulate_chain(panda, ref, 3.0)
    assert np.abs(a.q - exact.q).max() < 1e-6
    sampled = prrrp.ChainTrajectory.sampled(t, q, qd, qdd)
    assert sampled.end_time == pytest.approx(4.0)
    assert sampled.dof == 7
    sines = prrrp.ChainTrajectory.sinusoids(np.zeros(7), 0.3, 1.5, -np.pi / 2)
    _, qd0, _ = sines.eval(0.0)
    np.testing.assert_allclose(qd0, 0.0, atol=1e-12)
    assert sines.end_time is None


def test_validate_model_of_a_perfect_model(panda):
    train = prrrp.simulate_chain(panda, fourier(7, 0.6), 10.0).true_dataset()
    val = prrrp.simulate_chain(
        panda, prrrp.ChainTrajectory.sinusoids(np.zeros(7), 0.4, 1.3, -np.pi / 2), 5.0
    ).true_dataset()
    v = prrrp.validate_model(panda, val)
    assert v["rms"].shape == v["rsd"].shape == v["ai"].shape == (7,)
    assert v["predicted"].shape == (len(val), 7)
    assert np.all(v["rms"] < 1e-9)
    assert np.all(v["rsd"] < 1e-9)
    np.testing.assert_allclose(v["ai"], 1.0, atol=1e-12)
    # Base parameters at the true values: the same prediction.
    base = panda.base_parameters()
    vb = prrrp.validate_model(panda, val, beta=base.base_values(panda.parameters))
    assert np.all(vb["rms"] < 1e-8)
    # An identified model from noiseless data predicts other data almost exactly.
    model = prrrp.identify(panda, train, "ls")
    vi = prrrp.validate_model(model, val)
    assert np.all(vi["rms"] < 1e-6), vi
    assert np.all(vi["ai"] > 1 - 1e-9), vi
    # A wrong β predicts worse on every index.
    beta = 1.2 * base.base_values(panda.parameters)
    vw = prrrp.validate_model(panda, val, beta=beta)
    assert np.all(vw["rms"] > 1e-6)
    assert np.all(vw["ai"] < 1.0)


def test_bad_inputs_raise_typed_errors(panda):
    ref = fourier(7)
    with pytest.raises(prrrp.InvalidParameterError):
        prrrp.simulate_chain(panda, ref, 1.0, rate=0.0)
    with pytest.raises(prrrp.InvalidParameterError):
        prrrp.simulate_chain(panda, ref, float("nan"))
    with pytest.raises(prrrp.ShapeMismatchError):
        prrrp.simulate_chain(panda, fourier(6), 1.0)
    with pytest.raises(prrrp.ShapeMismatchError):
        prrrp.simulate_chain(panda, ref, 1.0, kp=np.ones(6))
    with pytest.raises(prrrp.InvalidParameterError):
        prrrp.simulate_chain(panda, ref, 1.0, tau_noise=-1.0)
    with pytest.raises(TypeError):
        prrrp.simulate_chain(panda, "not a trajectory", 1.0)
    t = np.linspace(0, 1, 11)
    with pytest.raises(prrrp.NonIncreasingTimeError):
        prrrp.ChainTrajectory.sampled(t[::-1], *np.zeros((3, 11, 7)))
    with pytest.raises(prrrp.ShapeMismatchError):
        prrrp.ChainTrajectory.fourier(1.0, np.zeros(7), np.zeros((7, 3)), np.zeros((7, 2)))
    # Past the end of a sampled reference.
    with pytest.raises(prrrp.InvalidParameterError):
        prrrp.simulate_chain(panda, (t, *np.zeros((3, 11, 7))), 2.0)
    # A blow-up names the joint and the time.
    with pytest.raises(prrrp.DivergedError) as info:
        prrrp.simulate_chain_open_loop(panda, np.zeros(7), np.zeros(7), np.full((50, 7), 1e200))
    assert 0 <= info.value.joint < 7
    assert info.value.time > 0
    data = prrrp.simulate_chain(panda, ref, 1.0).true_dataset()
    puma = prrrp.SerialChain.puma560()
    with pytest.raises(prrrp.ShapeMismatchError):
        prrrp.validate_model(puma, data)
    with pytest.raises(prrrp.ShapeMismatchError):
        prrrp.validate_model(panda, data, beta=np.ones(3))
    with pytest.raises(TypeError):
        prrrp.validate_model("model", data)
