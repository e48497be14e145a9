"""Hardening of the estimators: bounded and interruptible training, integer arguments,
least-squares sample count and zero estimates, concurrent use from two threads, and
non-finite estimates (also through the command line)."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import numpy as np
import pytest
from ctrl_c import assert_ctrl_c_stops

import prrrp
from prrrp import cli, csvio

Z = np.zeros((20, 5))


def excitation_data(n: int = 400, seed: int = 3) -> tuple[np.ndarray, ...]:
    rng = np.random.default_rng(seed)
    t = 0.02 * np.arange(n)
    w = rng.uniform(0.5, 2.0, (1, 5))
    q = 0.3 * np.sin(w * t[:, None] + rng.uniform(0, 3, (1, 5)))
    qd = 0.3 * w * np.cos(w * t[:, None] + 0.0)
    qdd = -(w**2) * q
    robot = prrrp.Robot.paper()
    tau = np.asarray(robot.inverse_dynamics(q, qd, qdd))
    return t, q, qd, qdd, tau


@pytest.mark.parametrize("cls", [prrrp.Adaline, prrrp.Hopfield])
@pytest.mark.parametrize("epochs", [10**12, 2**63])
def test_absurd_epochs_are_refused_before_allocating(cls, epochs):
    t = time.monotonic()
    with pytest.raises(prrrp.InvalidInputError, match="MAX_EPOCHS"):
        cls().train(Z, Z, Z, Z, epochs)
    assert time.monotonic() - t < 1.0


@pytest.mark.parametrize(
    "call",
    [
        lambda: prrrp.Adaline().train(Z, Z, Z, Z, -1),
        lambda: prrrp.Hopfield().train(Z, Z, Z, Z, -5),
        lambda: prrrp.Adaline().train(Z, Z, Z, Z, 2**70),
        lambda: prrrp.Rls().run(Z, Z, Z, Z, history_every=-2),
    ],
)
def test_negative_epochs_and_samples_are_value_errors(call):
    with pytest.raises(prrrp.InvalidParameterError, match="out of range") as e:
        call()
    assert isinstance(e.value, ValueError)


def test_ctrl_c_stops_a_long_training():
    assert_ctrl_c_stops(
        "prrrp.Adaline().train(q, qd, qdd, tau, 10**7)",
        setup="""
        t = 0.02 * np.arange(200)
        q = 0.3 * np.sin(np.outer(t, [1.0, 1.3, 0.7, 1.9, 0.4]))
        qd = np.cos(np.outer(t, [1.0, 1.3, 0.7, 1.9, 0.4]))
        qdd = -q
        tau = prrrp.Robot.paper().inverse_dynamics(q, qd, qdd)
        """,
    )


@pytest.mark.parametrize("n", [2, 5, 7])
def test_least_squares_needs_eight_samples(n):
    _, q, qd, qdd, tau = excitation_data()
    with pytest.raises(prrrp.TooFewSamplesError) as e:
        prrrp.least_squares(q[:n], qd[:n], qdd[:n], tau[:n])
    assert (e.value.needed, e.value.got) == (8, n)


def test_zero_estimate_has_a_defined_relative_std():
    _, q, qd, qdd, _ = excitation_data(200)
    res = prrrp.least_squares(q, qd, qdd, np.zeros((200, 5)))
    assert np.all(np.asarray(res.lam) == 0.0)
    rsd = np.asarray(res.rsd_percent)
    assert not np.any(np.isnan(rsd))
    assert np.all(np.isposinf(rsd))


def test_two_threads_on_one_estimator_get_a_typed_error():
    _, q, qd, qdd, tau = excitation_data(400)
    est = prrrp.Adaline()
    errors: list[BaseException] = []
    started = threading.Event()

    def long_training() -> None:
        started.set()
        try:
            est.train(q, qd, qdd, tau, 2000)
        except BaseException as e:
            errors.append(e)

    worker = threading.Thread(target=long_training)
    worker.start()
    started.wait()
    seen = None
    deadline = time.monotonic() + 5.0
    while worker.is_alive() and time.monotonic() < deadline:
        try:
            est.step(q[0], qd[0], qdd[0], tau[0])
        except prrrp.PrrrpError as e:
            seen = e
            break
        time.sleep(0.001)
    worker.join()
    assert not errors, errors
    assert seen is not None
    assert "in use by another thread" in str(seen)
    # Once the other call has finished, the estimator is usable again.
    est.step(q[0], qd[0], qdd[0], tau[0])


def test_overflowing_data_is_a_typed_error():
    _, q, qd, qdd, tau = excitation_data(200)
    tau = tau.copy()
    tau[50:60, 0] = 1e308
    with pytest.raises(prrrp.NonFiniteError):
        prrrp.least_squares(q, qd, qdd, tau)
    # Adaline's normalised rule stays finite (a projection), but its error report shows it.
    errors = prrrp.Adaline().train(q, qd, qdd, tau, 3)
    assert not np.all(np.isfinite(errors))


@pytest.mark.parametrize("method", ["ls", "adaline", "all"])
def test_identify_with_overflowing_torques_exits_2(tmp_path: Path, capsys, method):
    t, q, qd, qdd, tau = excitation_data(300)
    tau = tau.copy()
    tau[100:110, 0] = 1e308
    path = tmp_path / "data.csv"
    path.write_text(csvio.format_measurements(t, q, tau, qd, qdd))
    code = cli.main(["identify", str(path), "--method", method])
    out, err = capsys.readouterr()
    assert code == 2, (out, err)
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("prrrp: error: ")
    assert "inf" not in out
    assert "nan" not in out
