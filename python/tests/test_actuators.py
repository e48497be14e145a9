"""Geared arms (issue 26): rotor inertias (armature), coupled actuators and friction on the
actuator velocities, checked against an independent computation — Pinocchio's rigid-body
dynamics (`pin.rnea`, `pin.aba`, its `model.armature`) on the UR5 and Panda of
`example-robot-data`, with the actuator terms Cᵀ·(Ia∘(C·q̈) + f(C·q̇)) written out in numpy.

The stand-in for a real geared arm with a coupled wrist (the Stäubli TX40's sixth motor
turns with q5 + q6): the UR5's links, rotor inertias of an industrial arm's size
(0.4–1.6 kg·m² on the shoulders, 0.03–0.08 on the wrist, joint side) and friction on the
motor velocities, measured with torque noise. Identified with the actuator model (a TOML
file as a user writes it) the held-out error is the noise; identified as a rigid arm with
joint friction it is not, and a fake Coulomb term appears on joint 5.
"""

from __future__ import annotations

import importlib.metadata
from pathlib import Path

import numpy as np
import pytest
from conftest import pin_configuration

import prrrp
from prrrp.cli import main

pin = pytest.importorskip("pinocchio")

ROBOTS = importlib.metadata.distribution("example-robot-data").locate_file(
    "cmeel.prefix/share/example-robot-data/robots"
)
UR5 = str(ROBOTS / "ur_description/urdf/ur5_robot.urdf")
PANDA = str(ROBOTS / "panda_description/urdf/panda.urdf")

# The coupled wrist: motor 6 turns with q̇5 + q̇6.
COUPLING = np.eye(6)
COUPLING[5, 4] = 1.0
ARMATURE = np.array([1.6, 1.4, 0.4, 0.08, 0.05, 0.03])  # kg·m², joint side
FV = np.array([6.0, 5.0, 2.5, 0.6, 0.5, 0.4])  # N·m·s/rad, on the motor velocities
FC = np.array([5.0, 4.5, 2.5, 1.2, 0.6, 1.0])  # N·m
FO = np.array([0.4, -0.5, 0.3, 0.05, -0.06, 0.04])  # N·m
V_S = 0.02  # rad/s, the true Coulomb speed scale
TAU_NOISE = np.array([0.4, 0.4, 0.3, 0.06, 0.06, 0.06])  # N·m


def pin_model(path: str, locked: tuple[str, ...] = ()) -> object:
    model = pin.buildModelFromUrdf(path)
    if locked:
        ids = [model.getJointId(j) for j in locked]
        model = pin.buildReducedModel(model, ids, pin.neutral(model))
    return model


def multisine(seed: int, duration: float, rate: float, amplitude: np.ndarray):
    """t, q, q̇, q̈ of a sum of five harmonics per joint (exact derivatives)."""
    rng = np.random.default_rng(seed)
    n = len(amplitude)
    t = np.arange(0.0, duration, 1.0 / rate)
    w = 2 * np.pi * rng.uniform(0.08, 0.12) * np.arange(1, 6)
    a = rng.uniform(-1, 1, (n, 5)) / np.arange(1, 6)
    a *= (amplitude / np.abs(a).sum(axis=1))[:, None]
    ph = rng.uniform(0, 2 * np.pi, (n, 5))
    arg = t[:, None, None] * w[None, None, :] + ph[None]
    q = (a * np.sin(arg)).sum(axis=2)
    qd = (a * w * np.cos(arg)).sum(axis=2)
    qdd = -(a * w**2 * np.sin(arg)).sum(axis=2)
    return t, q, qd, qdd


def actuator_torques(c, ia, fv, fc, fo, v_s, qd, qdd):
    """Cᵀ·(Ia∘(C·q̈) + fv∘(C·q̇) + fc∘tanh(C·q̇/v_s) + fo), per sample (numpy)."""
    vm, am = qd @ c.T, qdd @ c.T
    tm = ia * am + fv * vm + fc * np.tanh(vm / v_s) + fo
    return tm @ c


