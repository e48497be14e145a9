"""`prrrp identify --robot` and `prrrp predict` on the Panda URDF, run as a user would: a
7-joint log with friction turning over at 0.03 rad/s, repeated rows and no velocities."""

from __future__ import annotations

import importlib.metadata
from pathlib import Path

import numpy as np
import pytest
from conftest import sine_motion

import prrrp
from prrrp import cli, csvio

URDF = importlib.metadata.distribution("example-robot-data").locate_file(
    "cmeel.prefix/share/example-robot-data/robots/panda_description/urdf/panda.urdf"
)
FRICTION = np.tile([0.3, 0.8, 0.05], (7, 1))


@pytest.fixture(scope="module")
def truth():
    chain = prrrp.SerialChain.from_urdf(str(URDF), tip="panda_link8")
    return chain.with_friction("viscous+coulomb+offset", FRICTION, coulomb_smoothing=0.03)


def log(truth, path: Path, seed: int, seconds: float, noise: float = 0.02) -> None:
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, seconds, 0.002)
    q, qd, qdd = sine_motion(rng, t)
    tau = truth.inverse_dynamics(q, qd, qdd) + rng.normal(0, noise, q.shape)
    rep = np.repeat(np.arange(len(t)), np.where(rng.random(len(t)) < 0.05, 2, 1))
    path.write_text(csvio.format_measurements(t[rep], q[rep], tau[rep]))


