"""Hardening: Ctrl-C stops long computations with KeyboardInterrupt (run in a child process,
which gets a real SIGINT); absurd sizes are refused before anything is allocated; integer
arguments out of range are ValueErrors; simulations do not run past their reference."""

import time

import numpy as np
import pytest
from ctrl_c import assert_ctrl_c_stops

import prrrp

LONG_CALLS = {
    "sensitivity": "prrrp.sensitivity(points=400)",
    "simulation": "prrrp.simulate_closed_loop(s, 5000.0, substeps=400)",
    "excitation": "prrrp.optimise_excitation(max_evaluations=10**6, restarts=50)",
}


@pytest.mark.parametrize("call", sorted(LONG_CALLS))
def test_ctrl_c_stops_a_long_call(call):
    assert_ctrl_c_stops(
        LONG_CALLS[call],
        setup="s = prrrp.SinusoidReference("
        "offset=np.zeros(5), amplitude=np.full(5, 0.1), omega=np.ones(5))",
    )


S = prrrp.SinusoidReference(offset=np.zeros(5), amplitude=np.full(5, 0.1), omega=np.ones(5))


@pytest.mark.parametrize(
    "call",
    [
        lambda: prrrp.simulate_closed_loop(S, 1e9),
        lambda: prrrp.simulate_closed_loop(S, 1.8e17),
        lambda: prrrp.simulate_closed_loop(S, 0.1, substeps=2**63),
        lambda: prrrp.simulate_open_loop(
            np.zeros(5), np.zeros(5), np.zeros((10, 5)), substeps=2**63
        ),
        lambda: prrrp.validate({"ls": prrrp.Robot.paper().base_parameters()}, duration=1e9),
        lambda: prrrp.sensitivity(duration=1e9, points=2),
        lambda: prrrp.sensitivity(points=2**63),
        lambda: prrrp.SerialChain.paper().base_parameters(samples=10**12),
        lambda: prrrp.SerialChain.paper().base_parameters(samples=2**63),
        lambda: prrrp.optimise_excitation(duration=1e9, max_evaluations=5, restarts=0),
    ],
)
def test_absurd_sizes_are_refused_before_allocating(call):
    t = time.monotonic()
    with pytest.raises(prrrp.InvalidInputError, match="MAX_"):
        call()
    assert time.monotonic() - t < 1.0


def test_simulation_does_not_run_past_the_excitation():
    exc = prrrp.optimise_excitation(max_evaluations=400, restarts=0)
    end = exc.duration
    prrrp.simulate_closed_loop(exc, end)  # the whole excitation is fine
    with pytest.raises(prrrp.InvalidParameterError, match="reference ends at"):
        prrrp.simulate_closed_loop(exc, end + 2.0)


def test_a_longer_recording_plays_the_excitation_forward_and_backward():
    """`Excitation.reflected()` (what `prrrp simulate --duration` longer than the excitation
    follows): the same motion mirrored in time, so the tracked arm stays within the limits
    the excitation was designed for and is tracked as well as on the first pass."""
    exc = prrrp.optimise_excitation(max_evaluations=400, restarts=0)
    end = exc.duration
    ref = exc.reflected()
    assert ref.is_reflected
    assert not exc.is_reflected
    assert ref.duration == end
    t = np.linspace(0.0, end, 101)
    q, qd, qdd = exc.eval(t)
    q2, qd2, qdd2 = ref.eval(2 * end - t)
    assert np.allclose(q2, q, atol=1e-12)
    assert np.allclose(qd2, -qd, atol=1e-12)
    assert np.allclose(qdd2, qdd, atol=1e-12)
    zero = np.zeros(5)
    rec = prrrp.simulate_closed_loop(ref, 3 * end, q_noise=zero, tau_noise=zero)
    qs = np.asarray(rec["q"])
    assert len(qs) == round(3 * end / 0.02) + 1
    lim = prrrp.joint_limits()
    assert np.all(qs <= np.asarray(lim["q_max"]) + 1e-3)
    assert np.all(qs >= np.asarray(lim["q_min"]) - 1e-3)
    # The closed loop tracks the reflected reference as well as the first pass.
    err = np.abs(qs - np.asarray(rec["q_ref"])).max(axis=0)
    first = np.abs(qs[: len(t)] - np.asarray(rec["q_ref"])[: len(t)]).max(axis=0)
    assert np.all(err <= 10 * first + 1e-9)


@pytest.mark.parametrize(
    "call",
    [
        lambda: prrrp.simulate_closed_loop(S, 1.0, seed=-1),
        lambda: prrrp.simulate_closed_loop(S, 1.0, substeps=-3),
        lambda: prrrp.simulate_closed_loop(S, 1.0, seed=2**70),
        lambda: prrrp.SerialChain.paper().base_parameters(samples=-1),
        lambda: prrrp.optimise_excitation(seed=-5),
        lambda: prrrp.sensitivity(points=-2),
        lambda: prrrp.run_study(seed=-1),
    ],
)
def test_out_of_range_integers_are_value_errors(call):
    with pytest.raises(prrrp.InvalidParameterError, match="out of range") as e:
        call()
    assert isinstance(e.value, ValueError)


@pytest.mark.parametrize(
    "q", [np.zeros(5) + 1j, [1j, 0, 0, 0, 0], np.zeros((3, 5), dtype=np.complex64)]
)
def test_complex_input_is_refused(q):
    robot = prrrp.Robot.paper()
    zeros = np.zeros(np.shape(q), dtype=float)
    with pytest.raises(prrrp.InvalidInputError, match="complex"):
        robot.inverse_dynamics(q, zeros, zeros)


@pytest.mark.parametrize("key", [slice(0, 10, 0), slice(2.5, 30), slice(0, 10, 2)])
def test_bad_dataset_slices_are_typed(key):
    t = 0.02 * np.arange(50)
    z = np.zeros((50, 5))
    data = prrrp.Dataset(t, z, z, z, z)
    with pytest.raises(prrrp.InvalidParameterError):
        data[key]


@pytest.mark.parametrize("trim", [2**63, 10**12])
def test_absurd_trim_is_a_typed_error(trim):
    t = 0.02 * np.arange(200)
    q = np.zeros((200, 5))
    with pytest.raises(prrrp.TooFewSamplesError):
        prrrp.preprocess(t, q, q, trim=trim)
