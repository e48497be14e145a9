"""ROS 2 bags: joint measurements from ``sensor_msgs/JointState`` messages, read with the
``rosbags`` package (an optional extra: ``pip install prrrp[ros]``; no ROS installation is
needed).

A bag is a folder (rosbag2, sqlite3 or mcap storage) or a single ``.mcap`` file. Each message
on the topic gives one sample: the time is the message header's stamp (the bag's receive
times of all messages when any stamp is zero: one clock), ``position`` → q (rad, m),
``velocity`` → measured q̇ (used when every message carries it) and ``effort`` → τ (N·m,
N). Joints are matched to the robot's joints by name, so the message may list them in any
order and carry more joints (grippers, other arms) than the robot has.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from prrrp._prrrp import MAX_MAGNITUDE
from prrrp.csvio import MIN_SAMPLES, TOO_LARGE, InputError

#: The default topic of ``sensor_msgs/JointState`` (ros2_control's joint_state_broadcaster).
DEFAULT_TOPIC = "/joint_states"
JOINT_STATE = "sensor_msgs/msg/JointState"
#: Most messages read from one topic (10 hours at 1 kHz), a bound against mistaken input.
MAX_MESSAGES = 36_000_000


def is_bag(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` looks like a ROS 2 bag: a folder with ``metadata.yaml`` or a ``.mcap``
    or ``.db3`` file."""
    p = Path(path)
    if p.is_dir():
        return (p / "metadata.yaml").is_file()
    return p.suffix.lower() in (".mcap", ".db3")


def _rosbags() -> Any:
    try:
        from rosbags.highlevel import AnyReader
    except ImportError:
        raise InputError(
            "reading ROS 2 bags needs the `rosbags` package: pip install 'prrrp[ros]'"
        ) from None
    return AnyReader