def pin_torques(model: object, q, qd, qdd) -> np.ndarray:
    data = model.createData()
    return np.array(
        [
            pin.rnea(model, data, pin_configuration(model, a), b, c).copy()
            for a, b, c in zip(q, qd, qdd, strict=True)
        ]
    )


def geared_log(seed: int, duration: float = 24.0, rate: float = 100.0):
    """The UR5 with the coupled, geared wrist: exact states, noisy measured torques."""
    model = pin_model(UR5)
    t, q, qd, qdd = multisine(seed, duration, rate, np.array([2.0, 1.2, 1.5, 2.0, 2.0, 2.5]))
    tau = pin_torques(model, q, qd, qdd) + actuator_torques(
        COUPLING, ARMATURE, FV, FC, FO, V_S, qd, qdd
    )
    rng = np.random.default_rng(1000 + seed)
    measured = tau + rng.normal(0.0, 1.0, tau.shape) * TAU_NOISE
    return t, q, qd, qdd, measured


def geared_toml(tmp_path: Path, extra: str = "", name: str = "ur5_geared") -> Path:
    rows = ", ".join("[" + ", ".join(f"{x:g}" for x in r) + "]" for r in COUPLING)
    path = tmp_path / f"{name}.toml"
    path.write_text(
        f'name = "ur5-geared"\nurdf = "{UR5}"\n[actuators]\narmature = true\n'
        f"coupling = [{rows}]\n{extra}",
        encoding="utf-8",
    )
    return path


def held_out_rms(model, log) -> np.ndarray:
    _, q, qd, qdd, measured = log
    return np.sqrt(np.mean((np.asarray(model.predict(q, qd, qdd)) - measured) ** 2, axis=0))


def beta_of(model, name: str) -> float:
    return float(model.beta[list(model.base_names).index(name)])


# ------------------------------------------------------------------------------ Pinocchio


def test_armature_equals_pinocchio_model_armature():
    """C = I: inverse dynamics, mass matrix, forward dynamics and an open-loop simulation
    of the UR5 with rotor inertias equal Pinocchio's with `model.armature` set."""
    model = pin_model(UR5)
    ia = np.array([0.9, 1.1, 0.5, 0.06, 0.05, 0.04])
    model.armature = ia
    data = model.createData()
    chain = prrrp.SerialChain.from_urdf(UR5).with_actuators(armature=True, armature_values=ia)
    rng = np.random.default_rng(4)
    q, qd, qdd = rng.uniform(-2, 2, (3, 30, 6))
    tau = chain.inverse_dynamics(q, qd, qdd)
    masses = chain.mass_matrix(q)
    for k in range(30):
        qp = pin_configuration(model, q[k])
        want = pin.rnea(model, data, qp, qd[k], qdd[k])
        assert np.allclose(tau[k], want, rtol=1e-10, atol=1e-10 * np.abs(want).max())
        m = pin.crba(model, data, qp)
        m = np.triu(m) + np.triu(m, 1).T
        assert np.allclose(masses[k], m, rtol=1e-10, atol=1e-12)
        a = pin.aba(model, data, qp, qd[k], tau[k])
        assert np.allclose(a, qdd[k], rtol=1e-8, atol=1e-8)

    # Open loop, zero-order-hold torques, RK4 with the same steps: the trajectories agree.
    rate, substeps, steps = 100.0, 10, 150
    torques = 3.0 * np.sin(np.outer(np.arange(steps) / rate, [1.0, 1.3, 1.7, 2.1, 2.6, 3.1]))
    torques += np.array(chain.gravity_torques(np.zeros(6)))
    q0, qd0 = np.array([0.1, -1.2, 1.0, -0.5, 0.4, 0.2]), np.zeros(6)
    sim = prrrp.simulate_chain_open_loop(chain, q0, qd0, torques, rate=rate, substeps=substeps)
    h = 1.0 / (rate * substeps)

    def f(x, u):
        qq, vv = x[:6], x[6:]
        return np.concatenate([vv, pin.aba(model, data, pin_configuration(model, qq), vv, u)])

    x = np.concatenate([q0, qd0])
    ours = np.asarray(sim.q)
    worst = 0.0
    for k in range(steps):
        worst = max(worst, np.abs(ours[k] - x[:6]).max())
        for _ in range(substeps):
            k1 = f(x, torques[k])
            k2 = f(x + 0.5 * h * k1, torques[k])
            k3 = f(x + 0.5 * h * k2, torques[k])
            k4 = f(x + h * k3, torques[k])
            x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    assert worst < 1e-9, f"largest joint-angle difference {worst:.3g} rad"
    assert np.ptp(ours, axis=0).min() > 0.05, "the arm moved"


