"""`prrrp.OnlineIdentifier` and `prrrp track` against Pinocchio: a UR5 of example-robot-data
whose torques come from `pin.rnea`, with a payload added to the last joint's inertia
(Pinocchio's own `Inertia` arithmetic) when the part is gripped mid-run."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pinocchio as pin
import pytest
from pinocchio_standin import ARMS, ROBOTS, _multisine, _torques

import prrrp
from prrrp.cli import main

RATE = 250.0
GRIP = 10.0
PART = {
    "mass": 2.0,
    "com": np.array([0.01, -0.02, 0.06]),
    "inertia_com": np.diag([4e-3, 4e-3, 3e-3]),
}


def _ur5():
    rel, tip = ARMS["ur5"]
    path = str(ROBOTS / rel)
    chain = prrrp.SerialChain.from_urdf(path, tip=tip)
    full = pin.buildModelFromUrdf(path)
    names = list(chain.joint_names)
    lock = [full.getJointId(j) for j in full.names[1:] if j not in names]
    model = pin.buildReducedModel(full, lock, pin.neutral(full)) if lock else full
    return chain, model


def _loaded(model: pin.Model) -> pin.Model:
    out = model.copy()
    part = pin.Inertia(PART["mass"], PART["com"], PART["inertia_com"])
    last = out.njoints - 1
    out.inertias[last] = out.inertias[last] + part
    return out


def _log(model, loaded, seed, seconds, grip, noise=0.02):
    rng = np.random.default_rng(seed)
    n = model.nv
    t, q, qd, qdd = _multisine(rng, n, seconds, RATE, np.full(n, 0.8), f0=0.1)
    tau = _torques(model, q, qd, qdd)
    if grip is not None:
        after = t >= grip
        tau[after] = _torques(loaded, q[after], qd[after], qdd[after])
    return {
        "t": t,
        "q": q + rng.normal(0, 1e-5, q.shape),
        "qd": qd,
        "qdd": qdd,
        "tau": tau + rng.normal(0, noise, tau.shape),
        "exact": tau,
    }


@pytest.fixture(scope="module")
def setup():
    chain, model = _ur5()
    loaded = _loaded(model)
    un = _log(model, loaded, 1, 20.0, None)
    data = prrrp.Dataset(un["t"], un["q"], un["qd"], un["qdd"], un["tau"])
    prior = prrrp.identify(chain, data, "wls")
    run = _log(model, loaded, 2, 20.0, GRIP)
    val = _log(model, loaded, 3, 8.0, 0.0)
    return chain, prior, run, val


def _rel_error(m: prrrp.IdentifiedModel, val) -> np.ndarray:
    err = np.asarray(m.predict(val["q"], val["qd"], val["qdd"])) - val["exact"]
    return np.sqrt(np.mean(err**2, axis=0) / np.mean(val["exact"] ** 2, axis=0))


@pytest.mark.parametrize("method", ["rls", "ekf"])
def test_payload_mode_finds_the_gripped_mass(setup, method):
    """Payload mode on a prior of the bare arm: the change is detected within a second of
    the grip, the mass is within 5 % (Pinocchio's torques, not prrrp's), and the model at
    the end predicts another loaded motion within 3 % of each joint's RMS torque."""
    _chain, prior, run, val = setup
    online = prrrp.OnlineIdentifier(prior=prior, method=method, payload=True)
    changes = []
    for k in range(len(run["t"])):
        out = online.update(run["t"][k], run["q"][k], run["tau"][k])
        if out["change"]:
            changes.append(run["t"][k])
    assert any(GRIP <= c < GRIP + 1 for c in changes), changes
    p = online.payload()
    assert abs(p["mass"] / PART["mass"] - 1) < 0.05, p["mass"]
    assert 0 < p["mass_sigma"] < 0.1 * PART["mass"]
    assert p["physical"]
    err = _rel_error(online.estimate(), val)
    assert np.all(err < 0.03), err


