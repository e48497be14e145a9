"""The whole study through `prrrp.run_study`: schema of the parsed JSON, round trip."""

from __future__ import annotations

import json

import numpy as np
import pytest

import prrrp

METHODS = ["least_squares", "adaline", "hopfield", "ekf"]


@pytest.fixture(scope="module")
def study():
    calls = []
    result = prrrp.run_study(seed=0, progress=lambda *a: calls.append(a))
    return result, calls


def test_study_schema(study):
    r, _ = study
    assert r["schema_version"] == 1
    assert r["seed"] == 0
    np.testing.assert_allclose(r["truth"], prrrp.Robot.paper().base_parameters())
    assert [e["method"] for e in r["estimates"]] == METHODS
    for e in r["estimates"]:
        assert len(e["lambda"]) == 8
    n = len(r["estimation_data"]["t"])
    assert np.asarray(r["estimation_data"]["q"]).shape == (n, 5)
    assert [m["method"] for m in r["validation"]["methods"]] == METHODS
    assert r["excitation"]["cond_final"] <= r["excitation"]["cond_initial"]


def test_study_least_squares_close_to_truth(study):
    r, _ = study
    ls = r["estimates"][0]
    np.testing.assert_allclose(ls["lambda"], r["truth"], rtol=0.05)
    # Relative errors agree with an independent computation.
    np.testing.assert_allclose(
        ls["relative_error_percent"],
        100 * np.abs(np.subtract(ls["lambda"], r["truth"])) / np.abs(r["truth"]),
        rtol=1e-9,
    )


def test_study_round_trip_and_progress(study):
    r, calls = study
    assert json.loads(json.dumps(r)) == r
    assert calls
    stage, done, total = calls[-1]
    assert isinstance(stage, str)
    assert 0 <= done <= total


def test_study_progress_exception_propagates():
    class Stop(Exception):
        pass

    def boom(*_):
        raise Stop

    with pytest.raises(Stop):
        prrrp.run_study(seed=1, progress=boom)
