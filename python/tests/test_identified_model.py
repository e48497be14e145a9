"""prrrp.IdentifiedModel predicts like the robot it describes, also after save/load and
pickling, and refuses inconsistent parts."""

import pickle

import numpy as np
import pytest

import prrrp


@pytest.fixture(scope="module")
def puma():
    return prrrp.SerialChain.puma560()


def exact(chain):
    base = chain.base_parameters()
    return prrrp.identified_model_from_parts(
        chain,
        base.base_values(chain.parameters),
        sigma=np.full(base.count, 1e-3),
        cond=4.2,
        method="ls",
        settings={"weighted": False},
        preprocessing={"rate_hz": 100.0},
    )


def test_predicts_inverse_dynamics_after_save_and_pickle(puma, tmp_path):
    model = exact(puma)
    rng = np.random.default_rng(1)
    q, qd, qdd = rng.normal(size=(3, 40, 6))
    want = puma.inverse_dynamics(q, qd, qdd)
    np.testing.assert_allclose(model.predict(q, qd, qdd), want, rtol=1e-9, atol=1e-9)
    path = tmp_path / "model.json"
    model.save(path)
    loaded = prrrp.IdentifiedModel.load(path)
    np.testing.assert_array_equal(loaded.predict(q, qd, qdd), model.predict(q, qd, qdd))
    again = pickle.loads(pickle.dumps(model))
    np.testing.assert_array_equal(again.beta, model.beta)
    assert loaded.settings == {"weighted": False}
    assert loaded.preprocessing == {"rate_hz": 100.0}
    assert loaded.method == "ls"
    assert loaded.cond == 4.2
    assert loaded.robot.joint_names == puma.joint_names
    assert len(loaded.base_names) == len(loaded.combinations) == puma.base_parameters().count
    single = model.predict(q[0], qd[0], qdd[0])
    assert single.shape == (6,)


def test_bad_parts_and_files_are_typed_errors(puma, tmp_path):
    b = puma.base_parameters().count
    with pytest.raises(prrrp.ShapeMismatchError):
        prrrp.identified_model_from_parts(puma, np.ones(b - 1))
    with pytest.raises(prrrp.NonFiniteError):
        prrrp.identified_model_from_parts(puma, np.full(b, np.nan))
    with pytest.raises(prrrp.InvalidParameterError):
        prrrp.identified_model_from_parts(puma, np.ones(b), cond=np.inf)
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    with pytest.raises(prrrp.InvalidParameterError, match="line 1"):
        prrrp.IdentifiedModel.load(bad)
    with pytest.raises(prrrp.InvalidParameterError):
        prrrp.IdentifiedModel.load(tmp_path / "missing.json")
    model = exact(puma)
    with pytest.raises(prrrp.ShapeMismatchError):
        model.predict(np.zeros(5), np.zeros(5), np.zeros(5))


def test_saving_to_a_folder_or_a_missing_folder_is_a_typed_error(puma, tmp_path):
    """Both were OSErrors (IsADirectoryError, FileNotFoundError from the temporary file's
    creation); they are prrrp errors that name the path, and nothing is written."""
    model = exact(puma)
    with pytest.raises(prrrp.PrrrpError, match="give a file name"):
        model.save(tmp_path)
    missing = tmp_path / "no" / "such" / "model.json"
    with pytest.raises(prrrp.PrrrpError, match=r"folder .*no/such does not exist"):
        model.save(missing)
    assert not (tmp_path / "no").exists()
    assert list(tmp_path.iterdir()) == []
