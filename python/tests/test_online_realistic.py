"""`prrrp.OnlineIdentifier` on logs like a real arm's, against Pinocchio: the UR5 of
example-robot-data with every link perturbed as CAD models are off (`pinocchio_standin`),
viscous and Coulomb friction whose Coulomb term has a Stribeck bump the model lacks, torque
noise of 0.15–0.6 N·m (current-based joint torques), a 2 kg part gripped mid-run, or a
short torque spike the model cannot explain. Scored against Pinocchio's torques (with the
friction) of another motion, never against the identifier's own regressor.

On such logs the innovation test also fires on bursts of errors the model cannot explain;
an opening after each such alarm left the model 32 % off 3 s after a grip and 47 % off at
the end of a log (docs/design/online.md): the look after an alarm (`online/guard.rs`) keeps
an opening only when it predicts better.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from pinocchio_standin import ARMS, ROBOTS, _multisine, _torques, _true_model
from test_online import _write_csv

import prrrp
from prrrp.cli import main

RATE = 500.0
GRIP = 15.0
PART = pin.Inertia(2.0, np.array([0.01, -0.02, 0.06]), np.diag([4e-3, 4e-3, 3e-3]))
TAU_NOISE = np.array([0.6, 0.6, 0.4, 0.15, 0.15, 0.15])  # N·m


class Arm:
    """A perturbed UR5 (seeded) with friction, its chain and a log generator."""

    def __init__(self, seed: int, stribeck: float = 0.5):
        rng = np.random.default_rng(seed)
        rel, tip = ARMS["ur5"]
        self.path = str(ROBOTS / rel)
        self.chain = prrrp.SerialChain.from_urdf(self.path, tip=tip)
        self.n = self.chain.dof
        self.model = _true_model(self.path, list(self.chain.joint_names), rng)
        self.loaded = self.model.copy()
        last = self.model.njoints - 1
        self.loaded.inertias[last] = self.loaded.inertias[last] + PART
        n = self.n
        self.fv, self.fc = rng.uniform(0.5, 3, n), rng.uniform(1, 6, n)
        self.fo = rng.normal(0, 0.5, n)
        # Static friction above the Coulomb level, fading within 0.05 rad/s: not in the
        # model's friction terms.
        self.fs = stribeck * 0.5 * self.fc
        self.seed = seed

    def friction(self, qd: np.ndarray) -> np.ndarray:
        coulomb = self.fc + self.fs * np.exp(-((qd / 0.05) ** 2))
        return self.fv * qd + coulomb * np.tanh(qd / 0.02) + self.fo

    def log(self, seed: int, seconds: float, grip: float | None) -> dict[str, np.ndarray]:
        """t, noisy q and τ, exact q̇, q̈ and τ; the part gripped from `grip` s."""
        rng = np.random.default_rng(1000 * self.seed + seed)
        n = self.n
        t, q, qd, qdd = _multisine(rng, n, seconds, RATE, np.full(n, 0.8), f0=0.1)
        tau = _torques(self.model, q, qd, qdd)
        if grip is not None:
            after = t >= grip
            tau[after] = _torques(self.loaded, q[after], qd[after], qdd[after])
        tau = tau + self.friction(qd)
        return {
            "t": t,
            "q": q + rng.normal(0, 1e-5, q.shape),
            "qd": qd,
            "qdd": qdd,
            "tau": tau + rng.normal(0, 1, tau.shape) * TAU_NOISE,
            "exact": tau,
        }

    def prior(self) -> prrrp.IdentifiedModel:
        """The bare arm identified (wls) from 30 s of its own log, as `prrrp identify`."""
        un = self.log(1, 30.0, None)
        robot = prrrp.workflow.load_robot(self.path, friction="viscous+coulomb+offset")
        return prrrp.identify_measurements(robot, un, "wls").model


def _error(model: prrrp.IdentifiedModel, val: dict[str, np.ndarray]) -> np.ndarray:
    """Per joint: RMS torque error on `val` against the exact torques, % of their RMS."""
    pred = np.asarray(model.predict(val["q"], val["qd"], val["qdd"]))
    ref = val["exact"]
    return 100 * np.sqrt(np.mean((pred - ref) ** 2, axis=0) / np.mean(ref**2, axis=0))


def _track(online: prrrp.OnlineIdentifier, run: dict[str, np.ndarray], at: float):
    """Feeds `run`; the estimate at `at` s and at the end, and the reported changes."""
    then, changes = None, []
    for k in range(len(run["t"])):
        out = online.update(run["t"][k], run["q"][k], run["tau"][k])
        if out["change"]:
            changes.append(run["t"][k])
        if then is None and run["t"][k] >= at:
            then = online.estimate()
    return then, online.estimate(), changes


@pytest.fixture(scope="module")
def arm():
    a = Arm(2)
    return a, a.prior()


@pytest.mark.parametrize("method", ["rls", "ekf"])
def test_whole_arm_follows_a_grip_on_a_realistic_log(arm, method):
    """From the bare arm's prior: 3 s after the grip within 15 % of each joint's RMS
    torque on another loaded motion, at the end within 3 %. Before the look, a false alarm
    at 12.7 s made the grip open every direction (RLS 19 % 3 s after on this arm, the EKF
    29 %; the EKF ended 21 % off after repeated restarts). Arms 0–7 now: 3 s after
    2.1–11.5 % (rls), 1.8–17.0 % (ekf; 3.4 % on this arm); at the end 1.9–2.6 % and
    1.7–2.5 %."""
    a, prior = arm
    run = a.log(2, 30.0, GRIP)
    val = a.log(3, 10.0, 0.0)
    online = prrrp.OnlineIdentifier(prior=prior, method=method)
    after3, end, changes = _track(online, run, GRIP + 3.0)
    assert any(GRIP <= c < GRIP + 1.0 for c in changes), changes
    assert np.all(_error(after3, val) < 15.0), _error(after3, val)
    assert np.all(_error(end, val) < 3.0), _error(end, val)


def test_the_alarm_after_a_confirmed_grip_opens_along_the_tip(arm):
    """A grip confirmed along the tip link is followed at once by a second alarm: the
    detector's fast mean still holds the errors of the estimator that waited through the
    look. That alarm opens along the tip again, not every direction, so what the data say
    of the rest of the arm is kept: the σ of joint 1's friction parameters (which a
    payload does not move) stay within 3× their value before the grip (its changes are
    the errors' correlation factor κ) while the model re-converges. Every direction was
    opened before: σ × 28–50 on arms 0–4, and the worst joint 3 s after the grip 7.7 %
    off (median over arms 0–7 and four logs each) instead of 3.1 %."""
    a, prior = arm
    run = a.log(2, 30.0, GRIP)
    online = prrrp.OnlineIdentifier(prior=prior, method="rls")
    names = list(online.parameter_names)
    friction = [names.index(f"{p}1") for p in ("fv", "fc", "fo")]
    changes, before, peak = [], None, 0.0
    for k in range(len(run["t"])):
        out = online.update(run["t"][k], run["q"][k], run["tau"][k])
        changes += [run["t"][k]] if out["change"] else []
        sigma = np.asarray(out["sigma"])[friction]
        if run["t"][k] < GRIP:
            before = sigma
        elif run["t"][k] < GRIP + 3.0:
            peak = max(peak, float(np.max(sigma / before)))
    # The grip and the re-opening after it, both confirmed.
    assert len([c for c in changes if GRIP <= c < GRIP + 1.5]) == 2, changes
    assert peak < 3.0, peak


@pytest.mark.parametrize("before_end", [0.2, 1.0])
def test_a_torque_spike_near_the_end_leaves_the_model_as_it_was(arm, before_end):
    """A 2 N·m spike on every joint (60 ms wide) shortly before the end of a log without a
    change: no change is reported (a look that ended dropped the opening), and the model at
    the end predicts another motion as well as without the spike. The spike 0.2 s before
    the end left the UR5 of test_online.py 410 % off on the wrist when every alarm opened
    the covariance, and 23 % when the estimator took the spike's rows in while the look was
    pending."""
    a, prior = arm
    run = a.log(4, 20.0, None)
    val = a.log(5, 10.0, None)
    t = run["t"]
    spiked = dict(run)
    sign = np.random.default_rng(7).choice([-1.0, 1.0], a.n)
    bump = np.exp(-(((t - (t[-1] - before_end)) / 0.03) ** 2))
    spiked["tau"] = run["tau"] + 2.0 * sign * bump[:, None]
    models = []
    for log in (run, spiked):
        online = prrrp.OnlineIdentifier(prior=prior, method="rls")
        _, end, changes = _track(online, log, np.inf)
        assert changes == []
        models.append(end)
    if before_end > 0.5:  # the look (0.5 s) ended before the log
        assert online.dropped_alarms >= 1
    clean, after = _error(models[0], val), _error(models[1], val)
    assert np.all(after <= 1.1 * clean + 0.05), (clean, after)


def test_from_no_knowledge_the_coulomb_scale_is_the_robots(arm):
    """From no knowledge the identifier fits the friction law of the robot it is given:
    on this arm, whose Coulomb friction turns over within ~0.02 rad/s, the robot with
    that speed scale is identified better than one with the exact sign (`prrrp identify`
    chooses the scale by cross-validation). `coulomb_scale="auto"` chooses it online
    from the robot with the exact sign: a neighbour of 0.02 among its candidates, and
    as good as the matched robot. Measured: 8.3 % (exact sign), 3.4 % (0.02), 2.6 %
    (auto, 0.016; 3.2 % with 0.01, the choice among candidates half a decade apart) on
    the worst joint."""
    a, _prior = arm
    run = a.log(2, 30.0, None)
    val = a.log(3, 10.0, None)
    robot = prrrp.workflow.load_robot(a.path, friction="viscous+coulomb+offset")
    worst = []
    for v_s in (0.0, 0.02):
        online = prrrp.OnlineIdentifier(
            prrrp.workflow.with_coulomb_scale(robot, v_s), change_detection=False
        )
        _, end, _ = _track(online, run, np.inf)
        assert end.robot.coulomb_smoothing == v_s
        worst.append(_error(end, val).max())
    assert worst[1] < 0.6 * worst[0], worst
    online = prrrp.OnlineIdentifier(robot, change_detection=False, coulomb_scale="auto")
    _, end, _ = _track(online, run, np.inf)
    search = online.settings["coulomb_search"]
    chosen = search["chosen"]
    below = max(c for c in search["candidates"] if c <= 0.02)
    above = min(c for c in search["candidates"] if c >= 0.02)
    assert chosen in (below, above), search
    assert end.robot.coulomb_smoothing == chosen
    assert _error(end, val).max() < 1.2 * worst[1], (_error(end, val), worst)


class _TanhArm(Arm):
    """The stand-in with Coulomb friction fc·tanh(q̇/v_s) of a given v_s and no Stribeck
    bump."""

    def __init__(self, seed: int, v_s: float):
        super().__init__(seed, stribeck=0.0)
        self.v_s = v_s

    def friction(self, qd: np.ndarray) -> np.ndarray:
        return self.fv * qd + self.fc * np.tanh(qd / self.v_s) + self.fo


@pytest.mark.parametrize("v_s", [0.001, 0.08])
def test_the_online_coulomb_scale_is_the_best_candidate(v_s):
    """On arms whose friction turns over within 0.001 or 0.08 rad/s (neither a
    candidate), the online choice is the candidate whose identifier ends nearest the arm
    (bare arm, 30 s, from no knowledge). Measured on arms 0–2: 0.003 and 0.1 were chosen
    and best every time; with the exact sign the 0.08 arms ended 17–22 % off, with the
    choice 3.2–3.5 %."""
    a = _TanhArm(1, v_s)
    run = a.log(2, 30.0, None)
    val = a.log(3, 10.0, None)
    robot = prrrp.workflow.load_robot(a.path, friction="viscous+coulomb+offset")
    online = prrrp.OnlineIdentifier(robot, change_detection=False, coulomb_scale="auto")
    _, end, _ = _track(online, run, np.inf)
    search = online.settings["coulomb_search"]
    worst = {}
    for c in search["candidates"]:
        fixed = prrrp.OnlineIdentifier(
            prrrp.workflow.with_coulomb_scale(robot, c), change_detection=False
        )
        worst[c] = _error(_track(fixed, run, np.inf)[1], val).max()
    assert search["chosen"] == min(worst, key=worst.get), (search, worst)
    assert _error(end, val).max() == pytest.approx(worst[search["chosen"]], rel=1e-9)


def test_the_online_coulomb_scale_choice_needs_no_prior_and_a_known_word(arm):
    """`coulomb_scale` is "auto" or None; a prior carries its own scale."""
    a, prior = arm
    robot = prrrp.workflow.load_robot(a.path, friction="viscous+coulomb+offset")
    with pytest.raises(prrrp.InvalidParameterError, match="auto"):
        prrrp.OnlineIdentifier(robot, coulomb_scale="best")
    with pytest.raises(prrrp.InvalidParameterError, match="prior"):
        prrrp.OnlineIdentifier(prior=prior, coulomb_scale="auto")


def test_track_takes_the_coulomb_scale_of_the_robot(arm, tmp_path):
    """`prrrp track --robot R --coulomb-scale V`: the model it writes has V; a negative
    V, or V beside --model (which carries its own), is a usage error."""
    a, prior = arm
    run = a.log(2, 4.0, None)
    data = tmp_path / "run.csv"
    _write_csv(data, run)
    out = tmp_path / "track"
    base = ["track", str(data), "--robot", a.path, "--tip", ARMS["ur5"][1]]
    assert main([*base, "--coulomb-scale", "0.02", "--out", str(out)]) == 0
    assert prrrp.IdentifiedModel.load(out / "model.json").robot.coulomb_smoothing == 0.02
    assert main([*base, "--coulomb-scale", "-1", "--out", str(tmp_path / "x")]) == 2
    assert main([*base, "--coulomb-scale", "best", "--out", str(tmp_path / "x")]) == 2
    # The default is the online choice, made 10 s after the first row: this 4 s log
    # ends before it, and the report says so.
    auto = tmp_path / "auto"
    assert main([*base, "--out", str(auto)]) == 0
    assert prrrp.IdentifiedModel.load(auto / "model.json").robot.coulomb_smoothing == 0.0
    assert "the log ended before the choice" in (auto / "report.md").read_text()
    prior_path = tmp_path / "prior.json"
    prior.save(prior_path)
    bad = ["track", str(data), "--model", str(prior_path), "--coulomb-scale", "0.02"]
    assert main([*bad, "--out", str(tmp_path / "y")]) == 2


@pytest.mark.parametrize("method", ["rls", "ekf"])
def test_payload_sigma_covers_the_centre_of_mass_on_a_realistic_log(arm, method):
    """The centre of mass of the test below within 3 σ of its own σ on each axis at the
    end, although the prior's friction misses the Stribeck bump (a bias σ does not
    know). Measured on arms 0–7: at most 2.7 σ (rls and ekf; 0.4–4.9 mm off). Before a
    re-converging estimator took its unopened copy's rows (docs/design/online.md), the
    payload EKF's centre on this arm was 3.2 σ off (3.0 mm, σ 0.93 mm)."""
    a, prior = arm
    run = a.log(2, 30.0, GRIP)
    online = prrrp.OnlineIdentifier(prior=prior, method=method, payload=True)
    for k in range(len(run["t"])):
        online.update(run["t"][k], run["q"][k], run["tau"][k])
    end = online.payload()
    err = np.asarray(end["com"]) - PART.lever
    assert np.all(np.abs(err) < 3.0 * np.asarray(end["com_sigma"])), (err, end["com_sigma"])


@pytest.mark.parametrize("method", ["rls", "ekf"])
def test_payload_mode_weighs_the_part_on_a_realistic_log(arm, method):
    """Payload mode on the bare arm's prior: the 2 kg part's mass within 5 % 3 s after the
    grip and at the end (the issue's bar), its centre of mass (tip frame) within 1 cm at
    the end, although the prior's friction misses the Stribeck bump and the torques are
    noisy. Measured on arms 0–7 (rls and ekf): mass within 2.3 % 3 s after and 0.3 % at
    the end; centre 0.3–5.1 mm off."""
    a, prior = arm
    run = a.log(2, 30.0, GRIP)
    online = prrrp.OnlineIdentifier(prior=prior, method=method, payload=True)
    after3 = None
    for k in range(len(run["t"])):
        online.update(run["t"][k], run["q"][k], run["tau"][k])
        if after3 is None and run["t"][k] >= GRIP + 3.0:
            after3 = online.payload()
    end = online.payload()
    for p in (after3, end):
        assert abs(p["mass"] / PART.mass - 1) < 0.05, p["mass"]
    err = np.asarray(end["com"]) - PART.lever
    assert np.linalg.norm(err) < 0.01, end["com"]
