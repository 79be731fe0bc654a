"""A floating base's log: the base's pose and twist and the contacts' wrenches beside the joints' channels,
`[data.base]` and `[[data.contacts]]` (docs/floating_base.md).

    [data.base]
    position = ["px", "py", "pz"]                  # m, world axes: the base frame's origin
    quaternion = ["qw", "qx", "qy", "qz"]          # the base frame's orientation, in the order `order` says
    order = "wxyz"                                 # or "xyzw" (Pinocchio's, ROS's): declared, never guessed
    twist = ["vx", "vy", "vz", "wx", "wy", "wz"]   # m/s, rad/s: the origin's velocity and the angular velocity
    twist_axes = "world"                           # or "base" (a state estimator's body-frame twist)

    [[data.contacts]]
    name = "FL_foot"
    body = "FL_LOWER_LEG"                          # the body it acts on
    point = [0.1946, 0.14695, -0.32]               # where on it, at q = 0 (world components, the file's pose)
    force = ["FL_fx", "FL_fy", "FL_fz"]            # N: the world's force on the body at the point
    torque = ["FL_mx", "FL_my", "FL_mz"]           # N m about the point (optional: a point contact has none)
    axes = "world"                                 # or "base", or "body": the axes the force and torque are given in
    rpy = [0.0, 0.0, 0.0]                          # with axes = "body": the sensor's axes at q = 0, as a URDF
                                                   # <origin rpy> in world (rad; default: the world's axes)

From a ROS bag (`[data] bag`, its joint states' `topic`), the base and each contact are topics of the same bag,
joined on their stamps to the joint states' (exactly, or the nearest within half a step, said):

    [data.base]
    topic = "/odom"                                # nav_msgs/Odometry: position, orientation (x y z w), twist
    twist_axes = "base"                            # declared: REP 105 puts it in the child frame, estimators vary

    [[data.contacts]]
    name = "FL_foot"
    body = "FL_LOWER_LEG"
    point = [0.1946, 0.14695, -0.32]
    topic = "/FL_foot/wrench"                      # geometry_msgs/WrenchStamped: force and torque about the point
    axes = "world"                                 # the frame its header names, declared as for columns

Read into the harness's convention (harness/model/floating.py, every vector in world axes): the quaternion
put in w x y z order and refused where its norm is off 1 by more than QUATERNION_NORM (a column in the wrong
order or unit reads as that), then normalised, its sign made continuous (q and -q are one orientation: a
log's quaternion flips where its estimator chose the other; the flip would read as a full turn); a twist
and a wrench in base axes turned into world axes by the base's orientation at the same row, a wrench in a
body's axes (a foot's force sensor) by that body's orientation at the row's joint positions and base
(harness/model/contacts.py, contact_axes). The base's
acceleration comes from the conditioning (the twist differentiated as the joints' velocities are: the
same resampling, filter and trim), and each contact's point from the kinematics of the conditioned
states.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from harness.base.tomlio import InputError, Table
from harness.model.spec import RobotSpec

QUATERNION_NORM = 1e-3  # a logged quaternion's norm may be off 1 by this (its logger's rounding), no more
ORDERS = ("wxyz", "xyzw")
AXES = ("world", "base")  # a twist's
CONTACT_AXES = (*AXES, "body")  # a contact wrench's


@dataclass(frozen=True)
class LogContact:
    name: str
    body: str
    point_W0: np.ndarray
    force: tuple[str, ...]
    torque: tuple[str, ...] | None
    axes: str
    R_W0: np.ndarray | None = None  # axes = "body": the sensor's axes at q = 0 in world (`rpy`)
    topic: str | None = None  # a bag's geometry_msgs/WrenchStamped topic (its force and torque), else columns


@dataclass(frozen=True, eq=False)
class FloatingLog:
    """What `[data.base]` and `[[data.contacts]]` name (module docstring)."""

    position: tuple[str, ...]
    quaternion: tuple[str, ...]
    order: str
    twist: tuple[str, ...]
    twist_axes: str
    contacts: tuple[LogContact, ...] = ()
    topic: str | None = None  # a bag's nav_msgs/Odometry topic (its pose and twist), else columns

    def describe(self) -> dict:
        return {"position": list(self.position), "quaternion": list(self.quaternion), "order": self.order,
                "twist": list(self.twist), "twist_axes": self.twist_axes, "topic": self.topic,
                "contacts": [{"name": c.name, "body": c.body, "point": [float(x) for x in c.point_W0],
                              "force": list(c.force), "torque": list(c.torque) if c.torque else None, "axes": c.axes,
                              "topic": c.topic, **({"R_W0": c.R_W0.tolist()} if c.R_W0 is not None else {})}
                             for c in self.contacts]}

    def columns(self) -> dict[str, list[str]]:
        """{kind: the log's columns}, the kinds `extra` gives back."""
        out = {"base_position": list(self.position), "base_quaternion": list(self.quaternion),
               "base_twist": list(self.twist)}
        for c in self.contacts:
            out[f"contact_force:{c.name}"] = list(c.force)
            if c.torque is not None:
                out[f"contact_torque:{c.name}"] = list(c.torque)
        return out


def read_floating_log(t: Table, robot: RobotSpec) -> FloatingLog | None:
    """`[data.base]` and `[[data.contacts]]` of the `[data]` table `t`, validated; None without `base`."""
    if not t.has("base"):
        if t.has("contacts"):
            raise t.error("contacts", "a log's contacts act on a floating base: give its [data.base] too")
        return None
    from harness.model.floating import not_free

    why = not_free(robot, "read from a log")
    if why is not None:
        raise t.error("base", why)
    b, bag = t.table("base"), t.has("bag")
    if _from_topic(b, bag, ("position", "quaternion", "order", "twist"), "nav_msgs/Odometry"):
        topic = b.string("topic")  # the message's own names, its quaternion in x y z w order
        position, quaternion, twist = _odometry_names(topic)
        base = FloatingLog(position, quaternion, "xyzw", twist, b.string("twist_axes", choices=AXES), topic=topic)
    else:
        base = FloatingLog(_names(b, "position", 3), _names(b, "quaternion", 4), b.string("order", choices=ORDERS),
                           _names(b, "twist", 6), b.string("twist_axes", choices=AXES))
    b.finish()
    contacts, bodies = [], {x.name for x in robot.massive_bodies}
    for ct in t.tables("contacts") if t.has("contacts") else ():
        name, body = ct.string("name"), ct.string("body")
        if body not in bodies:
            raise ct.error("body", f"no moving body {body!r} in model {robot.name!r}")
        if name in {c.name for c in contacts}:
            raise ct.error("name", f"contact {name!r} is named twice")
        axes = ct.string("axes", choices=CONTACT_AXES)
        if ct.has("rpy") and axes != "body":
            raise ct.error("rpy", f"the sensor's axes on its body: for axes = \"body\", not {axes!r}")
        R_W0 = None
        if axes == "body":
            from harness.model.urdf import rpy_matrix

            R_W0 = rpy_matrix(ct.vector("rpy", 3)) if ct.has("rpy") else np.eye(3)
        if _from_topic(ct, bag, ("force", "torque"), "geometry_msgs/WrenchStamped"):
            topic = ct.string("topic")
            force, torque = ([f"{topic}: wrench.{kind}.{x}" for x in "xyz"] for kind in ("force", "torque"))
            contacts.append(LogContact(name, body, ct.vector("point"), tuple(force), tuple(torque), axes, R_W0, topic))
        else:
            contacts.append(LogContact(name, body, ct.vector("point"), _names(ct, "force", 3),
                                       _names(ct, "torque", 3) if ct.has("torque") else None, axes, R_W0))
        ct.finish()
    return FloatingLog(base.position, base.quaternion, base.order, base.twist, base.twist_axes, tuple(contacts),
                       base.topic)


def _from_topic(t: Table, bag: bool, columns: tuple[str, ...], message: str) -> bool:
    """Whether a base's or a contact's channels are a bag's topic (`topic`, of `message`) rather than a CSV's
    `columns`: a bag's are topics, a CSV's columns, each refused in the other's place."""
    if t.has("topic") and not bag:
        raise t.error("topic", "a topic is read from a ROS bag: give [data] bag, or the CSV's columns")
    if bag and not t.has("topic"):
        raise t.error("topic", f"missing: a bag's {'base' if 'twist' in columns else 'contact'} is read from its "
                               f"{message} topic")
    given = [k for k in columns if t.has(k)]
    if bag and given:
        raise t.error(given[0], f"the {message} messages carry it: no column to give")
    return bag


def _odometry_names(topic: str) -> tuple[tuple[str, ...], tuple[str, ...], tuple[str, ...]]:
    """The position's, the quaternion's (x y z w) and the twist's names of a nav_msgs/Odometry topic."""
    return (tuple(f"{topic}: pose.pose.position.{x}" for x in "xyz"),
            tuple(f"{topic}: pose.pose.orientation.{x}" for x in "xyzw"),
            tuple(f"{topic}: twist.twist.{kind}.{x}" for kind in ("linear", "angular") for x in "xyz"))


def bag_channels(fl: FloatingLog, path, t_joints: np.ndarray) -> tuple[np.ndarray, dict[str, np.ndarray], dict,
                                                                      list[str]]:
    """The base's and the contacts' channels of a bag, their topics' messages joined on their stamps to the
    joint states' (harness/sources/log/join.py: exactly, or the nearest within half a step, said): which joint
    states are kept (N,), the channels {kind: (kept, k)} (FloatingLog.columns' kinds), the join's record and what
    it says."""
    from harness.sources.bag import ODOMETRY, WRENCH, read_stamped
    from harness.sources.log.join import join_on_time

    topics = {fl.topic: read_stamped(path, fl.topic, ODOMETRY, "data.base.topic")}
    for k, c in enumerate(fl.contacts):
        if c.topic not in topics:
            topics[c.topic] = read_stamped(path, c.topic, WRENCH, f"data.contacts[{k}].topic")
    join = join_on_time("the joint states", t_joints, {topic: v[0] for topic, v in topics.items()}, "header.stamp")
    odometry = topics[fl.topic][1][join.rows[fl.topic]]
    read = {"base_position": odometry[:, :3], "base_quaternion": odometry[:, 3:7], "base_twist": odometry[:, 7:]}
    for c in fl.contacts:
        wrench = topics[c.topic][1][join.rows[c.topic]]
        read[f"contact_force:{c.name}"], read[f"contact_torque:{c.name}"] = wrench[:, :3], wrench[:, 3:]
    return join.keep, read, join.record, join.warnings


def _names(t: Table, key: str, n: int) -> tuple[str, ...]:
    names = t.strings(key, None)
    if len(names) != n:
        raise t.error(key, f"{len(names)} columns: {n} expected")
    return names


def in_convention(fl: FloatingLog, read: dict[str, np.ndarray], path, row_of, robot: RobotSpec,
                  q: np.ndarray) -> dict[str, np.ndarray]:
    """The columns `read` ({kind: (N, k)}, FloatingLog.columns' kinds) in the harness's convention: `base_pose`
    (N, 7: p_W, w x y z), `base_twist_W` (N, 6), `contact_F_W` and `contact_M_W` (N, k, 3) (module docstring),
    the joints at q (N, n) placing a body's sensor. A quaternion whose norm is off 1 is refused naming its column
    and row (`row_of(i)`)."""
    quat = read["base_quaternion"]
    if fl.order == "xyzw":
        quat = quat[:, [3, 0, 1, 2]]
    norm = np.linalg.norm(quat, axis=1)
    off = np.flatnonzero(np.abs(norm - 1.0) > QUATERNION_NORM)
    if len(off):
        raise InputError(path, fl.quaternion[0], f"{row_of(int(off[0]))}: the quaternion's norm is "
                                                 f"{norm[off[0]]:.6g}, not 1 (within {QUATERNION_NORM:g}; {len(off)} "
                                                 "such rows): a column in the wrong order or unit?")
    quat = quat / norm[:, None]
    flips = np.cumsum(np.r_[0, np.sum(quat[1:] * quat[:-1], axis=1) < 0.0]) % 2  # q ~ -q: the sign kept continuous
    quat = quat * np.where(flips == 1, -1.0, 1.0)[:, None]
    from harness.model.quaternion import to_matrix

    R = to_matrix(quat)
    twist = read["base_twist"]
    if fl.twist_axes == "base":
        twist = np.concatenate([(R @ twist[:, :3, None])[..., 0], (R @ twist[:, 3:, None])[..., 0]], axis=1)
    out = {"base_pose": np.concatenate([read["base_position"], quat], axis=1), "base_twist_W": twist}
    if fl.contacts:
        F = np.stack([read[f"contact_force:{c.name}"] for c in fl.contacts], axis=1)
        M = np.stack([read[f"contact_torque:{c.name}"] if c.torque is not None else np.zeros_like(F[:, 0])
                      for c in fl.contacts], axis=1)
        base_axes = np.array([c.axes == "base" for c in fl.contacts])
        F[:, base_axes] = (R[:, None] @ F[:, base_axes, :, None])[..., 0]
        M[:, base_axes] = (R[:, None] @ M[:, base_axes, :, None])[..., 0]
        body_axes = np.array([c.axes == "body" for c in fl.contacts])
        if body_axes.any():
            from harness.model.contacts import contact_axes

            R_S = contact_axes(robot, tuple(c for c in fl.contacts if c.axes == "body"), R, q)
            F[:, body_axes] = (R_S @ F[:, body_axes, :, None])[..., 0]
            M[:, body_axes] = (R_S @ M[:, body_axes, :, None])[..., 0]
        out.update(contact_F_W=F, contact_M_W=M)
    return out


def refuse_on_floating(t: Table, source, root: Table, fl: FloatingLog) -> FloatingLog:
    """What a floating base's log is not read with yet, refused in one line naming the key: no payload, `repeat`
    or counterbalanced channel (a motor-side log of a robot with [drives] is read through N as an arm's; currents
    with their declared constants are read as torques, and their constants identified, the scale the contacts'
    wrenches', with `[floating_log] rows = "all"`; unmeasured
    channels, `unmeasured`, leave their joints' rows unread and unjudged); no identification method, friction
    law search or refinement beside it (their fits read a fixed base). A log in several files joined on time,
    or with its torques in a file of their own, is read as for an arm, the base's and contacts' columns in any
    of the files (in `file` beside a torque file); the torque channels' delays are estimated and corrected as
    an arm's (`delay`); its validation a part of it or another log (`validation = { file = ... }`, in the same
    columns). From a ROS bag, the base's pose and twist are its nav_msgs/Odometry topic and each contact's
    wrench its geometry_msgs/WrenchStamped topic (`topic`), joined on their stamps to the joint states'."""
    why = "not read with a floating base's log yet (docs/floating_base.md)"
    for key, given in (("payload", source.payload is not None),
                       ("repeat", source.repeat is not None),
                       ("counterbalanced", bool(source.counterbalanced))):
        if given:
            raise t.error(key, why)
    if t.has("tilt"):
        raise t.error("tilt", "a floating base's log measures the base's orientation: gravity is read in the world's "
                              "axes as declared")
    for table in ("identification", "friction_law", "refinement"):
        if root.has(table):
            raise root.error(table, "reads a fixed base's log: not beside [data.base]")
    if source.identify_constants and not (root.has("floating_log") and root.data["floating_log"].get("rows") == "all"):
        raise t.error("identify_torque_constants", "the constants are read from the base's rows and the joints' "
                                                   "together: give [floating_log] rows = \"all\"")
    return fl
