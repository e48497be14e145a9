"""prrrp.identify on a 7-joint arm (the Panda URDF) with viscous, smooth-Coulomb and offset
friction: noisy torques from the chain's own inverse dynamics on an exciting trajectory;
the estimate's error is covered by its reported σ, and torque prediction on a different
trajectory reaches the noise floor."""

import importlib.metadata

import numpy as np
import pytest
from conftest import fourier_motion

import prrrp

ROBOTS = importlib.metadata.distribution("example-robot-data").locate_file(
    "cmeel.prefix/share/example-robot-data/robots"
)
NOISE = 0.05  # N·m, torque sensor noise (standard deviation)


@pytest.fixture(scope="module")
def panda():
    chain = prrrp.SerialChain.from_urdf(
        str(ROBOTS / "panda_description/urdf/panda.urdf"), tip="panda_link8"
    )
    # fv (N·m·s/rad), fc (N·m), fo (N·m) per joint; Coulomb turning over within 0.02 rad/s.
    params = np.tile([0.6, 0.4, 0.05], (7, 1))
    return chain.with_friction("viscous+coulomb+offset", params, coulomb_smoothing=0.02)


def fourier(seed, seconds=20.0, rate=100.0):
    t = np.arange(0.0, seconds, 1.0 / rate)
    return (t, *fourier_motion(seed, t))


def dataset(chain, seed, noise):
    t, q, qd, qdd = fourier(seed)
    tau = chain.inverse_dynamics(q, qd, qdd)
    tau = tau + np.random.default_rng(100 + seed).normal(0.0, noise, tau.shape)
    return prrrp.Dataset(t, q, qd, qdd, tau), tau


@pytest.mark.parametrize("method", ["ls", "wls"])
def test_identify_recovers_the_base_parameters(panda, method):
    data, _ = dataset(panda, seed=1, noise=NOISE)
    model = prrrp.identify(panda, data, method)
    truth = panda.base_parameters().base_values(panda.parameters)
    assert model.method == method
    assert len(model.beta) == 64  # 43 rigid-body + 3·7 friction base parameters
    err = np.abs(model.beta - truth)
    assert (err <= 4.0 * model.sigma).all(), (err / model.sigma).max()
    # The residual on the identification data is the sensor noise.
    np.testing.assert_allclose(model.residual_rms, NOISE, rtol=0.1)
    # Prediction on a different trajectory: the error is the noise floor.
    val, _ = dataset(panda, seed=2, noise=0.0)
    pred = model.predict(val.q, val.qd, val.qdd)
    rms = np.sqrt(((pred - val.tau) ** 2).mean(axis=0))
    assert (rms < 0.5 * NOISE).all(), rms


def test_identify_bad_input(panda):
    data, _ = dataset(panda, seed=3, noise=NOISE)
    with pytest.raises(prrrp.InvalidParameterError, match="unknown"):
        prrrp.identify(panda, data, "magic")
    with pytest.raises(prrrp.InvalidParameterError, match="SerialChain"):
        prrrp.identify("panda", data)
    # The paper's arm is accepted, with its own joint count.
    with pytest.raises(prrrp.ShapeMismatchError):
        prrrp.identify(prrrp.Robot.paper(), data)
    with pytest.raises(prrrp.ShapeMismatchError):
        prrrp.identify(prrrp.SerialChain.puma560(), data)
    few = data[0:8]
    with pytest.raises(prrrp.PrrrpError):
        prrrp.identify(panda, few)
    still = prrrp.Dataset(data.t, np.zeros_like(data.q), data.qd * 0, data.qdd * 0, data.tau)
    with pytest.raises(prrrp.RankDeficientError):
        prrrp.identify(panda, still)