@pytest.mark.parametrize("method", ["rls", "ekf"])
def test_whole_arm_from_a_prior_follows_the_grip(setup, method):
    """The whole arm tracked from the bare arm's prior, as `prrrp track --model` runs: 3 s
    after the grip the estimate predicts another loaded motion within 15 % of each joint's
    RMS torque, at the end within 3 % (Pinocchio's torques). The running EKF opened in
    place after the alarm was 2231 % off 3 s after this grip."""
    _chain, prior, run, val = setup
    online = prrrp.OnlineIdentifier(prior=prior, method=method)
    after3 = None
    changes = []
    for k in range(len(run["t"])):
        out = online.update(run["t"][k], run["q"][k], run["tau"][k])
        if out["change"]:
            changes.append(run["t"][k])
        if after3 is None and run["t"][k] >= GRIP + 3.0:
            after3 = _rel_error(online.estimate(), val)
    assert any(GRIP <= c < GRIP + 1 for c in changes), changes
    assert np.all(after3 < 0.15), after3
    end = _rel_error(online.estimate(), val)
    assert np.all(end < 0.03), end


def test_future_rows_do_not_change_past_outputs(setup):
    _chain, prior, run, _ = setup
    k0 = 600
    outs = []
    for tau in (run["tau"], np.where(np.arange(len(run["t"]))[:, None] >= k0, 0.0, run["tau"])):
        online = prrrp.OnlineIdentifier(prior=prior, method="rls")
        outs.append([online.update(run["t"][k], run["q"][k], tau[k]) for k in range(k0 + 50)])
    for k in range(k0):
        for key in ("prediction", "estimate", "sigma"):
            np.testing.assert_array_equal(outs[0][k][key], outs[1][k][key])
    assert not np.array_equal(outs[0][-1]["estimate"], outs[1][-1]["estimate"])


def test_bad_input_is_a_typed_error(setup):
    chain, _prior, *_ = setup
    online = prrrp.OnlineIdentifier(chain)
    online.update(0.0, np.zeros(6), np.ones(6))
    with pytest.raises(prrrp.NonFiniteError):
        online.update(0.01, [0, 0, np.nan, 0, 0, 0], np.ones(6))
    with pytest.raises(prrrp.ShapeMismatchError):
        online.update(0.01, np.zeros(5), np.ones(6))
    with pytest.raises(prrrp.NonIncreasingTimeError):
        online.update(-1.0, np.zeros(6), np.ones(6))
    # Finite but absurd (a unit slip): refused at the row, naming it, before its squares
    # overflow the noise levels; before, every row was taken, nothing learned, and only
    # estimate() failed, on `residual_rms`.
    with pytest.raises(prrrp.InvalidParameterError, match=r"tau\[2\] at row 1.*units"):
        online.update(0.01, np.zeros(6), [1, 1, 1e300, 1, 1, 1])
    assert online.counts[0] == 1
    # A seed below 0 was Python's OverflowError; a δ of 1e12 was taken and diverged at
    # row 62 (rls) or, with the ekf, predicted zeros from its warm-up's restart on.
    for bad in (
        {"forgetting": 0.0},
        {"method": "adaline", "step_size": 2.5},
        {"payload": True},
        {"seed": -1},
        {"initial_covariance": 1e12},
        {"method": "ekf", "initial_covariance": 1e12},
        {"initial_covariance": 1e-300},
    ):
        with pytest.raises(prrrp.InvalidParameterError):
            prrrp.OnlineIdentifier(chain, **bad)
    # Rows at 5 Hz, below twice the 10 Hz cut-off: every row restarted the filtering and
    # nothing was learned, silently; 100 such rows in a row are refused.
    slow = prrrp.OnlineIdentifier(chain)
    for k in range(100):
        slow.update(0.2 * k, np.full(6, np.sin(0.06 * k)), np.ones(6))
    with pytest.raises(prrrp.InvalidParameterError, match=r"cutoff_hz.*Nyquist"):
        slow.update(20.0, np.zeros(6), np.ones(6))
    assert slow.counts[0] == 100
    with pytest.raises(prrrp.InvalidParameterError):
        prrrp.OnlineIdentifier(chain, method="kalman")
    with pytest.raises(prrrp.InvalidParameterError):
        prrrp.OnlineIdentifier()
    # A robot beside a prior was dropped without a word (the prior's robot was tracked).
    with pytest.raises(prrrp.InvalidParameterError, match="carries its robot"):
        prrrp.OnlineIdentifier(chain, prior=_prior)
    # From no knowledge, before any row has updated it, the estimate is zeros, not a model:
    # it was returned, "converged", predicting 0 everywhere.
    fresh = prrrp.OnlineIdentifier(chain)
    with pytest.raises(prrrp.InvalidParameterError, match="estimate after 0 rows"):
        fresh.estimate()
    fresh.update(0.0, np.zeros(6), np.ones(6))
    with pytest.raises(prrrp.InvalidParameterError, match="estimate after 1 rows"):
        fresh.estimate()
    assert prrrp.OnlineIdentifier(prior=_prior).estimate().robot.dof == 6


