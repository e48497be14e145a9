"""Payload identification and drive gains (issue 27) against Pinocchio: the UR10 of
example-robot-data with rotor inertias, friction and a 2.805 kg payload on the flange in two
mountings (``ur10_payload``). The arm is identified on an unloaded run, the payload on a
separate loaded run of another trajectory; mass, centre of mass and inertia are scored
against the payload Pinocchio carried. Drive gains from current logs (τ/K + noise) of the
same trajectory with and without the payload, with the bias check: the naive least squares
(noisy currents in the regressor) against the instrumental variables.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
import ur10_payload as ur

import prrrp
from prrrp.cli import main

TERMS = "viscous+coulomb+offset"


def _robot() -> prrrp.SerialChain:
    return prrrp.load_robot(ur.UR10, friction=TERMS, coulomb_scale=ur.V_S, armature=True)


def _dataset(r: dict[str, np.ndarray], tau: np.ndarray | None = None) -> prrrp.Dataset:
    return prrrp.Dataset(r["t"], r["q"], r["qd"], r["qdd"], r["tau"] if tau is None else tau)


@pytest.fixture(scope="module")
def arm() -> prrrp.IdentifiedModel:
    """The bare arm identified on an unloaded run (trajectory seed 1)."""
    robot = _robot()
    assert robot.link_names[-1] == "wrist_3_link"
    return prrrp.identify(robot, _dataset(ur.run(1, None, 10)), "wls")


@pytest.mark.parametrize("mounting", ["A", "B"])
def test_payload_mass_com_inertia_against_pinocchio(arm, mounting):
    """A loaded run of another trajectory (seed 2) whose friction offsets drifted: the
    payload's mass within 2 % and COM within 5 mm of the one Pinocchio carried; the
    inertia, where flagged identifiable, within 3 σ; the arm + payload model explains the
    loaded run to the torque sensors' noise."""
    m = ur.MOUNTINGS[mounting]
    truth = m.truth()
    loaded = _dataset(ur.run(2, m, 20))
    model = arm.identify_payload(loaded)
    p = model.payload
    assert p["link"] == "wrist_3_link"
    assert abs(p["mass"] / truth["mass"] - 1) < 0.02, (p["mass"], p["mass_sigma"])
    com_err = np.linalg.norm(np.array(p["com"]) - truth["com"])
    assert com_err < 0.005, (p["com"], truth["com"])
    assert p["identifiable"]["mass"]
    assert all(p["identifiable"]["com"])
    # σ is honest: the errors are of the size σ says.
    assert abs(p["mass"] - truth["mass"]) < 4 * p["mass_sigma"] + 1e-3
    for k, ok in enumerate(p["identifiable"]["inertia"]):
        if ok:
            err = abs(p["inertia"][k] - truth["inertia"][k])
            assert err < 3 * p["inertia_sigma"][k] + 1e-4, (k, p["inertia"], truth["inertia"])
    # Physical whatever the data: a rigid body (pseudo-inertia PSD, m > 0).
    assert prrrp.IdentifiedModel.from_json(model.to_json()).payload is not None
    pred = np.asarray(model.predict(loaded.q, loaded.qd, loaded.qdd))
    rms = np.sqrt(np.mean((pred - np.asarray(loaded.tau)) ** 2, axis=0))
    assert np.all(rms < 1.1 * ur.TAU_NOISE), rms / ur.TAU_NOISE
    bare = np.asarray(arm.predict(loaded.q, loaded.qd, loaded.qdd))
    rms_bare = np.sqrt(np.mean((bare - np.asarray(loaded.tau)) ** 2, axis=0))
    assert rms_bare[1] > 3 * ur.TAU_NOISE[1], "the payload must matter for the test to mean much"
    # A known mass: the rest fitted, the mass kept.
    fixed = arm.identify_payload(loaded, ur.MASS).payload
    assert fixed["mass"] == ur.MASS
    assert fixed["mass_given"]
    assert np.linalg.norm(np.array(fixed["com"]) - truth["com"]) < 0.005


