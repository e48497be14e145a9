"""`prrrp track`'s causal low-pass lowered from the log's position noise (`online/cutoff.rs`)
on an arm no default was tuned on: example-robot-data's Unitree Z1 at the 100 Hz and
1e-4 rad of `prrrp simulate`, a 1 kg part gripped on its gripper jaw 15 s into 30 s. Its
joints accelerate at 0.1–0.9 rad/s² RMS; the noise the 10 Hz low-pass leaves in q̈ (0.12
rad/s²) made least squares read smaller inertias, and the RLS ended 2.8–5.1 % off on
joints 2–4 where the batch fit of a loaded run is 0.9–2.1 % off. Scored on another
loaded motion against the measured torques, as `prrrp predict` scores."""

from __future__ import annotations

import json

import numpy as np
import pytest
from test_track_unseen_arm import ROBOTS, _errors, _run, grip_logs

Z1 = ROBOTS / "z1_description" / "urdf" / "z1.urdf"


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    return grip_logs(tmp_path_factory.mktemp("z1"), Z1, "gripperMover", ("wls",))


def _track(logs, name: str, *extra: str) -> np.ndarray:
    out = logs / name
    _run(
        "track",
        str(logs / "grip.csv"),
        "--model",
        str(logs / "prior-wls" / "model.json"),
        "--out",
        str(out),
        *extra,
    )
    return out


def test_track_lowers_the_cutoff_on_a_noisy_encoder(logs, capsys):
    """By default the end model is as good as the batch fit (per joint within 1.1× its
    error + 0.3 points; measured within 0.2 points); at the fixed 10 Hz it is not."""
    val = logs / "val" / "data.csv"
    batch = _errors(logs / "batch" / "model.json", val, logs, capsys)
    auto = _track(logs, "auto")
    end = _errors(auto / "model.json", val, logs, capsys)
    fixed = _errors(_track(logs, "fixed", "--cutoff", "10") / "model.json", val, logs, capsys)
    print("auto", end, "10 Hz", fixed, "batch", batch)
    bar = 1.1 * batch + 0.3
    assert np.all(end <= bar), (end, batch)
    assert np.any(fixed > bar), (fixed, batch)
    settings = json.loads((auto / "model.json").read_text())["settings"]
    choice = settings["cutoff_choice"]
    assert settings["cutoff_hz"] == choice["chosen_hz"] < 10.0
    # The noise simulate adds, 1e-4 rad, read from the third differences of q.
    assert np.allclose(choice["sample_noise"], 1e-4, rtol=0.25), choice
    assert "lowered from 10 Hz" in (auto / "report.md").read_text()
    # The one-step-ahead predictions (their tracker lowered with the low-pass), against
    # the measured torques of the last 20 % of the rows: at 10 Hz the q̈ noise of the
    # tracker swamped them (134, 4.5, 14, 12 % on joints 1-4; measured now 31, 1.0, 4.2,
    # 5.8 %).
    late = [_late_error(logs, d) for d in (auto, logs / "fixed")]
    print("one-step, last 20 %: auto", late[0], "10 Hz", late[1])
    assert np.all(late[0] <= late[1])
    assert np.all(late[0][:4] < 0.5 * late[1][:4])


def _late_error(logs, out) -> np.ndarray:
    """RMS of measured − predicted torque over the last 20 % of the rows, % of the
    measured RMS, per joint."""
    tau = np.loadtxt(logs / "grip.csv", delimiter=",", skiprows=1)
    pred = np.loadtxt(out / "prediction.csv", delimiter=",", skiprows=1)
    n = (tau.shape[1] - 1) // 2
    late = slice(int(0.8 * len(tau)), None)
    meas = tau[late, 1 + n :]
    err = meas - pred[late, 1:]
    return 100 * np.sqrt((err**2).mean(0) / (meas**2).mean(0))


def test_track_ekf_keeps_its_lowpass_and_lowers_its_predictions(logs):
    """The whole-arm EKF's low-pass stays at 10 Hz (its filter measures q and q̇), so its
    estimates are those of `--cutoff 10` to the bit; only the one-step-ahead predictions'
    tracker is lowered, and they come closer to the measured torques."""
    auto = _track(logs, "ekf-auto", "--method", "ekf")
    fixed = _track(logs, "ekf-fixed", "--method", "ekf", "--cutoff", "10")
    models = [json.loads((d / "model.json").read_text()) for d in (auto, fixed)]
    settings = models[0]["settings"]
    assert settings["cutoff_hz"] == 10.0
    assert settings["prediction_cutoff_hz"] == settings["cutoff_choice"]["chosen_hz"] < 10.0
    assert models[0]["beta"] == models[1]["beta"]
    late = [_late_error(logs, d) for d in (auto, fixed)]
    print("ekf one-step, last 20 %: auto", late[0], "10 Hz", late[1])
    assert np.all(late[0][:4] < late[1][:4])