@pytest.mark.parametrize("method", ["rls", "ekf"])
def test_a_torque_channel_that_reads_zero_teaches_nothing(setup, method):
    """Torques exactly 0 while the arm moves (a channel not connected, a sensor not yet
    streaming): no row is regression data, and nothing is learned. Before, such a joint was
    weighted 1/1e-300 (its noise floor scales with its largest torque) and its first
    equation overflowed the estimator: "diverged at sample 0", with or without a prior."""
    chain, prior, run, _ = setup
    zero = np.zeros(chain.dof)
    for start in (None, prior):
        online = prrrp.OnlineIdentifier(
            chain if start is None else None, prior=start, method=method
        )
        before = np.array(online.parameters)
        for k in range(int(2 * RATE)):
            online.update(run["t"][k], run["q"][k], zero)
        assert online.counts[1] == 0
        np.testing.assert_allclose(online.parameters, before, rtol=1e-12, atol=0)


@pytest.mark.parametrize("method", ["rls", "ekf"])
def test_torques_that_start_late_are_learned_from_where_they_start(setup, method):
    """The torque channels deliver only from 1 s on (exact zeros before, the arm already
    moving): the identifier starts there as on a log that starts there. Filtered through
    the step from 0, the first torques were fitted from no knowledge and the estimate never
    recovered (10⁴–10⁶ % off at the end on this log, 0.05–0.8 % on the plain one)."""
    chain, _prior, run, val = setup
    late = run["tau"].copy()
    late[: int(RATE)] = 0.0
    ends = []
    for tau in (run["tau"], late):
        online = prrrp.OnlineIdentifier(chain, method=method)
        for k in range(len(run["t"])):
            online.update(run["t"][k], run["q"][k], tau[k])
        ends.append(_rel_error(online.estimate(), val))
    print(method, "plain / late start, % of RMS torque:", *(np.round(100 * e, 2) for e in ends))
    assert np.all(ends[1] <= 1.5 * ends[0] + 0.01), ends


def _write_csv(path, log):
    n = log["q"].shape[1]
    header = ["t", *(f"q{j + 1}" for j in range(n)), *(f"tau{j + 1}" for j in range(n))]
    table = np.column_stack([log["t"], log["q"], log["tau"]])
    np.savetxt(path, table, delimiter=",", header=",".join(header), comments="")


def _files(tmp_path, log, prior, name="loaded.csv"):
    """``log`` written as a CSV and ``prior`` as a model file in ``tmp_path``: the command
    line of `prrrp track` of them from the prior into ``tmp_path/track``, and that
    folder."""
    data = tmp_path / name
    _write_csv(data, log)
    prior_path = tmp_path / "prior.json"
    prior.save(prior_path)
    out = tmp_path / "track"
    return ["track", str(data), "--model", str(prior_path), "--out", str(out)], out


def _track_loaded_log(setup, tmp_path, *flags):
    """`prrrp track` of the setup's loaded log (a CSV) from its prior, with ``flags``: the
    CSV's path and the output folder."""
    _chain, prior, run, _ = setup
    argv, out = _files(tmp_path, run, prior)
    assert main([*argv, *flags]) == 0
    return tmp_path / "loaded.csv", out