def test_armature_and_coupling_match_pinocchio_plus_actuator_terms():
    """The coupled wrist: prrrp's inverse dynamics = pin.rnea + Cᵀ·(Ia∘C·q̈ + f(C·q̇))."""
    chain = (
        prrrp.SerialChain.from_urdf(UR5)
        .with_friction(
            "viscous+coulomb+offset", np.column_stack([FV, FC, FO]), coulomb_smoothing=V_S
        )
        .with_actuators(coupling=COUPLING, armature=True, armature_values=ARMATURE)
    )
    rng = np.random.default_rng(5)
    q, qd, qdd = rng.uniform(-2, 2, (3, 40, 6))
    want = pin_torques(pin_model(UR5), q, qd, qdd) + actuator_torques(
        COUPLING, ARMATURE, FV, FC, FO, V_S, qd, qdd
    )
    got = chain.inverse_dynamics(q, qd, qdd)
    assert np.abs(got - want).max() < 1e-9 * np.abs(want).max()
    # The regressor times the parameters is the same torque.
    y = chain.regressor(q, qd, qdd)
    assert np.abs(y @ chain.parameters - want).max() < 1e-9 * np.abs(want).max()


# ----------------------------------------------------------------- the coupled-wrist stand-in


@pytest.fixture(scope="module")
def geared(tmp_path_factory):
    """The stand-in's identification and held-out logs and both identifications."""
    tmp = tmp_path_factory.mktemp("geared")
    train, test = geared_log(seed=1), geared_log(seed=2)
    data = prrrp.Dataset(*train)
    terms = "viscous+coulomb+offset"
    with_model = prrrp.identify_measurements(
        prrrp.load_robot(geared_toml(tmp), friction=terms), data
    ).model
    rigid = prrrp.identify_measurements(prrrp.load_robot(UR5, friction=terms), data).model
    return {"train": train, "test": test, "with": with_model, "rigid": rigid, "tmp": tmp}


def test_actuator_model_reaches_the_noise_on_held_out_data(geared):
    rms = held_out_rms(geared["with"], geared["test"])
    print("held-out RMS with the actuator model (N·m):", np.round(rms, 4))
    print("noise:", TAU_NOISE)
    # The noise itself is the floor; a few % above it is the estimate's own error.
    assert np.all(rms < 1.05 * TAU_NOISE), rms / TAU_NOISE


def test_rigid_model_fails_on_the_coupled_wrist(geared):
    """Without rotor inertias and coupling the wrist's error stays far above the noise, and
    the wrist's Coulomb friction lands on the wrong joints; with the actuator model every
    motor's friction is recovered (no fake Coulomb term)."""
    rms_with = held_out_rms(geared["with"], geared["test"])
    rms_rigid = held_out_rms(geared["rigid"], geared["test"])
    print("held-out RMS as a rigid arm (N·m):", np.round(rms_rigid, 4))
    assert np.all(rms_rigid[3:] > 2.0 * rms_with[3:]), rms_rigid / rms_with
    model = geared["with"]
    sigma = dict(zip(model.base_names, model.sigma, strict=True))
    for k in range(1, 7):
        for term, truth in (("fv", FV), ("fc", FC)):
            name = f"{term}{k}"
            err = abs(beta_of(model, name) - truth[k - 1])
            assert err < max(4 * sigma[name], 0.02 * truth[k - 1]), (name, err, sigma[name])
    fc_rigid = np.array([beta_of(geared["rigid"], f"fc{k}") for k in (5, 6)])
    print("wrist fc: truth", FC[4:], "as a rigid arm", np.round(fc_rigid, 3))
    assert np.abs(fc_rigid - FC[4:]).max() > 0.3


