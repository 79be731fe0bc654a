"""Joint logs from ROS bags: ROS 2 (rosbag2, sqlite3 or MCAP storage) and ROS 1 (.bag), read with the
`rosbags` library (an optional extra: `pip install "robot-dynamics-harness[ros]"`). A floating base's pose
and twist (nav_msgs/Odometry) and its contacts' wrenches (geometry_msgs/WrenchStamped) are topics of the
same bag (`read_stamped`; harness/sources/log/floating.py).

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
ODOMETRY = ("nav_msgs/msg/Odometry", "nav_msgs/Odometry")  # a floating base's pose and twist
WRENCH = ("geometry_msgs/msg/WrenchStamped", "geometry_msgs/WrenchStamped")  # a contact's force and torque
TYPES = {JOINT_STATE: "sensor_msgs/JointState", ODOMETRY: "nav_msgs/Odometry", WRENCH: "geometry_msgs/WrenchStamped"}


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


def _connections(reader, path: Path, topic: str, types: tuple[str, str] = JOINT_STATE, key: str = "topic") -> list:
    """The bag's connections of `topic`, of one of `types`; `key` names the scenario's key in the errors."""
    found = [c for c in reader.connections if c.topic == topic]
    if not found:
        topics = sorted({f"{c.topic} ({c.msgtype})" for c in reader.connections})
        raise InputError(path, key, f"no topic {topic!r} in the bag (it has {', '.join(topics[:8]) or 'none'})")
    wrong = [c.msgtype for c in found if c.msgtype not in types]
    if wrong:
        raise InputError(path, key, f"{topic!r} carries {wrong[0]}, not {TYPES[types]}")
    return found


def check_bag(path: Path, topic: str, others: tuple[tuple[str, tuple[str, str], str], ...] = ()) -> None:
    """At load, before any work: the bag opens and has the topic, of JointState, and each of `others`
    ((topic, its message types, the scenario's key naming it): a floating base's odometry and wrenches)."""
    reader, errors = _reader(path)
    try:
        with reader:
            _connections(reader, path, topic)
            for other, types, key in others:
                _connections(reader, path, other, types, key)
    except errors as exc:
        raise InputError(path, "bag", f"cannot read the bag ({exc})") from None


def _stamp(msg, received_ns: int) -> float:
    """A message's time (s): its header's stamp, or the time the bag received it where the header has none."""
    header = getattr(msg, "header", None)
    sec = getattr(getattr(header, "stamp", None), "sec", 0) if header is not None else 0
    nanosec = getattr(getattr(header, "stamp", None), "nanosec", 0) if header is not None else 0
    return sec + nanosec * 1e-9 if (sec or nanosec) else received_ns * 1e-9


def _vector(v) -> list[float]:
    return [float(v.x), float(v.y), float(v.z)]


def read_stamped(path: Path, topic: str, types: tuple[str, str], key: str) -> tuple[np.ndarray, np.ndarray]:
    """t (N,) and the values (N, k) of a floating base's topic, in stamp order: nav_msgs/Odometry (ODOMETRY) as
    its pose's position, its orientation x y z w and its twist (linear, angular: in the frame its child_frame_id
    names, a base frame by REP 105) (k = 13); geometry_msgs/WrenchStamped (WRENCH) as force and torque (k = 6),
    in the frame its header names. `key` names the scenario's key in the errors."""
    reader, errors = _reader(path)
    t, rows = [], []
    try:
        with reader:
            connections = _connections(reader, path, topic, types, key)
            for connection, received, raw in reader.messages(connections=connections):
                msg = reader.deserialize(raw, connection.msgtype)
                t.append(_stamp(msg, received))
                if types == ODOMETRY:
                    pose, twist = msg.pose.pose, msg.twist.twist
                    o = pose.orientation
                    rows.append([*_vector(pose.position), float(o.x), float(o.y), float(o.z), float(o.w),
                                 *_vector(twist.linear), *_vector(twist.angular)])
                else:
                    rows.append([*_vector(msg.wrench.force), *_vector(msg.wrench.torque)])
    except errors as exc:
        raise InputError(path, "bag", f"cannot read the bag ({exc})") from None
    if not t:
        raise InputError(path, key, f"no message on {topic}")
    order = np.argsort(np.asarray(t), kind="stable")
    return np.asarray(t)[order], np.asarray(rows, dtype=float)[order]


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
                t.append(_stamp(msg, stamp))
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
