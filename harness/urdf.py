"""Robots from URDF files into a RobotSpec.

Revolute (and continuous), prismatic and fixed joints; a fixed joint merges its child into its
parent (masses add, centres of mass combine, inertias move by the parallel-axis theorem). The
root link and everything fixed to it are the ground. Each body's frame is placed at its centre of
mass along the principal axes of its inertia tensor (the paper's convention, Eq. 24), so full,
non-diagonal URDF tensors enter as principal moments in a rotated frame. Meshes are never read.

`robot = "panda"` names a robot of the `example-robot-data` package (an optional extra), found in
its installed data without any network access; `file = "..."` names a URDF file.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from importlib.metadata import PackageNotFoundError, distribution
from pathlib import Path

import numpy as np

from harness.spec import WORLD, Body, Joint
from harness.tomlio import InputError, Table

KNOWN_ROBOTS = {
    "panda": "panda_description/urdf/panda.urdf",
    "ur5": "ur_description/urdf/ur5_robot.urdf",
    "ur3": "ur_description/urdf/ur3_robot.urdf",
    "ur10": "ur_description/urdf/ur10_robot.urdf",
    "z1": "z1_description/urdf/z1.urdf",
    "xarm": "xarm_description/urdf/xarm7.urdf",
}


def example_robot_data_path(name: str) -> Path | None:
    """The URDF of a robot of the example-robot-data package, or None if it is not installed."""
    try:
        dist = distribution("example-robot-data")
    except PackageNotFoundError:
        return None
    root = Path(dist.locate_file("cmeel.prefix/share/example-robot-data/robots"))
    rel = KNOWN_ROBOTS.get(name)
    if rel is not None and (root / rel).is_file():
        return root / rel
    for folder in ("urdf", "robots"):  # the package keeps robots in both
        candidates = sorted(root.glob(f"*/{folder}/{name}.urdf"))
        if candidates:
            return candidates[0]
    return None


def _rpy(rpy: np.ndarray) -> np.ndarray:
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    Rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    Ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    Rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return Rz @ Ry @ Rx


def _origin(el) -> tuple[np.ndarray, np.ndarray]:
    o = el.find("origin") if el is not None else None
    if o is None:
        return np.eye(3), np.zeros(3)
    xyz = np.array([float(v) for v in o.get("xyz", "0 0 0").split()])
    rpy = np.array([float(v) for v in o.get("rpy", "0 0 0").split()])
    return _rpy(rpy), xyz


def _vec(text: str | None, default: str) -> np.ndarray:
    return np.array([float(v) for v in (text or default).split()])


def read_urdf(path: Path, table: Table) -> tuple[list[Body], list[Joint], dict]:
    """Bodies and joints (world frame at q = 0) of a URDF, plus joint limits by name."""
    try:
        root = ET.parse(path).getroot()
    except (OSError, ET.ParseError) as exc:
        raise InputError(path, "", f"cannot read URDF ({exc})") from None
    links = {link.get("name"): link for link in root.findall("link")}
    joints = root.findall("joint")
    children = {j.find("child").get("link") for j in joints}
    roots = [n for n in links if n not in children]
    if len(roots) != 1:
        raise table.error("urdf", f"{path}: expected one root link, found {len(roots)}")
    # world pose of every link at q = 0
    pose = {roots[0]: (np.eye(3), np.zeros(3))}
    order = [roots[0]]
    by_parent: dict[str, list] = {}
    for j in joints:
        by_parent.setdefault(j.find("parent").get("link"), []).append(j)
    frontier = [roots[0]]
    while frontier:
        parent = frontier.pop(0)
        for j in by_parent.get(parent, []):
            R_j, p_j = _origin(j)
            R_p, p_p = pose[parent]
            child = j.find("child").get("link")
            pose[child] = (R_p @ R_j, p_p + R_p @ p_j)
            order.append(child)
            frontier.append(child)

    # inertia of every link at the world frame, at q = 0: mass, CoM, tensor about the CoM
    inertial = {}
    for name in order:
        el = links[name].find("inertial")
        if el is None or el.find("mass") is None or float(el.find("mass").get("value")) <= 0:
            inertial[name] = (0.0, pose[name][1], np.zeros((3, 3)))
            continue
        R_l, p_l = pose[name]
        R_i, p_i = _origin(el)
        i = el.find("inertia")
        Ixx, Ixy, Ixz, Iyy, Iyz, Izz = (float(i.get(k, "0")) for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz"))
        I_local = np.array([[Ixx, Ixy, Ixz], [Ixy, Iyy, Iyz], [Ixz, Iyz, Izz]])
        R = R_l @ R_i
        inertial[name] = (float(el.find("mass").get("value")), p_l + R_l @ p_i, R @ I_local @ R.T)

    # merge along fixed joints: each link belongs to the body of its nearest non-fixed ancestor joint
    owner = {roots[0]: WORLD}
    kept = []
    for name in order[1:]:
        j = next(j for j in joints if j.find("child").get("link") == name)
        parent = j.find("parent").get("link")
        if j.get("type") == "fixed":
            owner[name] = owner[parent]
        elif j.get("type") in ("revolute", "continuous", "prismatic"):
            owner[name] = name
            kept.append(j)
        else:
            raise table.error("urdf", f"{path}: joint {j.get('name')!r} has type {j.get('type')!r} "
                                      "(revolute, continuous, prismatic and fixed are supported)")
    groups: dict[str, list[str]] = {}
    for name in order[1:]:
        if owner[name] != WORLD:
            groups.setdefault(owner[name], []).append(name)

    bodies = []
    for body_name, members in groups.items():
        m = sum(inertial[n][0] for n in members)
        if m <= 0:
            bodies.append(Body(body_name, 0.0, np.zeros((3, 3)), np.eye(3), pose[body_name][1]))
            continue
        com = sum(inertial[n][0] * inertial[n][1] for n in members) / m
        I = np.zeros((3, 3))
        for n in members:
            mi, ci, Ii = inertial[n]
            d = ci - com
            I += Ii + mi * (d @ d * np.eye(3) - np.outer(d, d))
        moments, axes = np.linalg.eigh(I)
        if np.linalg.det(axes) < 0:
            axes[:, 2] *= -1
        bodies.append(Body(body_name, m, np.diag(moments), axes, com))

    spec_joints, limits = [], {}
    for j in kept:
        child = j.find("child").get("link")
        parent = owner[j.find("parent").get("link")]
        R_c, p_c = pose[child]
        axis = R_c @ _vec(j.find("axis").get("xyz") if j.find("axis") is not None else None, "1 0 0")
        jtype = "prismatic" if j.get("type") == "prismatic" else "revolute"
        spec_joints.append(Joint(j.get("name"), jtype, parent, child, p_c, axis / np.linalg.norm(axis)))
        lim = j.find("limit")
        if lim is not None and j.get("type") != "continuous":
            limits[j.get("name")] = (float(lim.get("lower", "-inf")), float(lim.get("upper", "inf")))
    return bodies, spec_joints, limits
