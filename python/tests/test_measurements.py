"""Measurements of any robot: CSV files of N joints and ROS 2 bags (written here with
rosbags' own writer), their conversion to a data set, and `prrrp predict` on them."""

from __future__ import annotations

import importlib.metadata
from pathlib import Path

import numpy as np
import pytest

import prrrp
from prrrp import cli, csvio

ROBOTS = importlib.metadata.distribution("example-robot-data").locate_file(
    "cmeel.prefix/share/example-robot-data/robots"
)


@pytest.fixture(scope="module")
def panda():
    return prrrp.SerialChain.from_urdf(
        str(ROBOTS / "panda_description/urdf/panda.urdf"), tip="panda_link8"
    )


def motion(seconds=12.0, rate=200.0, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, seconds, 1.0 / rate)
    w = 2 * np.pi * 0.15 * np.arange(1, 5)
    a = rng.uniform(-1, 1, (7, 4)) * 0.6 / np.arange(1, 5)
    s, c = np.sin(np.outer(t, w)), np.cos(np.outer(t, w))
    return t, s @ a.T, (c * w) @ a.T, -(s * w**2) @ a.T


def test_csv_of_seven_joints_with_repeated_rows(tmp_path: Path, panda):
    t, q, qd, qdd = motion()
    tau = panda.inverse_dynamics(q, qd, qdd)
    # A real log repeats rows: every 20th row twice.
    rep = np.repeat(np.arange(len(t)), np.where(np.arange(len(t)) % 20 == 0, 2, 1))
    path = tmp_path / "log.csv"
    path.write_text(csvio.format_measurements(t[rep], q[rep], tau[rep]))
    raw = prrrp.read_measurements(path, panda)
    assert raw["q"].shape == (len(rep), 7)
    assert "qd" not in raw
    data, report = prrrp.measurements_to_dataset(raw, {"cutoff_hz": 8.0})
    assert report["repeated_rows"] == len(rep) - len(t)
    assert data.dof == 7
    # The preprocessing differentiates the log back to the true motion (up to the filter).
    k = np.searchsorted(t, data.t)
    assert np.abs(data.qd - qd[k]).max() < 0.02 * np.abs(qd).max()
    # Without a robot the joint count comes from the header.
    assert prrrp.read_measurements(path)["q"].shape[1] == 7


def test_csv_errors_name_what_to_fix(tmp_path: Path, panda):
    t, q, _, _ = motion(seconds=1.0)
    tau = np.zeros_like(q)
    path = tmp_path / "five.csv"
    path.write_text(csvio.format_measurements(t, q[:, :5], tau[:, :5]))
    with pytest.raises(csvio.InputError, match="missing columns 'q6', 'q7'"):
        prrrp.read_measurements(path, panda)
    back = tmp_path / "back.csv"
    tt = t.copy()
    tt[30] = tt[28]
    back.write_text(csvio.format_measurements(tt, q, tau))
    with pytest.raises(csvio.InputError, match="runs backwards at data row 31"):
        prrrp.read_measurements(back, panda)


def test_time_in_milliseconds_is_an_error_that_says_so(tmp_path: Path, panda):
    """A log at 200 Hz with t in milliseconds (rows 5 apart) would be taken for a 0.2 Hz
    motion whose q̇ and q̈ are 1000 and 1e6 times too small; reading it names the unit.
    The same rows in seconds read, and a table that gives q̇ and q̈ may number its rows."""
    t, q, qd, qdd = motion(seconds=2.0)
    tau = panda.inverse_dynamics(q, qd, qdd)
    path = tmp_path / "ms.csv"
    path.write_text(csvio.format_measurements(1e3 * t, q, tau))
    with pytest.raises(csvio.InputError, match=r"median 5 s apart .* milliseconds"):
        prrrp.read_measurements(path, panda)
    path.write_text(csvio.format_measurements(t, q, tau))
    assert prrrp.read_measurements(path, panda)["t"][-1] == pytest.approx(t[-1])
    poses = tmp_path / "poses.csv"
    poses.write_text(csvio.format_measurements(np.arange(len(t)), q, tau, qd, qdd))
    assert prrrp.read_measurements(poses, panda)["qdd"].shape == q.shape
    # Seconds divided by 1e6 (rows 5 ns apart): `identify` blamed the cut-off ("more than
    # 1e7 samples"), and `track` learned nothing and exited 0.
    path.write_text(csvio.format_measurements(1e-6 * t, q, tau))
    with pytest.raises(csvio.InputError, match=r"median 5e-09 s apart .* faster than any"):
        prrrp.read_measurements(path, panda)


