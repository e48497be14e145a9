"""``--robot paper`` / ``prrrp.load_robot("paper")``: the paper's arm as a robot like any
other, through the general pipeline (excite → simulate → identify → predict), checked
against its closed form ``Robot.paper()`` — an independent implementation of the same arm
(symbolic Euler–Lagrange, not the chain's recursive Newton–Euler)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import paper_states

import prrrp
from prrrp import cli, csvio


def test_the_built_in_paper_robot_is_the_closed_form_arm() -> None:
    chain = prrrp.load_robot("paper")
    q, qd, qdd = paper_states(200, 1)
    closed = prrrp.Robot.paper().inverse_dynamics(q, qd, qdd)
    assert np.allclose(chain.inverse_dynamics(q, qd, qdd), closed, rtol=1e-10, atol=1e-10)
    # It carries the limits the paper's excitation is designed within.
    lim, ref = chain.limits, prrrp.joint_limits()
    for mine, theirs in (
        ("lower", "q_min"),
        ("upper", "q_max"),
        ("velocity", "qd_max"),
        ("acceleration", "qdd_max"),
    ):
        assert np.array_equal(lim[mine], np.asarray(ref[theirs])), mine
    with pytest.raises(ValueError, match="built-in robot 'paper'"):
        prrrp.load_robot("paper", tip="link5")
    # A misspelt name read as a file without an extension ("use .urdf or .toml").
    for name in ("PAPER", "puma560"):
        with pytest.raises(prrrp.InvalidInputError, match=r"neither a built-in robot \('paper'\)"):
            prrrp.load_robot(name)


def test_the_commands_take_the_paper_robot_by_name(tmp_path: Path, monkeypatch, capsys) -> None:
    """excite, simulate, identify and predict with ``--robot paper``. The arm has no
    friction, so it is identified without friction terms (``--friction none``); a second,
    noise-free run is then predicted within 2.5 % of each joint's RMS torque (measured:
    0.01, 0.8, 1.2, 1.5, 0.03 %; the paper's own closed-form path on the same data: 0.004,
    0.3, 0.5, 1.0, 0.02 %)."""
    monkeypatch.chdir(tmp_path)
    robot = ["--robot", "paper"]
    for seed, name, noise in ((0, "data", "1"), (1, "val", "0")):
        traj = f"traj{seed}.csv"
        argv = ["excite", *robot, "--duration", "20", "--seed", str(seed), "--out", traj]
        assert cli.main(argv) == 0, capsys.readouterr()
        argv = ["simulate", *robot, "--trajectory", traj, "--seed", str(seed)]
        argv += ["--noise", noise, "--out", f"{name}.csv"]
        assert cli.main(argv) == 0, capsys.readouterr()
    argv = ["identify", "data.csv", *robot, "--friction", "none", "--out", "fit"]
    assert cli.main(argv) == 0, capsys.readouterr()
    model = prrrp.IdentifiedModel.load(tmp_path / "fit" / "model.json")
    assert model.robot.dof == 5
    capsys.readouterr()
    assert cli.main(["predict", "fit/model.json", "val.csv", "--out", "tau.csv"]) == 0
    assert "no better than predicting zero torque" not in capsys.readouterr().out
    table = np.loadtxt(tmp_path / "tau.csv", delimiter=",", skiprows=1)
    raw = csvio.read_table(tmp_path / "val.csv", 5, real_log=True)
    # The same log with its torques' signs flipped (a sensor wired the other way): the
    # errors read about 200 % and nothing else said the log was at fault.
    header = (tmp_path / "val.csv").read_text().splitlines()[0]
    flipped = np.loadtxt(tmp_path / "val.csv", delimiter=",", skiprows=1)
    flipped[:, 6:] *= -1
    np.savetxt("flipped.csv", flipped, delimiter=",", header=header, comments="")
    assert cli.main(["predict", "fit/model.json", "flipped.csv", "--out", "f.csv"]) == 0
    assert "no better than predicting zero torque" in capsys.readouterr().out
    inner = table[:, -1] == 0
    # Noise-free: the measured torque is the arm's own (the closed form's, test above).
    measured = np.asarray(raw["tau"])[inner]
    err = table[inner, 1:6] - measured
    rms = np.sqrt(np.mean(measured**2, axis=0))
    rel = np.sqrt(np.mean(err**2, axis=0)) / rms
    print("held-out torque error per joint (% of RMS):", np.round(100 * rel, 3))
    assert np.all(rel < 0.025), rel
