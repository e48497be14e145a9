"""Excitation optimisation and reference trajectories through the Python API."""

from __future__ import annotations

import numpy as np
import pytest

import prrrp


@pytest.fixture(scope="module")
def excitation() -> prrrp.Excitation:
    # A small budget keeps the test fast; the search still has to improve on its start.
    return prrrp.optimise_excitation(seed=1, duration=4.0, max_evaluations=300)


def test_excitation_result(excitation):
    assert excitation.cond_final < excitation.cond_initial
    assert 0 < excitation.evaluations <= 300 + 50  # a started simplex run may finish
    assert excitation.limits_satisfied is True
    assert excitation.samples == 201
    assert excitation.duration == 4.0
    assert excitation.dt == 0.02
    usage = excitation.limit_usage
    assert set(usage) == {"q", "qd", "qdd"}
    for v in usage.values():
        assert v.shape == (5,)
        assert np.all(v <= 1.0 + 1e-9)
    assert "Excitation" in repr(excitation)


def test_eval_scalar_and_batch_agree(excitation):
    t = np.linspace(0.0, 4.0, 101)
    q, qd, qdd = excitation.eval(t)
    assert q.shape == qd.shape == qdd.shape == (101, 5)
    assert q.dtype == np.float64
    q1, qd1, qdd1 = excitation.sample(t[37])
    assert q1.shape == (5,)
    np.testing.assert_array_equal(q1, q[37])
    np.testing.assert_array_equal(qd1, qd[37])
    np.testing.assert_array_equal(qdd1, qdd[37])


def test_eval_derivatives_are_consistent(excitation):
    # qd and qdd must be the time derivatives of q (central differences, O(h²)).
    h = 1e-5
    t = np.linspace(0.3, 3.7, 23)
    qp, qdp, _ = excitation.eval(t + h)
    qm, qdm, _ = excitation.eval(t - h)
    _, qd, qdd = excitation.eval(t)
    np.testing.assert_allclose((qp - qm) / (2 * h), qd, atol=1e-6)
    np.testing.assert_allclose((qdp - qdm) / (2 * h), qdd, atol=1e-5)


def test_excitation_respects_default_limits(excitation):
    lim = prrrp.joint_limits()
    q, qd, qdd = excitation.eval(np.linspace(0.0, 4.0, 2001))
    assert np.all(q >= lim["q_min"] - 1e-9)
    assert np.all(q <= lim["q_max"] + 1e-9)
    assert np.all(np.abs(qd) <= lim["qd_max"] + 1e-9)
    assert np.all(np.abs(qdd) <= lim["qdd_max"] + 1e-9)


def test_excitation_cond_matches_observation_matrix(excitation):
    # cond_final is cond(W) over the sampled trajectory: recompute it independently.
    t = np.arange(excitation.samples) * excitation.dt
    w = prrrp.observation_matrix(*excitation.eval(t))
    s = np.linalg.svd(w, compute_uv=False)
    assert excitation.cond_final == pytest.approx(s[0] / s[-1], rel=1e-6)


def test_joint_limits_defaults():
    lim = prrrp.joint_limits()
    assert set(lim) == {"q_min", "q_max", "qd_max", "qdd_max"}
    np.testing.assert_array_equal(lim["q_max"], [0.3, 2.5, 2.5, 2.5, 0.1])


def test_progress_callback_called_from_rust():
    calls = []
    prrrp.optimise_excitation(
        duration=2.0, max_evaluations=60, progress=lambda *a: calls.append(a), progress_every=20
    )
    assert len(calls) >= 2
    done, total, best = calls[-1]
    assert total == 60
    assert isinstance(done, int)
    assert np.isfinite(best)
    assert [c[0] for c in calls] == sorted(c[0] for c in calls)


def test_progress_exception_propagates():
    class Stop(Exception):
        pass

    def boom(*_):
        raise Stop("from the callback")

    with pytest.raises(Stop, match="from the callback"):
        prrrp.optimise_excitation(
            duration=2.0, max_evaluations=60, progress=boom, progress_every=10
        )


def test_excitation_errors():
    with pytest.raises(prrrp.InvalidParameterError):
        prrrp.optimise_excitation(duration=-1.0, max_evaluations=10)
    with pytest.raises(prrrp.ShapeMismatchError, match="q_max"):
        prrrp.optimise_excitation(limits={"q_max": [1.0, 2.0]}, max_evaluations=10)
    with pytest.raises(prrrp.InvalidParameterError):
        prrrp.optimise_excitation(limits={"qd_max": -np.ones(5)}, max_evaluations=10)


def test_eval_errors(excitation):
    with pytest.raises(prrrp.ShapeMismatchError, match="t"):
        excitation.eval(np.zeros((2, 2)))
    with pytest.raises(prrrp.NonFiniteError) as e:
        excitation.eval([0.0, np.nan])
    assert e.value.row == 1


def test_sinusoid_reference_is_analytic():
    o = np.array([0.1, 0, 0, 0, 0.05])
    a = np.array([0.05, 1.0, 0.8, 0.6, 0.02])
    w = np.arange(1.0, 6.0)
    p = np.array([0, 0.1, 0.2, 0.3, 0.4])
    ref = prrrp.SinusoidReference(offset=o, amplitude=a, omega=w, phase=p)
    t = np.linspace(0, 2, 7)
    q, qd, qdd = ref.eval(t)
    arg = np.outer(t, w) + p
    np.testing.assert_allclose(q, o + a * np.sin(arg), atol=1e-14)
    np.testing.assert_allclose(qd, a * w * np.cos(arg), atol=1e-13)
    np.testing.assert_allclose(qdd, -a * w**2 * np.sin(arg), atol=1e-12)
    with pytest.raises(prrrp.ShapeMismatchError, match="omega"):
        prrrp.SinusoidReference(offset=np.zeros(5), amplitude=np.zeros(5), omega=np.zeros(4))