def write_bag(path: Path, t, names, q, qd, tau, topic="/joint_states"):
    """A bag of one JointState message per row of q, qd and tau at times t."""
    rows = ((tk, names, q[k], qd[k], tau[k]) for k, tk in enumerate(t))
    write_messages(path, rows, topic)


def test_bag_joints_matched_by_name(tmp_path: Path, panda):
    pytest.importorskip("rosbags")
    t, q, qd, qdd = motion(seconds=3.0)
    t = t + 100.0
    tau = panda.inverse_dynamics(q, qd, qdd)
    joints = list(panda.joint_names)
    # The message lists the joints in another order, with two finger joints extra.
    order = [3, 0, 6, 1, 5, 2, 4]
    names = [joints[i] for i in order] + ["panda_finger_joint1", "panda_finger_joint2"]
    extra = np.zeros((len(t), 2))

    def shuffle(x):
        return np.hstack([x[:, order], extra])

    bag = tmp_path / "bag"
    write_bag(bag, t, names, shuffle(q), shuffle(qd), shuffle(tau))
    raw = prrrp.read_measurements(bag, panda)
    np.testing.assert_allclose(raw["t"], t, atol=1e-9)
    np.testing.assert_array_equal(raw["q"], q)
    np.testing.assert_array_equal(raw["qd"], qd)
    np.testing.assert_array_equal(raw["tau"], tau)
    with pytest.raises(csvio.InputError, match=r"no topic '/other'.*/joint_states"):
        prrrp.read_measurements(bag, panda, topic="/other")
    puma = prrrp.SerialChain.puma560()
    with pytest.raises(csvio.InputError, match="does not name the robot's joint"):
        prrrp.read_measurements(bag, puma)


def write_messages(path: Path, messages, topic="/joint_states", receive=None):
    """A bag of JointState messages given as (t, names, position, velocity, effort): t is
    the header stamp (0: none) and, unless ``receive`` gives them, the receive time."""
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    js = store.types["sensor_msgs/msg/JointState"]
    header = store.types["std_msgs/msg/Header"]
    stamp = store.types["builtin_interfaces/msg/Time"]
    with Writer(path, version=8) as writer:
        conn = writer.add_connection(topic, js.__msgtype__, typestore=store)
        for k, (tk, names, position, velocity, effort) in enumerate(messages):
            sec = int(tk)
            msg = js(
                header=header(stamp=stamp(sec=sec, nanosec=round((tk - sec) * 1e9)), frame_id=""),
                name=list(names),
                position=np.asarray(position, dtype=float),
                velocity=np.asarray(velocity, dtype=float),
                effort=np.asarray(effort, dtype=float),
            )
            at = tk if receive is None else receive[k]
            writer.write(conn, round(at * 1e9), store.serialize_cdr(msg, js.__msgtype__))


def test_bag_time_that_runs_backwards_or_mixes_clocks_names_the_message(tmp_path: Path, panda):
    """Header stamps of messages 10 and 11 swapped while the receive times increase: the
    error names the bag, the message and both stamps (it said only "time stamps must be
    strictly increasing; row 11 is not", without the file). A message without a header
    stamp among stamped ones read its receive time, another clock, beside their stamps:
    then every message reads its receive time."""
    pytest.importorskip("rosbags")
    names = list(panda.joint_names)
    receive = [500.0 + 0.01 * k for k in range(30)]
    header = [100.0 + 0.01 * k for k in range(30)]
    header[10], header[11] = header[11], header[10]
    rows = [(h, names, np.full(7, 0.01 * k), np.zeros(7), np.ones(7)) for k, h in enumerate(header)]
    bag = tmp_path / "back"
    write_messages(bag, rows, receive=receive)
    with pytest.raises(
        csvio.InputError,
        match=r"back: message 11 on '/joint_states': time runs "
        r"backwards \(header stamp 100\.1 s after 100\.11 s\)",
    ):
        prrrp.read_measurements(bag, panda)
    header = [100.0 + 0.01 * k for k in range(30)]
    header[5] = 0.0
    rows = [(h, names, np.full(7, 0.01 * k), np.zeros(7), np.ones(7)) for k, h in enumerate(header)]
    mixed = tmp_path / "mixed"
    write_messages(mixed, rows, receive=receive)
    np.testing.assert_allclose(prrrp.read_measurements(mixed, panda)["t"], receive)
    # No header stamps at all: the receive times are one clock, and read.
    rows = [(0.0, names, np.full(7, 0.01 * k), np.zeros(7), np.ones(7)) for k in range(30)]
    plain = tmp_path / "plain"
    write_messages(plain, rows, receive=receive)
    np.testing.assert_allclose(prrrp.read_measurements(plain, panda)["t"], receive)
    # Five messages: refused as a five-row CSV file is (they ran `prrrp track` to a model
    # of zeros).
    few = tmp_path / "few"
    write_messages(few, rows[:5], receive=receive[:5])
    with pytest.raises(csvio.InputError, match=r"few: too few messages on '/joint_states' \(5\)"):
        prrrp.read_measurements(few, panda)