def test_track_command_writes_its_outputs(setup, tmp_path):
    """`prrrp track --payload` on a CSV: every file, payload.json's mass within 5 %, a
    model.json that `prrrp predict` takes, one prediction row per input row."""
    _chain, _prior, run, _ = setup
    data, out = _track_loaded_log(setup, tmp_path, "--payload")
    for name in (
        "model.json",
        "payload.json",
        "estimates.csv",
        "prediction.csv",
        "track.png",
        "report.md",
    ):
        assert (out / name).is_file(), name
    payload = json.loads((out / "payload.json").read_text())
    assert abs(payload["mass"] / PART["mass"] - 1) < 0.05
    assert payload["identifiable"]["mass"]
    pred = np.loadtxt(out / "prediction.csv", delimiter=",", skiprows=1)
    assert pred.shape == (len(run["t"]), 7)
    np.testing.assert_array_equal(pred[:, 0], run["t"])
    assert (
        main(["predict", str(out / "model.json"), str(data), "--out", str(tmp_path / "t.csv")]) == 0
    )
    assert main(["track", str(data), "--payload", "--robot", "x.urdf", "--out", str(out)]) == 2


def test_identify_ekf_takes_the_options_its_errors_name(setup, tmp_path):
    """`prrrp identify --method ekf --ekf-prior-width W --ekf-noise F` reach the filter
    (recorded in the model's settings); a non-positive value is a usage error."""
    _chain, _prior, run, _ = setup
    rel, _tip = ARMS["ur5"]
    data = tmp_path / "ur5.csv"
    unloaded = {k: v[: int(GRIP * RATE)] for k, v in run.items()}
    _write_csv(data, unloaded)
    out = tmp_path / "ekf"
    common = ["identify", str(data), "--robot", str(ROBOTS / rel), "--method", "ekf"]
    assert main([*common, "--ekf-noise", "0", "--out", str(out)]) == 2
    # Squared into covariances: 1e300 was taken, and the filter started from the diagonal
    # prior without a word.
    assert main([*common, "--ekf-prior-width", "1e300", "--out", str(out)]) == 2
    assert main([*common, "--ekf-noise", "1e-300", "--out", str(out)]) == 2
    assert not out.exists()
    code = main([*common, "--ekf-prior-width", "2", "--ekf-noise", "3", "--out", str(out)])
    assert code == 0
    settings = prrrp.IdentifiedModel.load(out / "model.json").settings
    assert settings["least_squares_prior_width"] == 2.0
    assert np.atleast_1d(settings["position_noise"])[0] == pytest.approx(3e-3)


def test_absurd_options_are_usage_errors(setup, tmp_path, capsys):
    """Finite but absurd settings are refused, naming the option, before any output: a
    prior width of 1e300 (squared to inf, the prior dropped silently), an ekf noise of
    1e-300 (a variance of 0), a cut-off whose transient outlasts the log (it read "need at
    least 18446744073709551615 samples"), a noise factor whose log prrrp cannot read, a
    rate of 1e-300 Hz, a Coulomb speed scale of 1e300 or 1e-300 rad/s."""
    _chain, _prior, run, _ = setup
    rel, _tip = ARMS["ur5"]
    data = tmp_path / "ur5.csv"
    _write_csv(data, {k: v[: int(5 * RATE)] for k, v in run.items()})
    robot = str(ROBOTS / rel)
    out = tmp_path / "out"
    cases = [
        (["track", str(data), "--robot", robot, "--prior-width", "1e300"], "--prior-width"),
        (
            ["track", str(data), "--robot", robot, "--method", "ekf", "--ekf-noise", "1e-300"],
            "--ekf-noise",
        ),
        (["identify", str(data), "--robot", robot, "--cutoff", "1e-300"], "cutoff"),
        (["simulate", "--robot", robot, "--duration", "2", "--noise", "1e300"], "--noise"),
        (["benchmark", "--robot", robot, "--noise", "1e300", "--seeds", "1"], "noise scale"),
        # One sample over 10 s was written; the log resampled to one row.
        (["excite", "--robot", robot, "--rate", "1e-300"], "twice the highest harmonic"),
        (["identify", str(data), "--robot", robot, "--rate", "1e-300"], "rate_hz"),
        # tanh(q̇/1e300) is 0: the Coulomb term was gone without a word.
        (["track", str(data), "--robot", robot, "--coulomb-scale", "1e300"], "--coulomb-scale"),
        (["identify", str(data), "--robot", robot, "--coulomb-scale", "1e-300"], "--coulomb-scale"),
        # nan reached the model's record and read "must be a JSON-serialisable dict".
        (["identify", str(data), "--robot", robot, "--cutoff", "nan"], "finite number"),
        (["track", str(data), "--robot", robot, "--forgetting", "inf"], "finite number"),
        # An empty or repeated friction term was taken as none or as one.
        (["identify", str(data), "--robot", robot, "--friction", ""], "an empty term"),
        (["track", str(data), "--robot", robot, "--friction", "viscous,viscous"], "twice"),
        # EKF settings given to another method were ignored without a word.
        (["identify", str(data), "--robot", robot, "--ekf-noise", "2"], "--method ekf"),
        (["identify", str(data), "--robot", robot, "--ekf-prior-width", "2"], "--method ekf"),
        (["track", str(data), "--robot", robot, "--ekf-noise", "2"], "--method ekf"),
    ]
    for argv, needle in cases:
        capsys.readouterr()
        try:
            code = main([*argv, "--out", str(out)])
        except SystemExit as e:  # argparse's own usage errors
            code = e.code
        assert code == 2, argv
        err = capsys.readouterr().err
        assert needle in err, err
        assert "Traceback" not in err, err
        assert not out.exists()