def test_a_run_without_a_payload_says_so(arm):
    """Unloaded runs of other trajectories: a fitted mass <= 0 is an error saying the data
    show no payload, and one above 0 but within 2σ of it (not "identifiable" as a fraction
    of itself, yet bounded) is reported with the sentence that no payload was detected and
    the bound — never a bare "not identifiable" mass. A loaded run gets no such sentence."""
    from prrrp import payload as payloads

    refused = []
    for seed in range(4, 9):
        try:
            empty = arm.identify_payload(_dataset(ur.run(seed, None, 40 + seed))).payload
        except prrrp.InvalidParameterError as e:
            refused.append(str(e))
            continue
        assert abs(empty["mass"]) <= 2 * empty["mass_sigma"] < 0.1 * ur.MASS, empty["mass"]
        assert payloads.no_payload(empty).startswith("no payload detected")
        lines = payloads.payload_lines(empty)
        assert any(line.startswith("No payload detected") for line in lines)
    assert all("the data show no payload" in text for text in refused), refused
    loaded = arm.identify_payload(_dataset(ur.run(2, ur.MOUNTINGS["A"], 20))).payload
    assert payloads.no_payload(loaded) is None
    bounded = {"mass": 0.004, "mass_sigma": 0.003, "link": "wrist_3_link"}
    assert payloads.no_payload(bounded) == (
        "no payload detected: the fitted mass 0.004 ± 0.003 kg is within 2σ of 0, so "
        "anything carried at wrist_3_link weighs less than 0.01 kg"
    )
    assert payloads.no_payload({**bounded, "mass": 0.007}) is None
    assert payloads.no_payload({**bounded, "mass_given": True}) is None


def test_a_short_run_says_the_inertia_is_not_identifiable(arm):
    """Two seconds of motion: the mass and the COM may still show, the inertia about the
    COM cannot be told — flagged, and the value kept physical rather than printed raw."""
    loaded = _dataset(ur.run(3, ur.MOUNTINGS["A"], 30, duration=2.0))
    p = arm.identify_payload(loaded).payload
    assert not all(p["identifiable"]["inertia"]), p["inertia_sigma"]
    i = p["inertia"]
    inertia = np.array([[i[0], i[1], i[3]], [i[1], i[2], i[4]], [i[3], i[4], i[5]]])
    moments = np.linalg.eigvalsh(inertia)
    # A rigid body's principal moments: non-negative and each at most the sum of the others.
    tol = 1e-9 * max(1.0, float(np.abs(moments).max()))
    assert moments.min() >= -tol, moments
    assert 2 * moments.max() <= moments.sum() + tol, moments


def test_bad_payload_input_is_a_typed_error(arm):
    loaded = _dataset(ur.run(2, ur.MOUNTINGS["A"], 20, duration=4.0))
    # 1e-300 kg was taken, and the inertia came out at hundreds of kg·m².
    for mass in [-1.0, 1e-300, 1e300, float("nan")]:
        with pytest.raises(prrrp.InvalidParameterError, match="payload mass"):
            arm.identify_payload(loaded, mass)
    with pytest.raises(prrrp.InvalidParameterError, match="tip"):
        arm.identify_payload(loaded, tip="no_such_link")
    # -1 (Python's "last") was an OverflowError from the index's conversion.
    for tip in [-1, arm.robot.dof]:
        with pytest.raises(prrrp.InvalidParameterError, match=f"tip {tip} .links: 0 = "):
            arm.identify_payload(loaded, tip=tip)
    with pytest.raises(prrrp.ShapeMismatchError):
        arm.identify_payload(
            prrrp.Dataset(
                loaded.t,
                loaded.q[:, :5],
                loaded.qd[:, :5],
                loaded.qdd[:, :5],
                np.asarray(loaded.tau)[:, :5],
            )
        )


def _current_runs(rel_noise: float):
    """Unloaded and loaded runs of one trajectory (seed 4), currents τ/K + noise."""
    u = ur.run(4, None, 40)
    lo = ur.run(4, ur.MOUNTINGS["A"], 41)
    cu = ur.currents(u["tau_true"], rel_noise, 42)
    cl = ur.currents(lo["tau_true"], rel_noise, 43)
    return u, lo, cu, cl