@pytest.mark.parametrize(
    ("fault", "message"),
    [
        ("short_position", r"message 2 on '/joint_states' has 6 positions for 7 joint names"),
        ("long_position", r"message 2 on '/joint_states' has 8 positions for 7 joint names"),
        ("short_velocity", r"message 2 on '/joint_states' has 3 velocities for 7 joint names"),
        ("short_effort", r"message 2 on '/joint_states' has 6 efforts for 7 joints"),
        ("twice", r"message 2 on '/joint_states' names joint 'panda_joint2' twice"),
        ("huge_effort", r"message 2 on '/joint_states': tau is 1e100 or more in magnitude"),
    ],
)
def test_malformed_bag_messages_are_typed_errors(tmp_path: Path, panda, fault, message):
    """A JointState message whose arrays do not match its names (a bare IndexError before)
    or that names a joint twice (silently accepted before) is an InputError naming the bag,
    topic and message."""
    pytest.importorskip("rosbags")
    names = list(panda.joint_names)
    messages = []
    for k in range(30):
        q, v, e = np.full(7, 0.1 * k), np.zeros(7), np.ones(7)
        row = [100.0 + 0.01 * k, names, q, v, e]
        if k == 2:
            if fault == "short_position":
                row[2] = q[:-1]
            elif fault == "long_position":
                row[2] = np.append(q, 0.0)
            elif fault == "short_velocity":
                row[3] = v[:3]
            elif fault == "short_effort":
                row[4] = e[:-1]
            elif fault == "twice":
                row[1] = [*names[:2], names[1], *names[3:]]
            elif fault == "huge_effort":
                row[4] = np.where(np.arange(7) == 3, 1e300, e)
        messages.append(tuple(row))
    bag = tmp_path / "bag"
    write_messages(bag, messages)
    with pytest.raises(csvio.InputError, match=message) as info:
        prrrp.read_measurements(bag, panda)
    assert str(bag) in str(info.value)


def test_predict_command(tmp_path: Path, panda, capsys):
    t, q, qd, qdd = motion(seconds=20.0, rate=100.0, seed=1)
    tau = panda.inverse_dynamics(q, qd, qdd)
    model = prrrp.identify(
        panda,
        prrrp.Dataset(t, q, qd, qdd, tau),
        preprocessing={"settings": {"cutoff_hz": 6.0}},
    )
    model_path = tmp_path / "model.json"
    model.save(model_path)
    t2, q2, qd2, qdd2 = motion(seconds=10.0, rate=100.0, seed=2)
    tau2 = panda.inverse_dynamics(q2, qd2, qdd2)
    # States given in full: the prediction is the rigid-body torque of those states.
    full = tmp_path / "full.csv"
    full.write_text(csvio.format_measurements(t2, q2, tau2, qd2, qdd2))
    out = tmp_path / "tau.csv"
    assert cli.main(["predict", str(model_path), str(full), "--out", str(out)]) == 0
    table = np.loadtxt(out, delimiter=",", skiprows=1)
    header = "t," + ",".join(f"tau{i}" for i in range(1, 8)) + ",edge"
    assert out.read_text().splitlines()[0] == header
    np.testing.assert_allclose(table[:, 1:8], tau2, atol=1e-6 * np.abs(tau2).max())
    assert not table[:, 8].any()  # given states: no filter, no edge
    assert "torque-prediction error" in capsys.readouterr().out
    # Positions only: derived with the model's recorded preprocessing (6 Hz cut-off).
    bare = tmp_path / "bare.csv"
    bare.write_text(csvio.format_measurements(t2, q2, tau2))
    assert cli.main(["predict", str(model_path), str(bare), "--out", str(out)]) == 0
    table = np.loadtxt(out, delimiter=",", skiprows=1)
    assert np.array_equal(table[:, 0], t2)  # every row, at its time stamp
    inside = table[:, 8] == 0
    err = np.sqrt(((table[inside, 1:8] - tau2[inside]) ** 2).mean(axis=0))
    assert (err < 0.05 * np.sqrt((tau2**2).mean(axis=0))).all(), err
    # Bad input: one line on stderr, exit 2, nothing written.
    out.unlink()
    assert cli.main(["predict", str(full), str(full), "--out", str(out)]) == cli.EXIT_USAGE
    assert "not a usable identified model" in capsys.readouterr().err
    assert not out.exists()