def test_track_figure_error_window_is_in_seconds():
    """The figure's 0.1 s RMS of the one-step-ahead errors is taken over the rows within
    0.05 s of each row, on any clock: against a plain loop over the rows, on irregular
    time stamps with repeated rows and a gap (a median step of 0 from the repeated rows
    made the window one row before)."""
    from prrrp.cli.track import windowed_rms

    rng = np.random.default_rng(5)
    t = np.cumsum(rng.uniform(0.5e-3, 3e-3, 400))
    t[200:] += 1.0  # a gap
    t = np.sort(np.concatenate([t, t[::3]]))  # every third row repeated
    x = rng.standard_normal(len(t))
    want = [np.sqrt(np.mean(x[np.abs(t - tk) <= 0.05] ** 2)) for tk in t]
    np.testing.assert_allclose(windowed_rms(t, x, 0.1), want, rtol=1e-9)
    # Constant errors: the same RMS at every row, the ends included.
    np.testing.assert_allclose(windowed_rms(t, np.full(len(t), 2.0), 0.1), 2.0, rtol=1e-12)


def test_track_figure_draws_the_best_determined_parameters():
    """The whole-arm panel of track.png draws at most 8 parameters: those with the smallest
    final σ/|θ| (zero values left out), or without σ (adaline, hopfield) the smallest
    spread over the last fifth of the rows relative to |θ|."""
    from prrrp.cli.track import shown_parameters

    rng = np.random.default_rng(3)
    p, rows = 12, 50
    final = rng.uniform(0.5, 2.0, p) * rng.choice([-1, 1], p)
    final[4] = 0.0
    rel = rng.permutation(np.geomspace(1e-3, 10, p))
    rel[4] = 1e-6  # the smallest σ, but of a zero value: no relative size
    theta = final + 0.01 * rng.standard_normal((rows, p))
    theta[-1] = final
    sigma = np.tile(rel * np.abs(final), (rows, 1))
    est = np.column_stack([np.arange(rows), theta, sigma])
    want = [k for k in np.argsort(rel) if k != 4][:8]
    assert shown_parameters(est, p) == want
    assert shown_parameters(est, p, most=3) == want[:3]
    # Without σ: the spread of the late rows decides.
    late = theta.copy()
    spread = rng.permutation(np.geomspace(1e-4, 1e-1, p))
    late[40:] = final + spread * np.abs(final) * rng.choice([-1, 1], (rows - 40, p))
    late[-1] = final
    est = np.column_stack([np.arange(rows), late, np.full((rows, p), np.nan)])
    with np.errstate(invalid="ignore"):  # 0/0 for the zero value, left out below
        rel_spread = np.std(late[40:], axis=0) / np.abs(final)
    want = [k for k in np.argsort(rel_spread) if k != 4][:8]
    assert shown_parameters(est, p) == want