def read_joint_states(
    path: str | os.PathLike[str],
    joint_names: list[str],
    topic: str = DEFAULT_TOPIC,
) -> dict[str, np.ndarray]:
    """Reads the robot's joints from the ``JointState`` messages of ``topic`` in the bag at
    ``path``.

    Returns ``t`` (S,) s, ``q`` and ``tau`` (S, N) in the order of ``joint_names`` and, when
    every message carries velocities, ``qd`` (S, N). Raises :class:`prrrp.csvio.InputError`
    (one line) for a missing topic (naming the topics the bag has), a topic of another
    message type, a joint that the messages do not name, messages without efforts, or
    non-finite values.
    """
    reader_cls = _rosbags()
    p = Path(path)
    if not p.exists():
        raise InputError(f"{p}: no such file or directory")
    # A single .mcap file is read as a bag of one file (rosbags wants its folder then).
    try:
        reader = reader_cls([p])
        reader.open()
    except Exception as e:  # rosbags raises its own hierarchy; any failure is bad input
        raise InputError(f"{p}: not a readable ROS 2 bag ({type(e).__name__}: {e})") from None
    try:
        conns = [c for c in reader.connections if c.topic == topic]
        if not conns:
            topics = sorted({c.topic for c in reader.connections})
            raise InputError(
                f"{p}: no topic '{topic}' in the bag (it has {', '.join(topics) or 'none'}); "
                "choose one with --topic"
            )
        wrong = [c.msgtype for c in conns if c.msgtype != JOINT_STATE]
        if wrong:
            raise InputError(f"{p}: topic '{topic}' carries {wrong[0]}, not {JOINT_STATE}")
        t: list[float] = []
        q: list[np.ndarray] = []
        qd: list[np.ndarray | None] = []
        tau: list[np.ndarray] = []
        receive: list[float] = []  # the bag's receive times, s
        index: dict[tuple[str, ...], np.ndarray] = {}
        for k, (conn, stamp_ns, raw) in enumerate(reader.messages(connections=conns)):
            if k >= MAX_MESSAGES:
                raise InputError(f"{p}: more than {MAX_MESSAGES} messages on '{topic}'")
            msg = reader.deserialize(raw, conn.msgtype)
            names = tuple(msg.name)
            if names not in index:
                index[names] = _match(p, topic, names, joint_names, k)
            cols = index[names]
            where = f"{p}: message {k} on '{topic}'"
            if len(msg.position) != len(names):
                raise InputError(
                    f"{where} has {len(msg.position)} positions for {len(names)} joint names; "
                    "a JointState message gives one position per name"
                )
            if len(msg.effort) != len(names):
                raise InputError(
                    f"{where} has {len(msg.effort)} efforts for "
                    f"{len(names)} joints; identification needs measured joint torques"
                )
            if len(msg.velocity) not in (0, len(names)):
                raise InputError(
                    f"{where} has {len(msg.velocity)} velocities for {len(names)} joint "
                    "names; a JointState message gives one per name or none"
                )
            sec = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
            t.append(sec)
            receive.append(1e-9 * stamp_ns)
            q.append(np.asarray(msg.position, dtype=float)[cols])
            tau.append(np.asarray(msg.effort, dtype=float)[cols])
            vel = np.asarray(msg.velocity, dtype=float)
            qd.append(vel[cols] if len(vel) == len(names) else None)
    finally:
        reader.close()
    if not t:
        raise InputError(f"{p}: no messages on '{topic}'")
    if len(t) < MIN_SAMPLES:
        # As a CSV file's: 5 messages ran `prrrp track` to a model of zeros.
        raise InputError(
            f"{p}: too few messages on '{topic}' ({len(t)}); at least {MIN_SAMPLES} are needed"
        )
    t = _time(p, topic, t, receive)
    out = {"t": np.asarray(t), "q": np.vstack(q), "tau": np.vstack(tau)}
    if all(v is not None for v in qd):
        out["qd"] = np.vstack(qd)
    for key, value in out.items():
        bad = np.argwhere(~np.isfinite(value))
        if bad.size:
            raise InputError(f"{p}: message {int(bad[0][0])} on '{topic}': {key} is not finite")
        big = np.argwhere(np.abs(value) >= MAX_MAGNITUDE)
        if big.size:
            raise InputError(f"{p}: message {int(big[0][0])} on '{topic}': {key} {TOO_LARGE}")
    return out


def _time(path: Path, topic: str, header: list[float], receive: list[float]) -> list[float]:
    """The messages' times: their header stamps, or the bag's receive times for all of
    them when any header stamp is 0 (a driver that stamps nothing, or not its first
    messages): one clock either way, where a zero stamp's receive time among header stamps
    mixed two. InputError naming the message whose time runs backwards (the data set's own
    check said only "row 501 is not", without the file)."""
    t, kind = (header, "header stamp") if min(header) > 0 else (receive, "receive time")
    back = np.flatnonzero(np.diff(np.asarray(t)) < 0)
    if back.size:
        k = int(back[0]) + 1
        raise InputError(
            f"{path}: message {k} on '{topic}': time runs backwards ({kind} {t[k]:.9g} s "
            f"after {t[k - 1]:.9g} s)"
        )
    return t


def _match(path: Path, topic: str, names: tuple[str, ...], joints: list[str], k: int) -> np.ndarray:
    """Columns of the robot's joints in a message naming ``names``; a name given twice is
    an error (which of its values is the joint's would be a guess)."""
    seen: set[str] = set()
    for name in names:
        if name in seen:
            raise InputError(
                f"{path}: message {k} on '{topic}' names joint '{name}' twice; each joint "
                "must appear once per JointState message"
            )
        seen.add(name)
    where = {n: i for i, n in enumerate(names)}
    missing = [j for j in joints if j not in where]
    if missing:
        raise InputError(
            f"{path}: message {k} on '{topic}' does not name the robot's joint(s) "
            f"{', '.join(missing)} "
            f"(it names {', '.join(names) or 'none'})"
        )
    return np.asarray([where[j] for j in joints], dtype=int)