def test_friction_figure_points_per_actuator(geared):
    """With a coupling the friction figure's points are per actuator: C·q̇ and
    C⁻ᵀ·(τ − τ̂_rigid), the same as predicting with the friction zeroed."""
    from test_figures import rigid_points

    model = geared["with"]
    grid = prrrp.model_report.as_grid(prrrp.Dataset(*geared["test"]), model)
    qd, points = prrrp.model_report.friction_points(model, grid)
    want_qd, want = rigid_points(model, grid)
    assert np.allclose(qd, want_qd, rtol=0, atol=1e-12 * np.abs(want_qd).max())
    assert np.abs(points - want).max() < 1e-9 * np.abs(want).max()


def test_identified_rotor_inertias_and_report(geared):
    """Ia3..Ia6 are base parameters on their own and come out near the truth with σ; Ia1
    (fixed axis) and Ia2 (axis perpendicular to it) join their links' inertia."""
    model = geared["with"]
    acts = {a["actuator"]: {t["name"]: t for t in a["terms"]} for a in model.actuators}
    for k in (3, 4, 5, 6):
        t = acts[k][f"Ia{k}"]
        assert t["alone"]
        assert t["sigma"] is not None
        assert abs(t["value"] - ARMATURE[k - 1]) < max(5 * t["sigma"], 0.02 * ARMATURE[k - 1])
    for k in (1, 2):
        t = acts[k][f"Ia{k}"]
        assert not t["alone"]
        assert "I" in t["combination"]
    assert model.actuators[5]["joints"] == ["wrist_2_joint", "wrist_3_joint"]
    text = model.to_json()
    assert '"schema_version": 2' in text
    assert '"Ia6"' in text
    back = prrrp.IdentifiedModel.from_json(text)
    _, q, qd, qdd, _ = geared["test"]
    assert np.array_equal(
        back.predict(q[:50], qd[:50], qdd[:50]), model.predict(q[:50], qd[:50], qdd[:50])
    )
    out = geared["tmp"] / "report"
    out.mkdir()
    prrrp.model_report.write_report(model, out, prrrp.Dataset(*geared_log(seed=1, duration=4.0)))
    report = (out / "report.md").read_text()
    assert "## Actuators" in report
    assert "| 6 | wrist_2_joint, wrist_3_joint | Ia6 |" in report


def test_physical_method_keeps_rotor_inertias_physical(geared):
    """The physically consistent method on the stand-in: rotor inertias ≥ 0, every link a
    rigid body, and (the truth being physical) the held-out error of least squares."""
    data = prrrp.Dataset(*geared["train"])
    robot = prrrp.load_robot(geared_toml(geared["tmp"]), friction="viscous+coulomb+offset")
    model = prrrp.identify_measurements(robot, data, "physical", coulomb_scale=V_S).model
    names = list(robot.parameter_names)
    pi = np.asarray(model.standard_parameters)
    ia = np.array([pi[names.index(f"Ia{k}")] for k in range(1, 7)])
    assert np.all(ia >= 0), ia
    assert robot.feasibility(pi)["consistent"]
    rms = held_out_rms(model, geared["test"])
    assert np.all(rms < 1.05 * TAU_NOISE), rms / TAU_NOISE


# --------------------------------------------------------------------- C = I: does not hurt