def test_identify_any_robot_then_predict(tmp_path: Path, truth, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    log(truth, tmp_path / "data.csv", 1, 24.0)
    log(truth, tmp_path / "val.csv", 2, 12.0)
    # The friction turns over within 0.03 rad/s; at joint accelerations of ~1 rad/s² that
    # takes ~0.03 s, so the torque carries content up to ~15 Hz, which the low-pass must
    # keep (at the default 10 Hz the smeared turnover costs up to 6 % on joint 3).
    argv = ["identify", "data.csv", "--robot", str(URDF), "--tip", "panda_link8"]
    code = cli.main([*argv, "--validate", "val.csv", "--out", "out", "--cutoff", "20"])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "Coulomb speed scale" in out
    for name in ("model.json", "report.md", "torque.png", "residual.png", "friction.png"):
        assert (tmp_path / "out" / name).is_file(), name
    model = prrrp.IdentifiedModel.load(tmp_path / "out" / "model.json")
    # The scale was found from the data (truth 0.03 rad/s) and recorded with the model.
    assert 0.015 <= model.robot.coulomb_smoothing <= 0.06
    assert model.preprocessing["report"]["repeated_rows"] > 0
    report = (tmp_path / "out" / "report.md").read_text()
    assert "## Base parameters" in report
    assert "## Coulomb speed scale" in report
    # Predict a third log with the saved model alone.
    log(truth, tmp_path / "new.csv", 3, 12.0, noise=0.0)
    code = cli.main(["predict", "out/model.json", "new.csv", "--out", "tau.csv"])
    assert code == 0
    table = np.loadtxt(tmp_path / "tau.csv", delimiter=",", skiprows=1)
    raw = csvio.read_table(tmp_path / "new.csv", 7, real_log=True)
    # Every row of the input, at its time stamps (repeated ones included).
    assert table.shape == (len(raw["t"]), 1 + 7 + 1)
    assert np.array_equal(table[:, 0], raw["t"])
    edge = table[:, -1] == 1
    assert 0 < edge.sum() < 0.1 * len(edge)
    assert not edge[len(edge) // 2]
    # Reference: the true robot's torque at the exact states of the rows (the log's sines
    # evaluated at the rows' time stamps).
    rng = np.random.default_rng(3)
    w = 2 * np.pi * 0.2 * np.arange(1, 5)
    a = rng.normal(0, 0.4, (7, 4)) / np.arange(1, 5)
    tt = table[:, 0]
    s, c = np.sin(np.outer(tt, w)), np.cos(np.outer(tt, w))
    qq, qqd, qqdd = s @ a.T, (c * w) @ a.T, -(s * w**2) @ a.T
    assert np.allclose(qq, raw["q"], atol=1e-12)
    ref = truth.inverse_dynamics(qq, qqd, qqdd)
    err = table[:, 1:8] - ref
    rel = np.sqrt((err[~edge] ** 2).mean(axis=0) / (ref**2).mean(axis=0))
    assert (rel < 0.03).all(), rel
    # The edge rows are predicted too, from the filter's unsettled output: finite, and
    # within the torque's own scale.
    assert np.isfinite(table[edge]).all()
    rel_edge = np.sqrt((err[edge] ** 2).mean(axis=0) / (ref**2).mean(axis=0))
    assert (rel_edge < 1.0).all(), rel_edge


def test_friction_terms_take_the_cli_and_the_api_spelling():
    """`--friction` takes the comma list of its help and the "a+b" form of the Python API
    (`load_robot(..., friction="viscous+coulomb+offset")`), which a user copies over."""
    from prrrp.cli import common

    assert common.friction_terms("viscous,coulomb,offset") == "viscous+coulomb+offset"
    assert common.friction_terms("viscous+coulomb+offset") == "viscous+coulomb+offset"
    assert common.friction_terms(" viscous + offset ") == "viscous+offset"
    assert common.friction_terms("none") is None
    with pytest.raises(common.CliError, match="comma-separated"):
        common.friction_terms("viscous+sticky")


def test_identify_any_robot_bad_input(tmp_path: Path, truth, capsys):
    log(truth, tmp_path / "data.csv", 1, 4.0)
    base = ["identify", str(tmp_path / "data.csv"), "--robot", str(URDF), "--tip", "panda_link8"]
    assert cli.main(base) == cli.EXIT_USAGE
    assert "--out DIR is required" in capsys.readouterr().err
    out = ["--out", str(tmp_path / "o")]
    assert cli.main([*base, *out, "--coulomb-scale", "-1"]) == cli.EXIT_USAGE
    assert "0 (exact sign) or between" in capsys.readouterr().err
    assert cli.main([*base, *out, "--friction", "sticky"]) == cli.EXIT_USAGE
    assert "unknown term 'sticky'" in capsys.readouterr().err
    puma = tmp_path / "five.csv"
    puma.write_text(
        csvio.format_measurements(np.arange(50) * 0.01, np.zeros((50, 5)), np.zeros((50, 5)))
    )
    argv = ["identify", str(puma), "--robot", str(URDF), "--tip", "panda_link8", *out]
    assert cli.main(argv) == cli.EXIT_USAGE
    assert "missing columns 'q6', 'q7'" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()
    assert cli.main(["identify", str(puma), "--method", "rls"]) == cli.EXIT_USAGE
    assert "needs --robot" in capsys.readouterr().err


def test_identify_gives_no_percentage_for_a_dead_torque_channel(tmp_path: Path, truth, capsys):
    """A torque channel that reads 0 throughout: the summary's table gives "-" for that
    joint, says why, and prints no "nan"; the other joints keep their percentages."""
    rng = np.random.default_rng(4)
    t = np.arange(0.0, 12.0, 0.005)
    q, qd, qdd = sine_motion(rng, t)
    tau = truth.inverse_dynamics(q, qd, qdd) + rng.normal(0, 0.02, q.shape)
    tau[:, 6] = 0.0
    (tmp_path / "dead.csv").write_text(csvio.format_measurements(t, q, tau))
    argv = ["identify", str(tmp_path / "dead.csv"), "--robot", str(URDF), "--tip", "panda_link8"]
    assert cli.main([*argv, "--out", str(tmp_path / "o")]) == 0
    out = capsys.readouterr().out
    assert "nan" not in out.lower()
    row = next(line.split() for line in out.splitlines() if line.lstrip().startswith("wls "))
    assert row[-1] == "-"
    assert all(c.endswith("%") for c in row[-7:-1])
    assert "reads 0 over the scored rows" in out


def test_identify_names_the_joints_that_barely_move(tmp_path: Path, truth, capsys):
    """Joints 5–7 held still but for encoder noise (1e-4 rad): the fit runs (noise excites
    them a little) but does not determine their parameters; the terminal and report.md
    name exactly those joints. It used to give their 70–80 % errors without a word."""
    rng = np.random.default_rng(6)
    t = np.arange(0.0, 12.0, 0.005)
    q, qd, qdd = sine_motion(rng, t)
    q[:, 4:] = 0.2 + rng.normal(0, 1e-4, q[:, 4:].shape)
    qd[:, 4:] = qdd[:, 4:] = 0.0
    tau = truth.inverse_dynamics(q, qd, qdd) + rng.normal(0, 0.02, q.shape)
    (tmp_path / "still.csv").write_text(csvio.format_measurements(t, q, tau))
    argv = ["identify", str(tmp_path / "still.csv"), "--robot", str(URDF), "--tip", "panda_link8"]
    assert cli.main([*argv, "--out", str(tmp_path / "o")]) == 0
    line = next(s for s in capsys.readouterr().out.splitlines() if "barely move" in s)
    names = truth.joint_names
    report = (tmp_path / "o" / "report.md").read_text()
    for j, name in enumerate(names):
        assert (f"{name} (spans " in line) == (j >= 4), line
        assert (f"{name} (spans " in report) == (j >= 4)


def test_simulate_warns_of_a_trajectory_past_the_limits(tmp_path: Path, truth, capsys):
    """A given trajectory that leaves the Panda's position or speed limits is simulated
    (it is a simulation) with a warning that names each joint and bound it passes, and
    none for a trajectory within them."""
    t = np.arange(0.0, 4.0, 0.01)
    w = 2 * np.pi * 0.5
    mid = (truth.limits["lower"] + truth.limits["upper"]) / 2
    q = mid + 0.2 * np.sin(w * t)[:, None]
    qd = 0.2 * w * np.cos(w * t)[:, None] * np.ones(7)
    qdd = -0.2 * w**2 * np.sin(w * t)[:, None] * np.ones(7)
    names = truth.joint_names
    for k, (shift, pace) in enumerate([(0.0, 1.0), (5.0, 1.0), (0.0, 30.0)]):
        qq, vv = q.copy(), qd.copy()
        qq[:, 3] += shift  # past panda_joint4's upper bound (-0.07 rad)
        vv[:, 5] *= pace  # past panda_joint6's 2.61 rad/s
        path = tmp_path / f"traj{k}.csv"
        path.write_text(csvio.format_measurements(t, qq, np.zeros_like(qq), vv, qdd))
        argv = ["simulate", "--robot", str(URDF), "--tip", "panda_link8"]
        argv += ["--trajectory", str(path), "--max-tracking-error", "100"]
        assert cli.main([*argv, "--out", str(tmp_path / f"sim{k}")]) == 0
        out = capsys.readouterr().out
        line = next((s for s in out.splitlines() if s.startswith("warning: the traj")), "")
        assert (f"{names[3]} q up to" in line) == (shift > 0), line
        assert (f"{names[5]} |q̇| up to" in line) == (pace > 1), line
        assert sum(f"{n} " in line for n in names) == (shift > 0) + (pace > 1), line


def test_excite_simulate_identify_tour(tmp_path: Path, capsys, monkeypatch):
    """The README's "your robot" tour, as a user runs it, on the Panda URDF."""
    monkeypatch.chdir(tmp_path)
    robot = ["--robot", str(URDF), "--tip", "panda_link8"]
    assert cli.main(["excite", *robot, "--duration", "20", "--out", "traj"]) == 0
    out, err = capsys.readouterr()
    assert "cond(W_b)" in out
    assert "deprecated" not in err
    traj = csvio.read_table(tmp_path / "traj" / "trajectory.csv", 7, need_tau=False)
    chain = prrrp.SerialChain.from_urdf(str(URDF), tip="panda_link8")
    lim = chain.limits
    # At rest at both ends, within the file's position and speed limits everywhere.
    for k in (0, -1):
        assert np.abs(traj["qd"][k]).max() < 1e-9
        assert np.abs(traj["qdd"][k]).max() < 1e-9
    assert (traj["q"] >= lim["lower"]).all()
    assert (traj["q"] <= lim["upper"]).all()
    assert (np.abs(traj["qd"]) <= lim["velocity"]).all()
    # The trajectory's accelerations are the derivative of its velocities.
    dqd = np.gradient(traj["qd"], traj["t"], axis=0)
    assert np.abs(dqd[2:-2] - traj["qdd"][2:-2]).max() < 1e-2 * np.abs(traj["qdd"]).max()
    argv = ["simulate", *robot, "--trajectory", "traj/trajectory.csv", "--out", "data"]
    assert cli.main(argv) == 0
    assert sorted(p.name for p in (tmp_path / "data").iterdir()) == [".prrrp-output", "data.csv"]
    data = csvio.read_table(tmp_path / "data" / "data.csv", 7)
    # Closed-loop tracking: the measured motion follows the reference to within a few
    # milliradians; the measured torques are the robot's (noise 0.05 N·m).
    assert np.abs(data["q"] - traj["q"]).max() < 5e-3
    ref = chain.inverse_dynamics(traj["q"], traj["qd"], traj["qdd"])
    assert np.sqrt(((data["tau"] - ref) ** 2).mean()) < 0.5
    argv = ["identify", "data/data.csv", *robot, "--out", "out", "--cutoff", "20"]
    assert cli.main(argv) == 0
    argv = ["predict", "out/model.json", "traj/trajectory.csv", "--out", "tau.csv"]
    assert cli.main(argv) == 0
    pred = np.loadtxt(tmp_path / "tau.csv", delimiter=",", skiprows=1)[:, 1:8]
    scale = np.sqrt((ref**2).mean(axis=0))
    rel = np.sqrt(((pred - ref) ** 2).mean(axis=0)) / scale
    # Joints with torques well above the sensor noise are predicted within 10 %.
    big = scale > 2.0
    # (The q̈ the identification sees is differentiated from positions with 1e-4 rad noise;
    # that, not the torque noise, sets this error: ~0.2 N·m on the big joints.)
    assert (rel[big] < 0.1).all(), rel


def test_excite_bad_input(tmp_path: Path, capsys):
    robot = ["--robot", str(URDF), "--tip", "panda_link8", "--out", str(tmp_path / "t.csv")]
    assert cli.main(["excite", *robot, "--duration", "10", "--base-freq", "0.15"]) == 2
    assert "whole number of periods" in capsys.readouterr().err
    assert cli.main(["excite", *robot, "--limits", "speed=3"]) == 2
    assert "KEY=VALUE" in capsys.readouterr().err
    # 1e-300 rad/s designed a trajectory of cond(W) = 6e299 without a word.
    for bad in ["velocity=1e-300", "acceleration=0", "velocity=-2", "acceleration=1e300"]:
        assert cli.main(["excite", *robot, "--limits", bad]) == 2
        assert "must be between 1e-06 and 1e+06" in capsys.readouterr().err
    assert not (tmp_path / "t.csv").exists()
    puma = tmp_path / "puma.toml"
    # A DH robot file without limits: the error names the joint and what is missing.
    puma.write_text(
        'name = "one"\nconvention = "standard"\n'
        '[[joint]]\nname = "elbow"\ntype = "revolute"\nd = 0.0\na = 0.5\nalpha = 0.0\ntheta = 0.0\n'
        "inertial = [1.0, 0.25, 0.0, 0.0, 0.01, 0.0, 0.02, 0.0, 0.0, 0.02]\n"
    )
    code = cli.main(["excite", "--robot", str(puma), "--out", str(tmp_path / "t.csv")])
    err = capsys.readouterr().err
    assert code == 2, err
    assert "joint elbow has no speed limit and no position or acceleration limit" in err, err
    assert "--limits velocity=" in err, err
    # The Kinova Gen2 URDF: continuous joints, a speed limit only. The error names the
    # first, says what is missing and how to give it; the override then works.
    kinova = URDF.parent.parent.parent / "kinova_description" / "robots" / "kinova.urdf"
    out = str(tmp_path / "kinova")
    quick = ["--duration", "4", "--rate", "50", "--evaluations", "20", "--harmonics", "2"]
    assert cli.main(["excite", "--robot", str(kinova), "--out", out, *quick]) == 2
    err = capsys.readouterr().err
    assert "joint j2s6s200_joint_1 has no position or acceleration limit" in err, err
    assert not (tmp_path / "kinova").exists()
    limits = ["--limits", "velocity=1,acceleration=4"]
    assert cli.main(["excite", "--robot", str(kinova), "--out", out, *quick, *limits]) == 0
    assert (tmp_path / "kinova" / "trajectory.csv").exists()
    # `simulate` designs as `excite` does: the same error, and the same override.
    sim = ["simulate", "--robot", str(kinova), "--duration", "2"]
    assert cli.main([*sim, "--out", str(tmp_path / "sim0")]) == 2
    err = capsys.readouterr().err
    assert "has no position or acceleration limit" in err, err
    assert "prrrp simulate" in err, err
    assert cli.main([*sim, *limits, "--out", str(tmp_path / "sim")]) == 0
    data = np.loadtxt(tmp_path / "sim" / "data.csv", delimiter=",", skiprows=1)
    qd = np.gradient(data[:, 1:7], data[:, 0], axis=0)
    assert np.abs(qd).max() < 1.1, np.abs(qd).max()  # within velocity=1 (and noise)
    traj = str(tmp_path / "kinova" / "trajectory.csv")
    bad = ["simulate", "--robot", str(kinova), "--trajectory", traj, *limits, "--out"]
    assert cli.main([*bad, str(tmp_path / "sim1")]) == 2
    assert "--limits is not used with --trajectory" in capsys.readouterr().err


def test_model_report_from_python(tmp_path: Path, truth):
    log(truth, tmp_path / "data.csv", 4, 12.0)
    robot = prrrp.load_robot(str(URDF), tip="panda_link8", friction="viscous+coulomb+offset")
    run = prrrp.identify_measurements(
        robot, prrrp.read_measurements(tmp_path / "data.csv", robot), "wls"
    )
    written = run.model.report(tmp_path / "rep", run.data)
    names = sorted(p.name for p in written)
    assert names == ["friction.png", "report.md", "residual.png", "torque.png"]
    text = (tmp_path / "rep" / "report.md").read_text()
    assert "(wls)" in text
    assert "## Coulomb speed scale" in text


def test_identify_physical_writes_a_urdf(tmp_path: Path, truth, monkeypatch):
    monkeypatch.chdir(tmp_path)
    log(truth, tmp_path / "data.csv", 6, 12.0)
    argv = ["identify", "data.csv", "--robot", str(URDF), "--tip", "panda_link8"]
    assert cli.main([*argv, "--method", "physical", "--out", "out", "--cutoff", "20"]) == 0
    chain = prrrp.SerialChain.from_urdf(str(tmp_path / "out" / "robot.urdf"))
    assert chain.dof == 7
    assert chain.is_physically_consistent()
    assert "## Physical feasibility" in (tmp_path / "out" / "report.md").read_text()


def test_method_all_compares_every_method(tmp_path: Path, truth, capsys, monkeypatch):
    """`--method all`: one model-<method>.json each, model.json the default method's (not
    a copy of ls), a report comparing the methods (table and figure); a method that fails
    is reported in the table and does not stop the others."""
    monkeypatch.chdir(tmp_path)
    log(truth, tmp_path / "data.csv", 7, 8.0)
    log(truth, tmp_path / "val.csv", 8, 6.0)
    real_identify = prrrp.workflow.identify

    def flaky(robot, data, method, **kwargs):
        if method == "hopfield":
            raise prrrp.DivergedError("hopfield diverged at epoch 3 (test fault)")
        return real_identify(robot, data, method, **kwargs)

    monkeypatch.setattr(prrrp.workflow, "identify", flaky)
    argv = ["identify", "data.csv", "--robot", str(URDF), "--tip", "panda_link8"]
    code = cli.main([*argv, "--method", "all", "--validate", "val.csv", "--out", "out"])
    text = capsys.readouterr().out
    assert code == 0, text
    out = tmp_path / "out"
    ok = [m for m in prrrp.workflow.METHODS if m != "hopfield"]
    for method in ok:
        assert prrrp.IdentifiedModel.load(out / f"model-{method}.json").method == method
    assert not (out / "model-hopfield.json").exists()
    default = prrrp.workflow.DEFAULT_METHOD
    assert (out / "model.json").read_bytes() == (out / f"model-{default}.json").read_bytes()
    assert (out / "model.json").read_bytes() != (out / "model-ls.json").read_bytes()
    assert (out / "methods.png").read_bytes()[:4] == b"\x89PNG"
    report = (out / "report.md").read_text()
    assert report.startswith("# Identified models of panda: methods compared")
    assert "## Methods compared" in report
    assert f"## The {default} model (`model.json`)" in report
    rows = [ln for ln in report.splitlines() if ln.startswith("| ") and "|" in ln[2:]]
    for method in ok:
        row = next(r for r in rows if r.startswith(f"| {method} | ok |"))
        # converged, epochs, time, 7 held-out and 7 identification errors
        assert len(row.strip("|").split("|")) == 5 + 7 + 7, row
    assert any(r.startswith("| hopfield | failed: hopfield diverged") for r in rows)
    assert "hopfield: failed: hopfield diverged" in text
    assert f"model.json is the {default} model" in text
    # The printed table has every method that ran, with its time.
    for method in ok:
        assert any(ln.split()[:1] == [method] for ln in text.splitlines()), method


def test_method_all_where_every_method_fails_exits_1(tmp_path: Path, truth, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    log(truth, tmp_path / "data.csv", 7, 4.0)

    def broken(robot, data, method, **kwargs):
        raise prrrp.DivergedError(f"{method} broke (test fault)")

    monkeypatch.setattr(prrrp.workflow, "identify", broken)
    argv = ["identify", "data.csv", "--robot", str(URDF), "--tip", "panda_link8"]
    assert cli.main([*argv, "--method", "all", "--out", "out"]) == cli.EXIT_FAILED
    err = capsys.readouterr().err
    assert "every method failed" in err
    assert "ekf broke" in err
    assert len(err.strip().splitlines()) == 1
    assert not (tmp_path / "out").exists()


def test_chain_options_without_a_urdf_are_usage_errors(tmp_path: Path, capsys):
    data = tmp_path / "d.csv"
    data.write_text(
        csvio.format_measurements(np.arange(50) * 0.01, np.zeros((50, 5)), np.zeros((50, 5)))
    )
    cases = [
        (["identify", str(data), "--tip", "x"], "--tip needs --robot"),
        (["identify", str(data), "--cutoff", "5"], "--cutoff applies to --robot"),
        (["excite", "--robot", "arm.toml", "--base", "b", "--out", "t.csv"], "not one"),
        (["benchmark", "--tip", "x", "--out", str(tmp_path / "b")], "--tip needs --robot"),
        (["simulate", "--out", str(tmp_path / "s.csv"), "--base", "x"], "--base needs"),
    ]
    for argv, message in cases:
        assert cli.main(argv) == cli.EXIT_USAGE, argv
        err = capsys.readouterr().err
        assert message in err, (argv, err)
        assert len(err.strip().splitlines()) == 1


def test_comparison_section_names_the_model_json_method():
    from prrrp import model_report

    errors = {"percent": [1.0, 2.0]}
    rows = [
        {"method": "ls", "status": "ok", "converged": True, "epochs": None, "seconds": 0.1,
         "error": None, "identification": errors, "validation": None},
        {"method": "wls", "status": "failed", "converged": None, "epochs": None,
         "seconds": 0.2, "error": "boom", "identification": None, "validation": None},
    ]  # fmt: skip
    text = "\n".join(model_report.comparison_section(rows, ["a", "b"], "ls", None, "wls"))
    assert "`model.json` is the ls model (the default, wls, failed" in text
    assert "| wls | failed: boom |" in text
    assert "| ls | ok | yes | – | 0.1 | 1 | 2 |" in text
