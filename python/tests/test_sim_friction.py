"""Closed-loop simulation of robots with Coulomb friction of the exact sign (issue 25): the
UR5 of example-robot-data with friction added, and a UR5-like DH arm whose light wrist
(1.5e-4 kg·m² about its axis) carries 0.4 N·m of Coulomb friction (it used to end 7.7 rad
off its reference), track within the bound that `prrrp simulate --robot` states; the
recorded torques are Pinocchio's `rnea` at the recorded state plus the friction law
(fv·q̇ + fc·sgn q̇, and at a joint at rest a Coulomb torque within ±fc) and agree with the
independent model along the reference; the command refuses a run beyond its bound."""

import importlib.metadata
from pathlib import Path

import numpy as np
import pytest

import prrrp
from prrrp import cli
from prrrp.cli.simulate import MAX_TRACKING_ERROR

pin = pytest.importorskip("pinocchio")

ROOT = Path(__file__).resolve().parents[2]
UR5_LIKE = ROOT / "tests" / "data" / "ur5_like_friction.toml"
ROBOTS_DIR = importlib.metadata.distribution("example-robot-data").locate_file(
    "cmeel.prefix/share/example-robot-data/robots"
)
UR5 = ROBOTS_DIR / "ur_description/urdf/ur5_robot.urdf"
# [fv (N·m·s/rad), fc (N·m), fo] per joint, the UR5-like file's figures.
UR5_FRICTION = np.array([[2.0, 4.0, 0.0]] * 2 + [[1.5, 3.0, 0.0]] + [[0.3, 0.8, 0.0]] * 2)
UR5_FRICTION = np.vstack([UR5_FRICTION, [0.1, 0.4, 0.0]])


def fourier(n, scale=0.5):
    """A 0.2 Hz, 3-harmonic excitation from rest; every joint reverses several times."""
    a = scale * np.tile([0.6, -0.2, -0.4], (n, 1)) * (1 + 0.1 * np.arange(n))[:, None]
    b = scale * np.tile([0.3, 0.15, -0.2], (n, 1)) * (1 + 0.1 * np.arange(n))[:, None]
    offsets = 0.1 * np.arange(n) - 0.2
    return prrrp.ChainTrajectory.fourier(2 * np.pi * 0.2, offsets, a, b)


def ur5_urdf():
    chain = prrrp.SerialChain.from_urdf(str(UR5)).with_friction(
        "viscous+coulomb+offset", UR5_FRICTION
    )
    return chain, pin.buildModelFromUrdf(str(UR5))


def ur5_like():
    chain = prrrp.SerialChain.from_file(str(UR5_LIKE))
    # Pinocchio reads the arm from the URDF prrrp writes of it (kinematics and inertials);
    # the dynamics are Pinocchio's own.
    return chain, pin.buildModelFromXML(chain.to_urdf())


ROBOTS = {"ur5 (example-robot-data)": ur5_urdf, "ur5-like toml": ur5_like}


@pytest.fixture(scope="module", params=list(ROBOTS))
def run(request):
    chain, model = ROBOTS[request.param]()
    assert chain.dof == model.nv == 6
    rec = prrrp.simulate_chain(chain, fourier(6), 10.0)
    return chain, model, rec


def test_tracks_within_the_stated_bound(run):
    _, _, rec = run
    err = np.abs(rec.q - rec.q_ref).max(axis=0)
    assert (err < MAX_TRACKING_ERROR).all(), err


def test_recorded_torque_is_pinocchio_rnea_plus_the_friction_law(run):
    chain, model, rec = run
    data = model.createData()
    fv, fc, fo = chain.parameters[60:].reshape(6, 3).T
    assert fc.max() > 0
    assert chain.friction_params[:, 1].max() > 0
    at_rest = 0
    for k in range(len(rec)):
        q, qd, qdd = rec.q[k], rec.qd[k], rec.qdd[k]
        rigid = pin.rnea(model, data, q, qd, qdd)
        friction = fv * qd + fc * np.sign(qd) + fo
        diff = rec.tau[k] - rigid - friction
        moving = qd != 0
        tol = 1e-9 * (1 + np.abs(rigid).max())
        np.testing.assert_allclose(diff[moving], 0, atol=tol, err_msg=f"sample {k}")
        # A joint at rest: the friction that holds it, anywhere within ±fc.
        assert (np.abs(diff[~moving]) <= fc[~moving] * (1 + 1e-9) + tol).all(), (k, diff)
        at_rest += (~moving).sum()
    assert at_rest >= 6  # the start, at rest on the reference