@pytest.mark.parametrize(
    ("path", "tip", "locked"),
    [(UR5, None, ()), (PANDA, "panda_link8", ("panda_finger_joint1", "panda_finger_joint2"))],
)
def test_armature_columns_do_not_hurt_an_ungeared_arm(path, tip, locked):
    """Data of an arm without rotor inertias (joint friction only): identifying with one
    armature per joint predicts held-out data as well as without."""
    model = pin_model(path, locked)
    n = model.nv
    fv, fc = np.full(n, 0.8), np.full(n, 0.6)

    def log(seed):
        t, q, qd, qdd = multisine(seed, 20.0, 100.0, np.full(n, 1.5))
        tau = pin_torques(model, q, qd, qdd) + fv * qd + fc * np.tanh(qd / V_S)
        noise = np.random.default_rng(seed + 50).normal(0.0, 0.05, tau.shape)
        return t, q, qd, qdd, tau + noise

    train, test = log(11), log(12)
    terms = "viscous+coulomb+offset"
    plain = prrrp.load_robot(path, tip=tip, friction=terms)
    geared = prrrp.load_robot(path, tip=tip, friction=terms, armature=True)
    data = prrrp.Dataset(*train)
    a = held_out_rms(prrrp.identify_measurements(plain, data).model, test)
    b = held_out_rms(prrrp.identify_measurements(geared, data).model, test)
    print("held-out RMS without / with armature:", np.round(a, 4), np.round(b, 4))
    assert np.all(b <= 1.02 * a + 1e-4), b / a


# ------------------------------------------------------------------------ logs of geared arms


def _write_csv(path: Path, t, q, cols: dict[str, np.ndarray]) -> None:
    n = q.shape[1]
    names = ["t", *(f"q{j}" for j in range(1, n + 1))]
    blocks = [t[:, None], q]
    for prefix, values in cols.items():
        names += [f"{prefix}{j}" for j in range(1, n + 1)]
        blocks.append(values)
    prrrp.csvio.write_text_atomic(path, prrrp.csvio.format_table(names, np.hstack(blocks)))


RATIOS = np.array([101.0, 101.0, 101.0, 81.0, 81.0, 51.0])
GAINS = np.array([9.0, 9.0, 7.0, 2.0, 2.0, 1.5])  # N·m/A, joint side


def ratios_toml(tmp: Path) -> Path:
    ratio_line = "gear_ratios = [" + ", ".join(f"{r:g}" for r in RATIOS) + "]\n"
    return geared_toml(tmp, ratio_line, name="ur5_ratios")


def motor_log(log, path: Path, accelerations: bool = True) -> None:
    """`log` as the drives record it: motor angles (and rates) and motor currents."""
    t, q, qd, qdd, tau = log
    # τ = Cᵀ·(K∘i)  ⇒  i = C⁻ᵀ·τ / K.
    current = np.linalg.solve(COUPLING.T, tau.T).T / GAINS
    cols = {"qd": (qd @ COUPLING.T) * RATIOS}
    if accelerations:
        cols["qdd"] = (qdd @ COUPLING.T) * RATIOS
    _write_csv(path, t, (q @ COUPLING.T) * RATIOS, {**cols, "i": current})


