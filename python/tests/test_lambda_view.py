"""The paper's λ view of a ``paper`` model: λ = T·β against the closed form's own λ
(``Robot.paper().base_parameters()``, Table 3 with Table 2 — the arm's grouping, not the
chain's), with torques from the closed form (symbolic Euler–Lagrange), never from the
chain that is identified."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from conftest import paper_states

import prrrp
from prrrp import cli


def _closed_form_data(n: int, seed: int, noise: float) -> prrrp.Dataset:
    q, qd, qdd = paper_states(n, seed)
    rng = np.random.default_rng(seed + 1000)
    tau = np.asarray(prrrp.Robot.paper().inverse_dynamics(q, qd, qdd))
    tau = tau + noise * rng.standard_normal(tau.shape)
    return prrrp.Dataset(np.arange(n) * 1e-2, q, qd, qdd, tau)


def test_lambda_of_a_paper_model_is_the_arms_lambda() -> None:
    truth = np.asarray(prrrp.Robot.paper().base_parameters())
    chain = prrrp.load_robot("paper")
    exact = prrrp.identify(chain, _closed_form_data(400, 3, 0.0), "ls")
    lam = prrrp.paper_lambda(exact)
    assert lam is not None
    assert len(lam["lambda"]) == len(lam["units"]) == 8
    np.testing.assert_allclose(lam["lambda"], truth, rtol=1e-8, atol=1e-10)
    # With noise, σ is the covariance's: the errors are of its size (|z| < 5), not 0.
    noisy = prrrp.identify(chain, _closed_form_data(2000, 4, 0.05), "ls")
    lam = prrrp.paper_lambda(noisy)
    assert lam is not None
    assert lam["sigma"] is not None
    z = (np.asarray(lam["lambda"]) - truth) / np.asarray(lam["sigma"])
    assert np.all(np.abs(z) < 5.0), z
    assert np.all(np.asarray(lam["sigma"]) > 0.0)


def test_other_robots_have_no_lambda() -> None:
    """The same arm read from a URDF under another name is not the built-in robot: its
    base parameters are not promised to be the paper's grouping, so no λ."""
    urdf = prrrp.load_robot("paper").to_urdf()
    other = prrrp.SerialChain.from_urdf(urdf.replace('name="paper-prrrp"', 'name="my-arm"', 1))
    assert other.name != "paper-prrrp"
    assert prrrp.paper_lambda(prrrp.identify(other, _closed_form_data(400, 5, 0.0), "ls")) is None


def test_identify_of_the_default_robot_writes_lambda(tmp_path: Path, monkeypatch, capsys) -> None:
    monkeypatch.chdir(tmp_path)
    ds = _closed_form_data(600, 6, 0.0)
    header = "t," + ",".join(
        [f"q{j}" for j in range(1, 6)]
        + [f"qd{j}" for j in range(1, 6)]
        + [f"qdd{j}" for j in range(1, 6)]
        + [f"tau{j}" for j in range(1, 6)]
    )
    table = np.column_stack([ds.t, ds.q, ds.qd, ds.qdd, ds.tau])
    np.savetxt("data.csv", table, delimiter=",", header=header, comments="")
    argv = ["identify", "data.csv", "--friction", "none", "--method", "ls", "--out", "fit"]
    assert cli.main(argv) == 0, capsys.readouterr()
    out = capsys.readouterr().out
    assert "λ1 = " in out
    lam = json.loads((tmp_path / "fit" / "lambda.json").read_text())
    truth = np.asarray(prrrp.Robot.paper().base_parameters())
    np.testing.assert_allclose(lam["lambda"], truth, rtol=1e-6, atol=1e-8)