def test_track_report_numbers_are_those_of_its_files(setup, tmp_path, capsys):
    """report.md's table, recomputed from the data and prediction.csv: each joint's RMS
    torque and the raw rows' error over the last 20 %; the level on the low-passed rows is
    below the raw rows' error (the log's torque noise, 0.02 N·m, is what the low-pass
    removes and no model predicts) and its % is the level over that RMS torque. The
    terminal prints both percentages of the table."""
    chain, _prior, run, _ = setup
    capsys.readouterr()
    _data, out = _track_loaded_log(setup, tmp_path)
    printed = capsys.readouterr().out.splitlines()
    text = (out / "report.md").read_text()
    rows = [
        line.split("|")[2:6]
        for line in text.splitlines()
        if line.startswith("| ") and line.split("|")[1].strip() in chain.joint_names
    ]
    table = np.array([[float(v) for v in r] for r in rows])
    assert table.shape == (6, 4)
    pred = np.loadtxt(out / "prediction.csv", delimiter=",", skiprows=1)[:, 1:]
    tau = run["tau"]
    late = slice(int(0.8 * len(tau)), len(tau))
    rms = np.sqrt(np.mean(tau[late] ** 2, axis=0))
    err = 100 * np.sqrt(np.mean((pred[late] - tau[late]) ** 2, axis=0)) / rms
    np.testing.assert_allclose(table[:, 0], rms, rtol=5e-3)
    np.testing.assert_allclose(table[:, 1], err, rtol=5e-3)
    assert np.all(table[:, 2] < table[:, 1] / 100 * rms)
    np.testing.assert_allclose(table[:, 3], 100 * table[:, 2] / table[:, 0], rtol=1e-2)
    for start, column in [("one-step-ahead error", 1), ("  running level", 3)]:
        line = next(s for s in printed if s.startswith(start))
        shown = [float(c) for c in line.rsplit(":", 1)[1].split(",")]
        np.testing.assert_array_equal(shown, table[:, column])


def test_track_says_where_a_joint_had_no_torque(setup, tmp_path, capsys):
    """A torque channel that reads 0 over the last rows (dead or unlogged) has no error
    percentage: the terminal and report.md give "-" and say why, never "nan"; the other
    joints keep their numbers."""
    _chain, prior, run, _ = setup
    log = {k: v.copy() for k, v in run.items()}
    log["tau"][int(0.7 * len(log["t"])) :, 1] = 0.0
    argv, out = _files(tmp_path, log, prior)
    capsys.readouterr()
    assert main(argv) == 0
    printed = capsys.readouterr().out
    report = (out / "report.md").read_text()
    for text in (printed, report):
        assert "nan" not in text.lower()
        assert "reads 0 over those rows" in text
    line = next(s for s in printed.splitlines() if s.startswith("one-step-ahead error"))
    cells = [c.strip() for c in line.split(":", 1)[1].split(",")]
    assert cells[1] == "-"
    assert all(float(c) > 0 for k, c in enumerate(cells) if k != 1)


def test_track_of_torques_that_all_read_zero_warns_nothing_but_its_own(tmp_path, setup, capsys):
    """Every torque 0 (no channel logged): from the prior, the prediction is the prior's
    and the figure's error panel is drawn without matplotlib's warnings on stderr, and the
    run says why nothing was learned; from no knowledge there is no model to write (it
    wrote zeros with exit 0), and nothing is written."""
    _chain, prior, run, _ = setup
    log = {k: v[:1000].copy() for k, v in run.items()}
    log["tau"][:] = 0.0
    argv, out = _files(tmp_path, log, prior, name="zero.csv")
    capsys.readouterr()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert main(argv) == 0
    printed = capsys.readouterr().out
    assert "reads 0" in printed
    assert "warning: no row updated the estimate" in printed
    assert (out / "track.png").stat().st_size > 0
    rel, _tip = ARMS["ur5"]
    bare = tmp_path / "bare"
    assert main(["track", argv[1], "--robot", str(ROBOTS / rel), "--out", str(bare)]) == 2
    assert "no joint's torque was measured" in capsys.readouterr().err
    assert not bare.exists()


