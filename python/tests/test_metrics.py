"""Error indices (eqs. 45-47) against direct numpy formulas."""

from __future__ import annotations

import numpy as np
import pytest

import prrrp


def test_indices_match_formulas(rng):
    o = rng.normal(size=(50, 5)) + 3.0
    p = o + 0.1 * rng.normal(size=(50, 5))
    r = np.sqrt(np.mean((o - p) ** 2, axis=0))
    np.testing.assert_allclose(prrrp.rms(o, p), r, rtol=1e-12)
    assert prrrp.rms(o[:, 2], p[:, 2]) == pytest.approx(r[2], rel=1e-12)
    om = o.mean(axis=0)
    ai = 1 - np.sum((o - p) ** 2, axis=0) / np.sum((np.abs(p - om) + np.abs(o - om)) ** 2, axis=0)
    np.testing.assert_allclose(prrrp.agreement_index(o, p), ai, rtol=1e-12)
    e = prrrp.error_indices(o, p)
    assert set(e) == {"rms", "rsd", "ai"}
    np.testing.assert_allclose(e["rms"], r, rtol=1e-12)
    rsd = np.sqrt(np.sum((o - p) ** 2, axis=0) / np.sum(o**2, axis=0))
    np.testing.assert_allclose(prrrp.rsd(o, p), rsd, rtol=1e-12)
    np.testing.assert_allclose(e["rsd"], rsd, rtol=1e-12)
    assert e["rsd"].shape == (5,)
    e1 = prrrp.error_indices(o[:, 0], p[:, 0])
    assert isinstance(e1["ai"], float)


def test_perfect_prediction():
    o = np.linspace(0, 1, 20)
    assert prrrp.rms(o, o) == 0.0
    assert prrrp.agreement_index(o, o) == 1.0


def test_relative_errors_percent():
    np.testing.assert_allclose(
        prrrp.relative_errors_percent([1.1, 1.8, 0.5], [1.0, 2.0, 0.0]), [10.0, 10.0, 50.0]
    )


def test_metric_errors():
    with pytest.raises(prrrp.ShapeMismatchError, match="predicted"):
        prrrp.rms(np.zeros(4), np.zeros(5))
    with pytest.raises(prrrp.ShapeMismatchError, match="observed"):
        prrrp.rms(np.zeros((2, 2, 2)), np.zeros((2, 2, 2)))
    with pytest.raises(prrrp.NonFiniteError):
        prrrp.rms([1.0, np.nan], [1.0, 2.0])