def test_drive_gains_are_not_biased_by_noisy_currents():
    """The bias check: with currents 10 % noisy (white, of each current's RMS), every
    instrumental-variable gain the runs determine is within 2 % of the truth, and the
    joints the payload's weight loads (2–4) are determined; the naive least squares
    (currents in the regressor) is off by more on every joint."""
    u, lo, cu, cl = _current_runs(0.1)
    robot = _robot()
    start = prrrp.identify(robot, _dataset(u, cu), "wls")
    arm, payload, naive = prrrp.identify_drive_gains(
        start, _dataset(u, cu), _dataset(lo, cl), ur.MASS
    )
    g = arm.drive_gains
    iv_err = np.array(g["values"]) / ur.GAINS - 1
    naive_err = np.array(naive) / ur.GAINS - 1
    print("gain errors %: iv", np.round(100 * iv_err, 2), "naive", np.round(100 * naive_err, 2))
    assert all(g["identifiable"][j] for j in (1, 2, 3)), g
    for j, ok in enumerate(g["identifiable"]):
        if ok:
            assert abs(iv_err[j]) < 0.02, (j, iv_err)
    assert np.all(np.abs(naive_err) > 0.02), naive_err
    # A gain flagged identifiable is within 4 σ; σ is in N·m/A.
    for j, ok in enumerate(g["identifiable"]):
        if ok:
            assert abs(g["values"][j] - ur.GAINS[j]) < 4 * g["sigma"][j] + 1e-3, (j, g)
    # The arm in N·m predicts the unloaded run's joint torques to the friction model's
    # accuracy; the payload's COM comes with the gains.
    pred = np.asarray(arm.predict(u["q"], u["qd"], u["qdd"]))
    rms = np.sqrt(np.mean((pred - u["tau_true"]) ** 2, axis=0))
    scale = np.sqrt(np.mean(u["tau_true"] ** 2, axis=0))
    assert np.all(rms < 0.05 * scale), rms / scale
    assert np.linalg.norm(np.array(payload["com"]) - ur.MOUNTINGS["A"].truth()["com"]) < 0.01


def _write(path, r, cols):
    path.write_text(ur.csv_text(r["t"], r["q"], {"qd": r["qd"], "qdd": r["qdd"], **cols}))