def test_current_and_motor_side_logs_through_the_command_line(geared, capsys):
    """A log of motor currents i1..i6 and motor-side angles, with --drive-gains and
    --motor-side, identifies the same arm; predict converts a new log the same way."""
    tmp = geared["tmp"]
    ratios, gains = RATIOS, GAINS
    toml = ratios_toml(tmp)

    motor_log(geared_log(seed=1, duration=16.0), tmp / "train.csv")
    motor_log(geared["test"], tmp / "val.csv")
    gains_arg = ",".join(f"{g:g}" for g in gains)
    base = ["identify", str(tmp / "train.csv"), "--robot", str(toml)]
    # Currents without gains, motor-side data without ratios: one-line errors.
    assert main([*base, "--out", str(tmp / "x")]) == 2
    assert "--drive-gains" in capsys.readouterr().err
    # The UR5's URDF states a reduction of 1 on every joint, a placeholder: no gear ratios.
    assert prrrp.SerialChain.from_urdf(UR5).actuators["gear_ratios"] is None
    plain = geared_toml(tmp)
    assert (
        main(
            [
                "identify",
                str(tmp / "train.csv"),
                "--robot",
                str(plain),
                "--motor-side",
                "--drive-gains",
                gains_arg,
                "--out",
                str(tmp / "x"),
            ]
        )
        == 2
    )
    assert "gear_ratios" in capsys.readouterr().err
    out = tmp / "cli"
    code = main(
        [
            *base,
            "--drive-gains",
            gains_arg,
            "--motor-side",
            "--validate",
            str(tmp / "val.csv"),
            "--out",
            str(out),
        ]
    )
    assert code == 0, capsys.readouterr().err
    model = prrrp.IdentifiedModel.load(out / "model.json")
    assert model.preprocessing["drives"]["motor_side"] is True
    rms = held_out_rms(model, geared["test"])
    assert np.all(rms < 1.05 * TAU_NOISE), rms / TAU_NOISE
    assert (
        main(
            [
                "predict",
                str(out / "model.json"),
                str(tmp / "val.csv"),
                "--out",
                str(tmp / "tau.csv"),
            ]
        )
        == 0
    )
    printed = capsys.readouterr().out
    assert "torque-prediction error per joint" in printed
    # t, tau1..tauN, edge: the log has q̇ and q̈, so no row is in a filter transient.
    table = np.loadtxt(tmp / "tau.csv", delimiter=",", skiprows=1)
    predicted, edge = table[:, 1:-1], table[:, -1]
    assert not edge.any()
    _, q, qd, qdd, _ = geared["test"]
    assert np.allclose(predicted, model.predict(q, qd, qdd), rtol=1e-9, atol=1e-9)
    # A raw recording: motor angles and currents only. predict differentiates it itself
    # and writes a row per input row; away from the filter's edges its torques score
    # against the measured torque (currents × gains, joint side) at the noise level.
    t, q, _, _, tau = geared["test"]
    current = np.linalg.solve(COUPLING.T, tau.T).T / gains
    _write_csv(tmp / "raw.csv", t, (q @ COUPLING.T) * ratios, {"i": current})
    code = main(
        [
            "predict",
            str(out / "model.json"),
            str(tmp / "raw.csv"),
            "--out",
            str(tmp / "raw-tau.csv"),
        ]
    )
    assert code == 0, capsys.readouterr().err
    capsys.readouterr()
    table = np.loadtxt(tmp / "raw-tau.csv", delimiter=",", skiprows=1)
    assert table.shape[0] == len(t)
    assert np.allclose(table[:, 0], t)
    inner = table[:, -1] == 0
    assert inner.sum() > 0.8 * len(t)
    rms = np.sqrt(np.mean((table[inner, 1:-1] - tau[inner]) ** 2, axis=0))
    assert np.all(rms < 1.5 * TAU_NOISE), rms / TAU_NOISE


def test_track_reads_current_and_motor_side_logs(geared, capsys):
    """`prrrp track` takes the logs `identify` takes: motor currents with --drive-gains and
    motor-side data with --motor-side give the model of the same log on the joint side
    (the conversion is exact to round-off), recorded in model.json for `prrrp predict`; with
    --model it converts as that model's log was converted."""
    tmp = geared["tmp"] / "track"
    tmp.mkdir()
    toml = ratios_toml(tmp)
    log = geared_log(seed=3, duration=12.0)
    t, q, qd, _qdd, tau = log
    _write_csv(tmp / "joint.csv", t, q, {"qd": qd, "tau": tau})
    motor_log(log, tmp / "motor.csv", accelerations=False)
    gains = ",".join(f"{g:g}" for g in GAINS)
    base = ["track", "--robot", str(toml), "--coulomb-scale", str(V_S)]
    assert main([*base, str(tmp / "joint.csv"), "--out", str(tmp / "a")]) == 0
    # Currents without their gains: the error names the option, which track has.
    assert main([*base, str(tmp / "motor.csv"), "--motor-side", "--out", str(tmp / "x")]) == 2
    assert "--drive-gains" in capsys.readouterr().err
    code = main(
        [
            *base,
            str(tmp / "motor.csv"),
            "--drive-gains",
            gains,
            "--motor-side",
            "--out",
            str(tmp / "b"),
        ]
    )
    assert code == 0, capsys.readouterr().err
    a = prrrp.IdentifiedModel.load(tmp / "a" / "model.json")
    b = prrrp.IdentifiedModel.load(tmp / "b" / "model.json")
    np.testing.assert_allclose(b.beta, a.beta, rtol=1e-6, atol=1e-9 * np.abs(a.beta).max())
    assert b.preprocessing["drives"] == {"drive_gains": list(GAINS), "motor_side": True}
    assert "drives" not in a.preprocessing
    # predict converts a motor-side current log with what model.json recorded.
    assert (
        main(
            [
                "predict",
                str(tmp / "b" / "model.json"),
                str(tmp / "motor.csv"),
                "--out",
                str(tmp / "tau.csv"),
            ]
        )
        == 0
    )
    # A prior identified from such a log: track converts the same way without the flags.
    assert (
        main(
            [
                "identify",
                str(tmp / "motor.csv"),
                "--robot",
                str(toml),
                "--drive-gains",
                gains,
                "--motor-side",
                "--coulomb-scale",
                str(V_S),
                "--out",
                str(tmp / "prior"),
            ]
        )
        == 0
    )
    prior = str(tmp / "prior" / "model.json")
    assert main(["track", str(tmp / "motor.csv"), "--model", prior, "--out", str(tmp / "c")]) == 0
    c = prrrp.IdentifiedModel.load(tmp / "c" / "model.json")
    assert c.preprocessing["drives"]["motor_side"] is True
    capsys.readouterr()