def test_track_names_the_joints_at_the_noise_floor(setup, tmp_path, capsys):
    """A wrist whose torque sensor is far noisier than its torque (σ = 1 N·m added, known
    from the log's making) has a one-step-ahead error that is that noise: the summary names
    it with the noise it estimated (within 10 % of σ) and never names a joint whose error
    % is small."""
    chain, prior, run, _ = setup
    log = {k: v.copy() for k, v in run.items()}
    sigma, noisy = 1.0, chain.dof - 1
    log["tau"][:, noisy] += np.random.default_rng(7).normal(0.0, sigma, len(log["t"]))
    argv, _out = _files(tmp_path, log, prior)
    capsys.readouterr()
    assert main(argv) == 0
    lines = capsys.readouterr().out.splitlines()
    raw = next(s for s in lines if s.startswith("one-step-ahead error"))
    percent = np.array([float(c) for c in raw.split(":", 1)[1].split(",")])
    note = next((s for s in lines if s.startswith("at the noise floor")), "")
    name = chain.joint_names[noisy]
    assert f"{name} (noise " in note, note
    found = float(note.split(f"{name} (noise ", 1)[1].split()[0])
    assert abs(found / sigma - 1) < 0.1, found
    for j, joint in enumerate(chain.joint_names):
        if percent[j] < 25:
            assert f"{joint} (" not in note, (joint, note)
    assert (percent < 25).sum() >= 3, percent  # the test can fail on the last loop


def test_track_of_a_log_shorter_than_the_filtering_says_nothing_was_learned(
    setup, tmp_path, capsys
):
    """20 rows (0.08 s at 250 Hz): shorter than the causal filtering's settling and than
    the figure's 0.1 s error window (whose kernel used to outgrow the log and crash the
    figure). From the prior, the command completes, writes every file and says that no
    row updated the estimate (model.json predicts as the prior); from no knowledge it
    refuses, saying why, and writes nothing (it wrote a model of zeros with exit 0)."""
    _chain, prior, run, _ = setup
    short = {k: v[:20] for k, v in run.items()}
    argv, out = _files(tmp_path, short, prior, name="short.csv")
    capsys.readouterr()
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert "warning: no row updated the estimate" in printed
    assert (out / "track.png").is_file()
    model = prrrp.IdentifiedModel.load(out / "model.json")
    q, qd, qdd = run["q"][:50], run["qd"][:50], run["qdd"][:50]
    np.testing.assert_allclose(model.predict(q, qd, qdd), prior.predict(q, qd, qdd), atol=1e-9)
    rel, _tip = ARMS["ur5"]
    bare = tmp_path / "bare"
    assert main(["track", argv[1], "--robot", str(ROBOTS / rel), "--out", str(bare)]) == 2
    err = capsys.readouterr().err
    assert "no row updated the estimate: the log (0.076 s) ended before" in err
    assert "--model" in err
    assert not bare.exists()


def test_track_payload_of_a_run_without_one_says_so(setup, tmp_path, capsys):
    """`prrrp track --payload` on a run that carries nothing: payload.json does not call
    a centre of mass of a few grams determined (σ of decimetres; it used to flag every
    quantity identifiable), and the terminal says that no payload was detected."""
    _chain, prior, _run, _ = setup
    _chain2, model = _ur5()
    argv, out = _files(tmp_path, _log(model, model, 4, 10.0, None), prior)
    capsys.readouterr()
    assert main([*argv, "--payload"]) == 0
    printed = capsys.readouterr().out
    payload = json.loads((out / "payload.json").read_text())
    assert abs(payload["mass"]) <= 2 * payload["mass_sigma"] < 0.05 * PART["mass"]
    assert not any(payload["identifiable"]["com"])
    assert "no payload detected" in printed