def test_payload_and_drive_gains_through_the_command_line(tmp_path, capsys):
    """prrrp identify → prrrp payload → prrrp predict; identify --payload-run, then the
    identified gains given back with --drive-gains FILE.json."""
    u, lo = ur.run(1, None, 10, duration=20.0), ur.run(2, ur.MOUNTINGS["B"], 20, duration=20.0)
    _write(tmp_path / "unloaded.csv", u, {"tau": u["tau"]})
    _write(tmp_path / "loaded.csv", lo, {"tau": lo["tau"]})
    robot = ["--robot", ur.UR10, "--armature", "--coulomb-scale", str(ur.V_S)]
    arm_dir, pl_dir = tmp_path / "arm", tmp_path / "pl"
    assert main(["identify", str(tmp_path / "unloaded.csv"), *robot, "--out", str(arm_dir)]) == 0
    code = main(
        [
            "payload",
            str(tmp_path / "loaded.csv"),
            "--model",
            str(arm_dir / "model.json"),
            "--out",
            str(pl_dir),
        ]
    )
    assert code == 0, capsys.readouterr().err
    printed = capsys.readouterr().out
    assert "payload at link wrist_3_link" in printed
    doc = json.loads((pl_dir / "payload.json").read_text())
    truth = ur.MOUNTINGS["B"].truth()
    assert abs(doc["mass"] / ur.MASS - 1) < 0.03, doc["mass"]
    assert np.linalg.norm(np.array(doc["com"]) - truth["com"]) < 0.01
    report = (pl_dir / "report.md").read_text()
    assert "explained_torque.png" in report
    assert (pl_dir / "explained_torque.png").stat().st_size > 0
    assert (
        main(
            [
                "predict",
                str(pl_dir / "model.json"),
                str(tmp_path / "loaded.csv"),
                "--out",
                str(tmp_path / "tau.csv"),
            ]
        )
        == 0
    )
    capsys.readouterr()
    table = np.loadtxt(tmp_path / "tau.csv", delimiter=",", skiprows=1)
    rms = np.sqrt(np.mean((table[:, 1:7] - lo["tau"]) ** 2, axis=0))
    assert np.all(rms < 1.2 * ur.TAU_NOISE), rms / ur.TAU_NOISE
    # A wrong mass and a missing model are one-line errors (exit 2), nothing written.
    bad = ["payload", str(tmp_path / "loaded.csv"), "--model", str(arm_dir / "model.json")]
    # 1e-300 kg was taken (217 kg·m² of inertia), 1e300 read as a non-finite input.
    for mass in ["-2", "1e-300", "1e300", "nan"]:
        try:
            code = main([*bad, "--mass", mass, "--out", str(tmp_path / "bad")])
        except SystemExit as e:  # nan: argparse's own usage error
            code = e.code
        assert code == 2
        assert "--mass" in capsys.readouterr().err
        assert not (tmp_path / "bad").exists()
    assert main([*bad, "--tip", "no_such_link", "--out", str(tmp_path / "bad")]) == 2
    assert "no_such_link" in capsys.readouterr().err
    # An --out below a file: refused before the fit, not after it.
    assert main([*bad, "--out", str(tmp_path / "loaded.csv" / "out")]) == 2
    assert "is a file, not a folder" in capsys.readouterr().err
    assert not (tmp_path / "bad").exists()
    # --tip naming the last link is the default.
    assert main([*bad, "--tip", "wrist_3_link", "--out", str(tmp_path / "tip")]) == 0
    capsys.readouterr()
    named = json.loads((tmp_path / "tip" / "payload.json").read_text())
    assert named["parameters"] == doc["parameters"]

    # Drive gains: current logs i1..i6 of one trajectory with and without the payload.
    uc, lc = ur.run(4, None, 40, duration=30.0), ur.run(4, ur.MOUNTINGS["A"], 41, duration=30.0)
    _write(tmp_path / "u_i.csv", uc, {"i": ur.currents(uc["tau_true"], 0.05, 42)})
    _write(tmp_path / "l_i.csv", lc, {"i": ur.currents(lc["tau_true"], 0.05, 43)})
    gains_dir = tmp_path / "gains"
    code = main(
        [
            "identify",
            str(tmp_path / "u_i.csv"),
            *robot,
            "--payload-run",
            str(tmp_path / "l_i.csv"),
            "--payload-mass",
            str(ur.MASS),
            "--out",
            str(gains_dir),
        ]
    )
    assert code == 0, capsys.readouterr().err
    capsys.readouterr()
    model = prrrp.IdentifiedModel.load(gains_dir / "model.json")
    g = model.drive_gains
    for j in (1, 2, 3):
        assert g["identifiable"][j], g
        assert abs(g["values"][j] / ur.GAINS[j] - 1) < 0.02, g
    assert "Drive gains" in (gains_dir / "report.md").read_text()
    # The gains of the file, used for a later current log (all must be determined).
    argv = ["identify", str(tmp_path / "u_i.csv"), *robot, "--drive-gains"]
    code = main([*argv, str(gains_dir / "model.json"), "--out", str(tmp_path / "again")])
    if all(g["identifiable"]):
        assert code == 0, capsys.readouterr().err
    else:
        assert code == 2
        assert "did not determine" in capsys.readouterr().err


def test_readme_payload_tour_runs_as_written(tmp_path):
    """The README's "Payload" shell block, run by bash in a folder holding the logs it
    names (the UR10 stand-in's runs), with the installed `prrrp` on PATH."""
    import re
    from pathlib import Path

    from conftest import run_shell_block

    readme = Path(__file__).resolve().parents[2] / "README.md"
    text = readme.read_text(encoding="utf-8")
    section = text[text.index("## Payload") :]
    block = re.search(r"```bash\n(.*?)```", section, re.S).group(1)
    assert "prrrp payload" in block
    assert "--payload-run" in block
    u, lo = ur.run(1, None, 10, duration=20.0), ur.run(2, ur.MOUNTINGS["A"], 20, duration=20.0)
    _write(tmp_path / "unloaded.csv", u, {"tau": u["tau"]})
    _write(tmp_path / "loaded.csv", lo, {"tau": lo["tau"]})
    uc, lc = ur.run(4, None, 40, duration=20.0), ur.run(4, ur.MOUNTINGS["A"], 41, duration=20.0)
    _write(tmp_path / "unloaded_i.csv", uc, {"i": ur.currents(uc["tau_true"], 0.05, 42)})
    _write(tmp_path / "loaded_i.csv", lc, {"i": ur.currents(lc["tau_true"], 0.05, 43)})
    run_shell_block(block, tmp_path)
    for name in ("tool/payload.json", "tool/report.md", "tool-known-mass/model.json", "tau.csv"):
        assert (tmp_path / name).is_file(), name
    assert json.loads((tmp_path / "gains/model.json").read_text())["drive_gains"]["values"]
