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

from harness.base.tomlio import MAX_XML_BYTES, InputError, Table, read_bounded
from harness.model.friction import JointFriction
from harness.model.inertia import union
from harness.model.spec import FLOATING_BASE_FIXED, WORLD, Body, Joint

KNOWN_ROBOTS = {
    "panda": "panda_description/urdf/panda.urdf",
    "g1": "g1_description/urdf/g1_29dof_rev_1_0.urdf",
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


def rpy_matrix(rpy: np.ndarray) -> np.ndarray:
    """The rotation a URDF <origin rpy> states: R = Rz(yaw) Ry(pitch) Rx(roll) (fixed axes x, y, z)."""
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    Rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    Ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    Rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return Rz @ Ry @ Rx


class _Bad(ValueError):
    """A malformed element: the message names it; read_urdf turns it into an InputError."""


def _numbers(text: str, what: str, count: int | None = None) -> np.ndarray:
    try:
        out = np.array([float(v) for v in text.split()])
    except ValueError:
        raise _Bad(f"{what} = {text!r} is not a list of numbers") from None
    if count is not None and len(out) != count:
        raise _Bad(f"{what} = {text!r} needs {count} numbers")
    if not np.all(np.isfinite(out)):
        raise _Bad(f"{what} = {text!r} is not finite")
    return out


def _origin(el, where: str = "") -> tuple[np.ndarray, np.ndarray]:
    o = el.find("origin") if el is not None else None
    if o is None:
        return np.eye(3), np.zeros(3)
    xyz = _numbers(o.get("xyz", "0 0 0"), f"{where} origin xyz", 3)
    rpy = _numbers(o.get("rpy", "0 0 0"), f"{where} origin rpy", 3)
    return rpy_matrix(rpy), xyz


def _vec(text: str | None, default: str) -> np.ndarray:
    return _numbers(text or default, "axis xyz", 3)


INERTIA_TOL = 1e-9  # relative to the largest principal moment: round-off in a URDF's printed tensor
NO_RIGID_BODY = "are no rigid body's"  # what the note of a link read as the nearest rigid body says


def physical_inertia(name: str, I: np.ndarray, model_scale: float) -> tuple[np.ndarray, str]:
    """A link's tensor about its centre of mass as a rigid body's, and a note where it was not one. A
    rigid body's principal moments p are each at most the sum of the other two (the triangle
    inequality, which implies p >= 0): the cone of p = B y, y >= 0, B's columns (0, 1, 1), (1, 0, 1),
    (1, 1, 0). Moments outside it (beyond INERTIA_TOL of the link's largest) are replaced by the nearest
    inside (Euclidean in p, so Frobenius in the tensor, the principal axes kept): B y for y the
    non-negative least squares of B y = p (scipy.optimize.nnls), every moment then raised by INERTIA_TOL
    of the largest, which leaves each inequality that much slack for an engine's check. A tensor below
    INERTIA_TOL of the model's largest moment is round-off around zero (a link with no rotational
    inertia) and passes as it is. Makers' URDFs carry such tensors (moments rounded, or fitted by CAD
    tools to a shape they do not bound): Pinocchio reads them as written, MuJoCo refuses them, and the
    identification starts from the nearest body that exists."""
    moments, axes = np.linalg.eigh(I)
    scale = float(np.max(np.abs(moments)))
    negative = moments[0] < -INERTIA_TOL * scale
    if scale <= INERTIA_TOL * model_scale or (not negative and (
            moments[2] <= (moments[0] + moments[1]) * (1 + INERTIA_TOL) + INERTIA_TOL * scale)):
        return I, ""
    from scipy.optimize import nnls  # only for a tensor no rigid body has

    B = np.ones((3, 3)) - np.eye(3)
    fixed = B @ nnls(B, moments)[0] + INERTIA_TOL * scale
    why = ("a negative principal moment" if negative
           else "the largest principal moment above the sum of the others (the triangle inequality)")
    note = (f"link {name!r}: principal moments {', '.join(f'{x:.4g}' for x in moments)} kg m^2 {NO_RIGID_BODY} "
            f"({why}): read as the nearest that is, {', '.join(f'{x:.4g}' for x in fixed)} kg m^2 about the same "
            "axes, the prior of its identification")
    return (axes * fixed) @ axes.T, note


def _structure(path: Path, root) -> tuple[dict, list, dict, dict]:
    """Links by name, joints, and each joint's parent and child link, validated: names unique,
    parent and child present and defined, each link the child of at most one joint (so a tree)."""
    links: dict = {}
    for link in root.findall("link"):
        name = link.get("name")
        if not name:
            raise _Bad("a <link> has no name")
        if name in links:
            raise _Bad(f"link {name!r} is defined twice")
        links[name] = link
    joints = root.findall("joint")
    parent_of, child_of = {}, {}
    seen_joints = set()
    for j in joints:
        jname = j.get("name")
        if not jname or jname in seen_joints:
            raise _Bad(f"joint {jname!r} has no name or is defined twice")
        seen_joints.add(jname)
        for tag, into in (("parent", parent_of), ("child", child_of)):
            el = j.find(tag)
            link = el.get("link") if el is not None else None
            if link is None:
                raise _Bad(f"joint {jname!r} has no <{tag} link=...>")
            if link not in links:
                raise _Bad(f"joint {jname!r}: {tag} link {link!r} is not defined")
            into[jname] = link
    children = list(child_of.values())
    twice = sorted({c for c in children if children.count(c) > 1})
    if twice:
        raise _Bad(f"link {twice[0]!r} is the child of two joints (a loop, not a tree)")
    return links, joints, parent_of, child_of


def _dynamics(joint) -> JointFriction:
    """<dynamics damping friction>: viscous and Coulomb friction (a sharp sign, as URDF means it)."""
    d = joint.find("dynamics")
    if d is None:
        return JointFriction()
    where = f"joint {joint.get('name')!r} <dynamics>"
    viscous, coulomb = (float(_numbers(d.get(k, "0"), f"{where} {k}", 1)[0]) for k in ("damping", "friction"))
    for k, v in (("damping", viscous), ("friction", coulomb)):
        if v < 0:
            raise _Bad(f"{where}: {k} = {v:g} is negative")
    return JointFriction(viscous=viscous, coulomb=coulomb)


def read_urdf(path: Path, table: Table, fixed: tuple[str, ...] = (), floating_root: bool = False) -> tuple:
    """Bodies and joints (world frame at q = 0) of a URDF, plus joint position limits by name,
    velocity and effort limits by name ({"velocity": .., "effort": ..}, where given), notes on what
    the reading assumed, and each <mimic> as a coupling of its joint to the one it follows (`_couplings`).
    The joints named in `fixed` are taken as fixed at q = 0 (a gripper's fingers), their bodies merged
    (a mimic joint among them is held, not coupled); and the root link's `floating` joint with the body
    it moves (`_floating_base`, None without; with `floating_root`, the root link floats), which the
    tree takes fixed at the file's pose (said)."""
    content = read_bounded(path, MAX_XML_BYTES)
    try:
        root = ET.fromstring(content)
    except ET.ParseError as exc:
        raise InputError(path, "", f"cannot read URDF ({exc})") from None
    except RecursionError:
        raise InputError(path, "", "cannot read URDF (nested too deeply)") from None
    try:
        return _read(path, root, table, fixed, floating_root)
    except _Bad as exc:
        raise table.error("urdf", f"{path}: {exc}") from None


def _read(path: Path, root, table: Table, fixed: tuple[str, ...], floating_root: bool = False) -> tuple:
    links, joints, parent_of, child_of = _structure(path, root)
    unknown = sorted(set(fixed) - {j.get("name") for j in joints})
    if unknown:
        raise _Bad(f"fixed: no joint {unknown[0]!r} in the URDF")
    children = set(child_of.values())
    roots = [n for n in links if n not in children]
    if len(roots) != 1:
        raise table.error("urdf", f"{path}: expected one root link, found {len(roots)}")
    pose, order = _poses(roots[0], joints, parent_of, child_of)
    inertial = {name: _inertial(name, links[name], pose[name]) for name in order}
    owner, kept = _owners(path, table, order, joints, parent_of, child_of, fixed)
    notes: list[str] = []
    bodies = _bodies(order, owner, inertial, pose, notes)
    floating = _floating_base(order, joints, parent_of, child_of, owner, inertial, pose, floating_root)
    if floating is not None:
        notes.append(f"floating joint {floating.joint!r} of link {floating.body.name!r}: {FLOATING_BASE_FIXED}")
    spec_joints, limits, drive_limits = [], {}, {}
    for j in kept:
        child = child_of[j.get("name")]
        R_c, p_c = pose[child]
        axis = R_c @ _vec(j.find("axis").get("xyz") if j.find("axis") is not None else None, "1 0 0")
        if not np.linalg.norm(axis) > 0:
            raise _Bad(f"joint {j.get('name')!r}: axis is the zero vector")
        jtype = "prismatic" if j.get("type") == "prismatic" else "revolute"
        spec_joints.append(Joint(j.get("name"), jtype, owner[parent_of[j.get("name")]], child, p_c,
                                 axis / np.linalg.norm(axis), _dynamics(j)))
        _limits(j, limits, drive_limits)
    return bodies, spec_joints, limits, drive_limits, notes, _couplings(kept, fixed, notes), floating


ROOT_FLOATING_JOINT = "root_joint"  # a floating root link's free joint (Pinocchio's name for a root joint it adds)


def _floating_base(order: list[str], joints: list, parent_of: dict, child_of: dict, owner: dict, inertial: dict,
                   pose: dict, root: bool = False):
    """The root link's `floating` joint and the rigid body it moves (its child link and every link fixed
    to it), at the file's pose (harness/model/spec.py, FloatingBase); with `root` and no such joint, the
    root link and the links fixed to it, on a free joint named ROOT_FLOATING_JOINT; None otherwise."""
    from harness.model.spec import FloatingBase

    joint = next((j for j in joints if j.get("type") == "floating"), None)
    if joint is not None:
        name, base = joint.get("name"), child_of[joint.get("name")]
    elif root:  # the root link floats (a model file's `floating = true`)
        name, base = ROOT_FLOATING_JOINT, order[0]
    else:
        return None
    link_parent = {child_of[j.get("name")]: parent_of[j.get("name")] for j in joints}

    def on_base(link: str) -> bool:
        while owner[link] == WORLD:
            if link == base:
                return True
            if link == order[0]:
                return False
            link = link_parent[link]
        return False

    parts = [inertial[n] for n in order if on_base(n)]
    if not sum(p[0] for p in parts) > 0:
        raise _Bad(f"floating joint {name!r}: its link {base!r} and those fixed to it have no mass" if joint is not None
                   else f"floating = true: the root link {base!r} and those fixed to it have no mass (a floating "
                        "base is a body; a root link named for the world is not one)")
    mass, com, moments, axes = union(parts)
    on_it = tuple(j.get("name") for j in joints if j.get("type") in ("revolute", "continuous", "prismatic")
                  and owner.get(child_of[j.get("name")]) != WORLD and on_base(parent_of[j.get("name")]))
    return FloatingBase(name, Body(base, mass, np.diag(moments), axes, com), *pose[base], on_it)


def _couplings(kept: list, fixed: tuple[str, ...], notes: list[str]) -> tuple:
    """Each kept joint's <mimic joint multiplier offset> as a coupling (harness/model/loops.py):
    q_joint = multiplier q_mimicked + offset (defaults 1 and 0); one that names no moving joint is a joint
    of its own, said in `notes`."""
    from harness.model.spec import Loop

    names = {j.get("name") for j in kept}
    out = []
    for j in kept:
        m = j.find("mimic")
        if m is None:
            continue
        name, leader = j.get("name"), m.get("joint")
        where = f"joint {name!r} <mimic>"
        if leader in fixed:
            raise _Bad(f"{where}: it follows {leader!r}, which [urdf] fixed holds at 0: fix {name!r} too")
        if leader not in names:  # a reference the file cannot resolve: nothing to couple to, said
            notes.append(f"joint {name!r} mimics {leader!r}, which is not a moving joint of the URDF: read as a joint "
                         "of its own")
            continue
        if leader == name:
            raise _Bad(f"{where}: the joint follows itself")
        ratio = float(_numbers(m.get("multiplier", "1"), f"{where} multiplier", 1)[0])
        offset = float(_numbers(m.get("offset", "0"), f"{where} offset", 1)[0])
        if ratio == 0.0:
            raise _Bad(f"{where}: multiplier = 0 holds the joint, not couples it: list it in [urdf] fixed")
        out.append(Loop.coupling(f"mimic_{name}", name, leader, ratio, offset))
    return tuple(out)


def _poses(root: str, joints: list, parent_of: dict, child_of: dict) -> tuple[dict, list[str]]:
    """Every link's world pose at q = 0, (R, p), and the links in breadth-first order from the root."""
    pose = {root: (np.eye(3), np.zeros(3))}
    order = [root]
    by_parent: dict[str, list] = {}
    for j in joints:
        by_parent.setdefault(parent_of[j.get("name")], []).append(j)
    frontier = [root]
    while frontier:
        parent = frontier.pop(0)
        for j in by_parent.get(parent, []):
            R_j, p_j = _origin(j, f"joint {j.get('name')!r}")
            R_p, p_p = pose[parent]
            child = child_of[j.get("name")]
            pose[child] = (R_p @ R_j, p_p + R_p @ p_j)
            order.append(child)
            frontier.append(child)
    return pose, order


def _inertial(name: str, link, pose: tuple[np.ndarray, np.ndarray]) -> tuple[float, np.ndarray, np.ndarray]:
    """A link's inertia in the world frame at q = 0: mass, centre of mass, tensor about the centre of
    mass. A link of zero mass keeps its rotational inertia: merged into its body, it adds to it."""
    el = link.find("inertial")
    if el is None:
        return 0.0, pose[1], np.zeros((3, 3))
    mass_el = el.find("mass")
    mass = _numbers(mass_el.get("value", "") if mass_el is not None else "0", f"link {name!r} mass", 1)[0]
    if mass < 0:
        raise _Bad(f"link {name!r}: mass {mass:g} is negative")
    R_l, p_l = pose
    R_i, p_i = _origin(el, f"link {name!r} inertial")
    i = el.find("inertia")
    values = [_numbers(i.get(k, "0"), f"link {name!r} inertia {k}", 1)[0] if i is not None else 0.0
              for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")]
    Ixx, Ixy, Ixz, Iyy, Iyz, Izz = values
    I_local = np.array([[Ixx, Ixy, Ixz], [Ixy, Iyy, Iyz], [Ixz, Iyz, Izz]])
    R = R_l @ R_i
    return float(mass), p_l + R_l @ p_i, R @ I_local @ R.T


def _owners(path: Path, table: Table, order: list[str], joints: list, parent_of: dict, child_of: dict,
            fixed: tuple[str, ...]) -> tuple[dict[str, str], list]:
    """Each link's body, the link of its nearest non-fixed ancestor joint (merging along fixed joints
    and those listed in `fixed`), and the joints kept as the robot's, in order."""
    owner = {order[0]: WORLD}
    kept = []
    joint_of = {child: j for j in joints for child in [child_of[j.get("name")]]}
    for name in order[1:]:
        j = joint_of[name]
        parent = parent_of[j.get("name")]
        if j.get("type") == "fixed" or j.get("name") in fixed:
            owner[name] = owner[parent]
        elif j.get("type") in ("revolute", "continuous", "prismatic"):
            owner[name] = name
            kept.append(j)
        elif j.get("type") == "floating" and parent == order[0]:  # the base: on the ground for a fixed reading
            owner[name] = WORLD
        else:
            raise table.error("urdf", f"{path}: joint {j.get('name')!r} has type {j.get('type')!r} "
                                      + ("below the root link (a floating base is the root link's child)"
                                         if j.get("type") == "floating" else
                                         "(revolute, continuous, prismatic, fixed and, from the root link, floating "
                                         "are supported)"))
    return owner, kept


def _bodies(order: list[str], owner: dict, inertial: dict, pose: dict, notes: list[str]) -> list[Body]:
    """The moving bodies, each the union of the links it owns, every moving link's tensor a rigid
    body's (`physical_inertia`, its note added to `notes`; the links of the ground never move: their
    inertia, consistent or not, enters nothing)."""
    groups: dict[str, list[str]] = {}
    model_scale = max((float(np.max(np.abs(np.linalg.eigvalsh(inertial[n][2])))) for n in order), default=0.0)
    inertial = dict(inertial)
    for name in order[1:]:
        if owner[name] != WORLD:
            groups.setdefault(owner[name], []).append(name)
            m, c, I = inertial[name]
            I, note = physical_inertia(name, I, model_scale)
            inertial[name] = (m, c, I)
            notes += [note] if note else []
    bodies = []
    for body_name, members in groups.items():
        m = sum(inertial[n][0] for n in members)
        if m <= 0:
            if any(np.any(inertial[n][2]) for n in members):
                raise _Bad(f"link {body_name!r} moves with rotational inertia but no mass (no engine takes it)")
            bodies.append(Body(body_name, 0.0, np.zeros((3, 3)), np.eye(3), pose[body_name][1]))
            continue
        _, com, moments, axes = union([inertial[n] for n in members])
        # every link is a rigid body's (physical_inertia): a moment below zero here is round-off of a link with
        # no rotational inertia (the iCub's -5e-20 kg m^2), which Pinocchio refuses as written
        bodies.append(Body(body_name, m, np.diag(np.maximum(moments, 0.0)), axes, com))
    return bodies


def _limits(j, limits: dict, drive_limits: dict) -> None:
    """A joint's position limits (not a continuous joint's) into `limits`, its velocity and effort
    limits into `drive_limits`, by its name."""
    lim = j.find("limit")
    if lim is None:
        return
    if j.get("type") != "continuous":
        try:
            lower, upper = float(lim.get("lower", "-inf")), float(lim.get("upper", "inf"))
        except ValueError:
            raise _Bad(f"joint {j.get('name')!r}: limit lower/upper are not numbers") from None
        if np.isnan(lower) or np.isnan(upper) or lower > upper:
            raise _Bad(f"joint {j.get('name')!r}: limit lower={lim.get('lower')!r} upper={lim.get('upper')!r} "
                       "is no range (lower above upper, or not a number)")
        limits[j.get("name")] = (lower, upper)
    rates = {}  # URDF's velocity and effort limits (of continuous joints too)
    for key in ("velocity", "effort"):
        if lim.get(key) is not None:
            value = _numbers(lim.get(key), f"joint {j.get('name')!r} limit {key}", 1)[0]
            if value > 0:  # 0 is URDF's way of saying none
                rates[key] = float(value)
    if rates:
        drive_limits[j.get("name")] = rates