def test_track_refuses_a_cutoff_or_memory_the_rows_cannot_carry(setup, tmp_path, capsys):
    """The log has a row every 4 ms (Nyquist 125 Hz): a --cutoff of 130 Hz would restart
    the causal filtering at every row and learn nothing (it ran to the end and wrote the
    starting model), and a 1 µs --forgetting forgets everything between two rows (it
    failed inside the estimator with "invalid value 0 for 'forgetting'"). Both are usage
    errors that name the rows' spacing, and nothing is written."""
    _chain, prior, run, _ = setup
    base, out = _files(tmp_path, run, prior)
    capsys.readouterr()
    assert main([*base, "--cutoff", "130"]) == 2
    assert "Nyquist frequency of the log's rows (125 Hz: a row every 0.004 s)" in (
        capsys.readouterr().err
    )
    assert main([*base, "--forgetting", "1e-6"]) == 2
    assert "forgets everything between two rows (a row every 0.004 s)" in capsys.readouterr().err
    assert not out.exists()
    # A cut-off that cannot settle within the 20 s log: 1e-300 Hz ran to the end.
    for cutoff in ["1e-300", "0.1"]:
        assert main([*base, "--cutoff", cutoff]) == 2
        assert "longer than the log (20 s)" in capsys.readouterr().err
    assert not out.exists()
    # The Nyquist frequency itself: the median step of k/100 s stamps is a hair under
    # 0.01 s, and a --cutoff of exactly 50 Hz passed.
    slow = {**run, "t": np.arange(len(run["t"])) / 100.0}
    base, out = _files(tmp_path, slow, prior, name="100hz.csv")
    assert main([*base, "--cutoff", "50"]) == 2
    assert "Nyquist frequency of the log's rows (50 Hz" in capsys.readouterr().err
    assert not out.exists()


def test_track_ekf_says_when_its_model_is_the_warm_ups(setup, tmp_path, capsys):
    """A 2 s log from no knowledge ends inside the ekf's warm-up (2 s of updates after the
    causal filtering settles): model.json is the warm-up's least-squares estimate, and the
    terminal and report.md say so instead of passing it for the filter's. An 8 s log
    (before the grip) starts the filter and says nothing of the kind."""
    _chain, _prior, run, _ = setup
    rel, _tip = ARMS["ur5"]
    for seconds, warm in [(2.0, True), (8.0, False)]:
        data = tmp_path / f"ur5_{seconds:g}.csv"
        _write_csv(data, {k: v[: int(seconds * RATE)] for k, v in run.items()})
        out = tmp_path / f"ekf_{seconds:g}"
        argv = ["track", str(data), "--robot", str(ROBOTS / rel), "--method", "ekf"]
        capsys.readouterr()
        assert main([*argv, "--out", str(out)]) == 0
        printed = capsys.readouterr().out
        running = prrrp.IdentifiedModel.load(out / "model.json").settings["ekf_running"]
        assert running is not warm
        said = "the ekf was not running at the end of the log"
        assert (said in printed) is warm
        assert (said in (out / "report.md").read_text()) is warm


def test_track_refuses_a_log_whose_rows_share_one_time_stamp(setup, tmp_path, capsys):
    """Every row at t = 0 (a clock that was not logged): `identify` refuses it; `track`
    treated every row as a repeat, learned nothing and exited 0 with the starting model."""
    _chain, prior, run, _ = setup
    log = {k: v[:500].copy() for k, v in run.items()}
    log["t"][:] = 0.0
    argv, out = _files(tmp_path, log, prior)
    capsys.readouterr()
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "every one of the log's 500 rows has the time stamp 0 s" in err
    assert not out.exists()


def test_track_names_the_joints_that_barely_move(setup, tmp_path, capsys):
    """The wrist held still but for encoder noise (1e-5 rad): its parameters are not
    determined, and the terminal and report.md say which joints to move; the others,
    which move by radians, are not named."""
    chain, prior, run, _ = setup
    log = {k: v.copy() for k, v in run.items()}
    still = chain.dof - 1
    log["q"][:, still] = 0.3 + np.random.default_rng(5).normal(0, 1e-5, len(log["t"]))
    argv, out = _files(tmp_path, log, prior)
    capsys.readouterr()
    assert main(argv) == 0
    printed = capsys.readouterr().out
    line = next(s for s in printed.splitlines() if "barely move" in s)
    names = chain.joint_names
    assert f"{names[still]} (spans " in line
    assert not any(f"{n} (spans" in line for n in names[:still])
    assert f"{names[still]} (spans " in (out / "report.md").read_text()
