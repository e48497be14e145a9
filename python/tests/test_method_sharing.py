"""`--method all` (workflow.identify_methods) prepares once what every method shares: the
preprocessing, the Coulomb speed-scale search and the base analysis; the report scores
each model on one prepared grid, predicting each model once."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import paper_friction_log

import prrrp
from prrrp import prediction, workflow


@pytest.fixture(scope="module")
def log():
    return paper_friction_log(11)


def test_every_method_gets_one_preprocessing_and_one_base_analysis(log, monkeypatch):
    robot, raw = log
    seen = []
    real = workflow.identify

    def spy(chain, data, method, **kwargs):
        seen.append((chain, data, kwargs.get("base"), kwargs.get("preprocessing")))
        return real(chain, data, method, **kwargs)

    calls = {"preprocess": 0, "scale": 0}
    real_to_dataset = workflow.measurements_to_dataset

    def count(*args, **kwargs):
        calls["preprocess"] += 1
        return real_to_dataset(*args, **kwargs)

    monkeypatch.setattr(workflow, "identify", spy)
    monkeypatch.setattr(workflow, "measurements_to_dataset", count)
    runs = workflow.identify_methods(robot, raw, ["ls", "wls", "rls"])
    assert [r.error for r in runs] == [None] * 3
    assert calls["preprocess"] == 1
    chains, datas, bases, records = zip(*seen, strict=True)
    assert all(c is chains[0] for c in chains)  # one Coulomb speed scale
    assert all(d is datas[0] for d in datas)
    assert all(r is records[0] for r in records)
    assert all(b is bases[0] for b in bases)
    assert isinstance(bases[0], prrrp.BaseParameters)
    # The shared analysis is the robot's own: the models agree with one identified alone.
    alone = workflow.identify_measurements(robot, raw, "wls")
    assert list(runs[1].result.model.base_names) == list(alone.model.base_names)
    assert np.allclose(runs[1].result.model.beta, alone.model.beta, rtol=1e-10, atol=1e-12)


def test_scoring_grid_reuses_the_identification_data(log):
    robot, raw = log
    run = workflow.identify_measurements(robot, raw, "wls", coulomb_scale=0.02)
    settings = run.model.preprocessing["settings"]
    fresh = prediction.prepare(raw, settings)
    reused = prediction.prepare(raw, settings, identified=(run.data, run.log_report))
    assert reused.data is run.data
    a, b = fresh.errors(fresh.predict(run.model)), reused.errors(reused.predict(run.model))
    for key in ("rms", "tau_rms", "percent", "filtered_rms"):
        assert np.array_equal(a[key], b[key]), key
    assert np.array_equal(fresh.edge, reused.edge)


def test_a_cached_prediction_is_the_models_and_the_callers_own(log):
    robot, raw = log
    ls = workflow.identify_measurements(robot, raw, "ls", coulomb_scale=0.02).model
    wls = workflow.identify_measurements(robot, raw, "wls", coulomb_scale=0.02).model
    grid = prediction.prepare(raw, ls.preprocessing["settings"])
    first = grid.predict(ls)
    first[:] = np.nan  # the caller may write into what it got
    again = grid.predict(ls)
    assert np.isfinite(again).all()
    p = grid.processed
    direct = np.asarray(ls.predict(p.q, p.qd, p.qdd))
    assert np.allclose(again, prediction._at_rows(np.asarray(p.t), direct, grid.t))
    # Another model on the same grid: its own prediction, not the cached one.
    assert not np.array_equal(grid.predict(wls), again)


def test_methods_share_one_fit_cache_and_give_their_own_models(log, monkeypatch):
    """Every method of one call gets the same FitCache, which ends holding two stacks (one
    unweighted, one weighted); each model equals the one `identify_measurements` gives
    that method alone (its own fresh cache), bit for bit."""
    robot, raw = log
    caches = []
    real = workflow.identify

    def spy(chain, data, method, **kwargs):
        caches.append(kwargs.get("cache"))
        return real(chain, data, method, **kwargs)

    monkeypatch.setattr(workflow, "identify", spy)
    runs = workflow.identify_methods(robot, raw, coulomb_scale=0.02)
    assert [r.error for r in runs] == [None] * len(workflow.METHODS)
    assert isinstance(caches[0], prrrp.FitCache)
    assert all(c is caches[0] for c in caches)
    assert caches[0].stacks == 2
    monkeypatch.setattr(workflow, "identify", real)
    for r in runs:
        alone = workflow.identify_measurements(robot, raw, r.method, coulomb_scale=0.02).model
        m = r.result.model
        np.testing.assert_array_equal(m.beta, alone.beta, err_msg=r.method)
        np.testing.assert_array_equal(m.residual_rms, alone.residual_rms, err_msg=r.method)
        if alone.sigma is None:
            assert m.sigma is None, r.method
        else:
            np.testing.assert_array_equal(m.sigma, alone.sigma, err_msg=r.method)


def test_a_fit_cache_of_other_data_is_refused(log):
    """A cache filled from one data set refuses another differing in one torque by
    1 µN·m, and still serves its own (the model of a fresh cache, bit for bit)."""
    robot, _ = log
    data = workflow.identify_measurements(*log, "ls", coulomb_scale=0.02).data
    cache = prrrp.FitCache()
    first = prrrp.identify(robot, data, "ls", cache=cache)
    tau = np.array(data.tau)
    tau[7, 2] += 1e-6
    other = prrrp.Dataset(data.t, data.q, data.qd, data.qdd, tau)
    for method in ("ls", "wls"):
        with pytest.raises(prrrp.InvalidParameterError, match="cache"):
            prrrp.identify(robot, other, method, cache=cache)
    again = prrrp.identify(robot, data, "ls", cache=cache)
    np.testing.assert_array_equal(again.beta, first.beta)
    np.testing.assert_array_equal(again.beta, prrrp.identify(robot, data, "ls").beta)
