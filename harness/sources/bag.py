"""Joint logs from ROS bags: ROS 2 (rosbag2, sqlite3 or MCAP storage) and ROS 1 (.bag), read with the
`rosbags` library (an optional extra: `pip install "robot-dynamics-harness[ros]"`).

    [data]
    bag = "run_2024_05_02"        # a rosbag2 folder, or a ROS 1 .bag file, relative to the scenario
    topic = "/joint_states"       # sensor_msgs/JointState

Each message's `name` list is matched to the model's joints by name (in any order, with other joints
beside them); `position`, `velocity` (optional: all or none) and `effort` give q, q' and tau. The
time of a sample is the message header's stamp, or the time the bag received it where the header
has none. Units are ROS's (REP 103: rad, rad/s, N m), unless `[data] units` says otherwise (a UR
driver's "effort" is a motor current). Messages that lack a joint of the model, or carry fewer
positions or efforts than names, are refused with the first one named.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np

from harness.base.tomlio import MAX_DATA_BYTES, InputError

JOINT_STATE = ("sensor_msgs/msg/JointState", "sensor_msgs/JointState")


def _reader(path: Path):
    try:
        from rosbags.highlevel import AnyReader, AnyReaderError
        from rosbags.typesys import Stores, get_typestore
    except ImportError:
        raise InputError(path, "bag", 'reading ROS bags needs the rosbags library: pip install '
                                      '"robot-dynamics-harness[ros]"') from None
    store = Stores.ROS1_NOETIC if path.suffix == ".bag" else Stores.ROS2_HUMBLE
    try:
        return AnyReader([path], default_typestore=get_typestore(store)), AnyReaderError
    except (AnyReaderError, FileNotFoundError) as exc:
        raise InputError(path, "bag", f"not a ROS bag ({exc})") from None


def _connections(reader, path: Path, topic: str) -> list:
    found = [c for c in reader.connections if c.topic == topic]
    if not found:
        topics = sorted({f"{c.topic} ({c.msgtype})" for c in reader.connections})
        raise InputError(path, "topic", f"no topic {topic!r} in the bag (it has {', '.join(topics[:8]) or 'none'})")
    wrong = [c.msgtype for c in found if c.msgtype not in JOINT_STATE]
    if wrong:
        raise InputError(path, "topic", f"{topic!r} carries {wrong[0]}, not sensor_msgs/JointState")
    return found


def check_bag(path: Path, topic: str) -> None:
    """At load, before any work: the bag opens and has the topic, of JointState."""
    reader, errors = _reader(path)
    try:
        with reader:
            _connections(reader, path, topic)
    except errors as exc:
        raise InputError(path, "bag", f"cannot read the bag ({exc})") from None


def digest(path: Path) -> str:
    """sha256 of the bag's files (a rosbag2 folder: every file in name order), read in blocks."""
    h = hashlib.sha256()
    files = sorted(p for p in path.rglob("*") if p.is_file()) if path.is_dir() else [path]
    total = 0
    for f in files:
        h.update(f.name.encode())
        with open(f, "rb") as stream:
            while block := stream.read(1 << 20):
                total += len(block)
                if total > MAX_DATA_BYTES:
                    raise InputError(path, "bag", f"larger than {MAX_DATA_BYTES >> 30} GiB")
                h.update(block)
    return h.hexdigest()


def read_bag(path: Path, topic: str, joints: list[str]) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray]:
    """t (s), q, q' (or None) and tau, (N, n) in the given joint order, from the topic's messages."""
    reader, errors = _reader(path)
    t, q, qd, tau = [], [], [], []
    try:
        with reader:
            connections = _connections(reader, path, topic)
            for k, (connection, stamp, raw) in enumerate(reader.messages(connections=connections)):
                msg = reader.deserialize(raw, connection.msgtype)
                names = list(msg.name)
                missing = [j for j in joints if j not in names]
                if missing:
                    raise InputError(path, "topic", f"message {k + 1} on {topic} has no joint {missing[0]!r} "
                                                    f"(it names {', '.join(names[:8])})")
                index = [names.index(j) for j in joints]
                for label, values in (("position", msg.position), ("effort", msg.effort)):
                    if len(values) != len(names):
                        raise InputError(path, "topic", f"message {k + 1} on {topic}: {len(values)} {label} values "
                                                        f"for {len(names)} names")
                header = getattr(msg, "header", None)
                sec = getattr(getattr(header, "stamp", None), "sec", 0) if header is not None else 0
                nanosec = getattr(getattr(header, "stamp", None), "nanosec", 0) if header is not None else 0
                t.append(sec + nanosec * 1e-9 if (sec or nanosec) else stamp * 1e-9)
                q.append(np.asarray(msg.position, dtype=float)[index])
                tau.append(np.asarray(msg.effort, dtype=float)[index])
                qd.append(np.asarray(msg.velocity, dtype=float)[index] if len(msg.velocity) == len(names) else None)
    except errors as exc:
        raise InputError(path, "bag", f"cannot read the bag ({exc})") from None
    if not t:
        raise InputError(path, "topic", f"no message on {topic}")
    with_velocity = [v is not None for v in qd]
    if any(with_velocity) and not all(with_velocity):
        raise InputError(path, "topic", f"message {with_velocity.index(False) + 1} on {topic} has no velocities where "
                                        "others have: all or none")
    order = np.argsort(np.asarray(t), kind="stable")  # messages in the order they were stamped

    def ordered(x: list) -> np.ndarray:
        return np.asarray(x)[order]

    return ordered(t), ordered(q), ordered(qd) if all(with_velocity) else None, ordered(tau)