def test_readme_geared_arm_file_loads(tmp_path):
    """The README's TOML example, with the UR5's URDF standing in for the TX40's."""
    import re
    import shutil

    readme = (Path(__file__).resolve().parents[2] / "README.md").read_text(encoding="utf-8")
    section = readme[readme.index("**Geared arms") :]
    text = re.search(r"```toml\n(.*?)```", section, re.S).group(1)
    shutil.copy(UR5, tmp_path / "tx40.urdf")
    (tmp_path / "tx40.toml").write_text(text, encoding="utf-8")
    robot = prrrp.SerialChain.from_file(tmp_path / "tx40.toml")
    act = robot.actuators
    assert robot.name == "tx40"
    assert act["armature"]
    assert np.array_equal(act["coupling"], COUPLING)
    assert np.array_equal(act["gear_ratios"], np.full(6, 100.0))
    assert robot.num_params == 6 * (10 + 1)


def test_current_columns_are_checked(tmp_path):
    robot = prrrp.SerialChain.from_urdf(UR5)
    t = np.arange(40) * 0.01
    q = np.zeros((40, 6))
    both = tmp_path / "both.csv"
    _write_csv(both, t, q, {"tau": q, "i": q})
    with pytest.raises(ValueError, match="give one"):
        prrrp.read_measurements(both, robot)
    currents = tmp_path / "currents.csv"
    _write_csv(currents, t, q, {"i": np.ones((40, 6))})
    with pytest.raises(ValueError, match="drive-gains"):
        prrrp.read_measurements(currents, robot)
    raw = prrrp.read_measurements(currents, robot, drive_gains=[2.0, 2, 2, 2, 2, 3])
    assert np.allclose(raw["tau"], [2.0, 2, 2, 2, 2, 3])
    torques = tmp_path / "torques.csv"
    _write_csv(torques, t, q, {"tau": q})
    with pytest.raises(ValueError, match="not motor currents"):
        prrrp.read_measurements(torques, robot, drive_gains=[1.0] * 6)
    with pytest.raises(ValueError, match="6 actuators"):
        prrrp.drives.parse_gains("1,2,3", 6)
    # 0, a gain past any drive (1e99 N·m/A), and an empty one ("1,,3" was read as two).
    for text in ["1,2,3,4,5,0", "1e99,2,3,4,5,6", "nan,2,3,4,5,6"]:
        with pytest.raises(ValueError, match=r"not a gain .* between 1e-06 and 1e\+06"):
            prrrp.drives.parse_gains(text, 6)
    with pytest.raises(ValueError, match="must be 3 comma-separated numbers"):
        prrrp.drives.parse_gains("1,,3", 3)
    assert prrrp.drives.parse_gains("1, -2.5 ,3", 3) == [1.0, -2.5, 3.0]
    # The paper's fixed format has no current columns.
    five = tmp_path / "five.csv"
    _write_csv(five, t, np.zeros((40, 5)), {"i": np.zeros((40, 5))})
    with pytest.raises(ValueError, match="unknown column 'i1'"):
        prrrp.csvio.read_measurements(five)