def test_torque_agrees_with_the_independent_model_along_the_reference(run):
    # What a user checks with a CSV: the torques against Pinocchio plus friction at the
    # trajectory the robot was asked to follow. Chattering or a lost joint shows here
    # (35 % off on the UR5-like wrist before); only the brief sticking at reversals
    # remains.
    chain, model, rec = run
    data = model.createData()
    fv, fc, fo = chain.parameters[60:].reshape(6, 3).T
    ref = np.array(
        [
            pin.rnea(model, data, q, qd, qdd) + fv * qd + fc * np.sign(qd) + fo
            for q, qd, qdd in zip(rec.q_ref, rec.qd_ref, rec.qdd_ref, strict=True)
        ]
    )
    rel = np.sqrt(((rec.tau - ref) ** 2).mean(axis=0) / (ref**2).mean(axis=0))
    assert (rel < 0.01).all(), rel


def test_simulate_command_refuses_a_run_beyond_its_bound(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    t = np.arange(0, 1001) * 0.01
    q, qd, qdd = fourier(6).eval(t)
    header = ",".join(["t"] + [f"{s}{j}" for s in ("q", "qd", "qdd") for j in range(1, 7)])
    np.savetxt(
        "traj.csv", np.column_stack([t, q, qd, qdd]), delimiter=",", header=header, comments=""
    )
    robot = ["simulate", "--robot", str(UR5_LIKE), "--trajectory", "traj.csv"]
    assert cli.main([*robot, "--out", "data.csv"]) == cli.EXIT_OK
    out = capsys.readouterr().out
    assert f"bound {MAX_TRACKING_ERROR:g}" in out
    assert cli.main([*robot, "--out", "tight.csv", "--max-tracking-error", "1e-5"]) == 1
    err = capsys.readouterr().err
    assert "--max-tracking-error 1e-05" in err
    assert "no data written" in err
    assert not (tmp_path / "tight.csv").exists()
    assert cli.main([*robot, "--out", "x.csv", "--max-tracking-error", "-1"]) == 2
    assert "positive" in capsys.readouterr().err


def test_simulate_function_holds_the_same_bound():
    # The Python API refuses what the command refuses, and says where the run strayed.
    t = np.arange(0, 501) * 0.01
    q, qd, qdd = fourier(6).eval(t)
    robot = prrrp.load_robot(str(UR5_LIKE))
    traj = {"t": t, "q": q, "qd": qd, "qdd": qdd}
    rec = prrrp.simulate(robot, traj, noise=0.0)
    assert rec["tracking_error"].shape == (6,)
    assert np.allclose(rec["tracking_error"], np.abs(rec["q_true"] - q).max(axis=0))
    assert rec["tracking_error"].max() <= prrrp.workflow.MAX_TRACKING_ERROR
    bound = 0.5 * rec["tracking_error"].max()
    with pytest.raises(prrrp.TrackingError) as caught:
        prrrp.simulate(robot, traj, noise=0.0, max_tracking_error=bound)
    worst = int(np.argmax(rec["tracking_error"]))
    assert caught.value.joint == worst
    assert caught.value.error == pytest.approx(rec["tracking_error"][worst])
    assert prrrp.simulate(robot, traj, noise=0.0, max_tracking_error=None)["t"].shape == t.shape
    with pytest.raises(ValueError, match="max_tracking_error"):
        prrrp.simulate(robot, traj, max_tracking_error=float("nan"))
    # A trajectory without its velocities was a bare KeyError('qd').
    with pytest.raises(prrrp.InvalidInputError, match="no qd, qdd"):
        prrrp.simulate(robot, {"t": t, "q": q})
