"""Pinocchio's own parsers of a robot file (`buildModelFromUrdf`, `buildModelFromMJCF`): the reading
that shares none of the harness's, which `harness audit` compares the harness's with, and the model
`harness init`'s placeholder computes with.

Pinocchio 4.1's MJCF parser reads less of a file than MuJoCo compiles, in ways that change no
dynamics; what it is given is the file with those parts made readable, each said in the notes:
- `<include>` files written in place (relative to the robot file's folder, as MuJoCo finds them);
- `<keyframe>` left out: its parser checks a keyframe's size against a model of its own, which
  differs from MuJoCo's where the file has a free joint ("Keyframe size does not match model size");
- several bodies under `<worldbody>` put under one massless body at the world's origin: its parser
  reads the first and drops the rest (a four-bar's rocker, a humanoid's second tree);
- a body of several joints written as nested bodies at its frame, one joint each, the last holding the
  body's inertial, geoms and children (MuJoCo applies a body's joints in order, each after the ones
  before it: the same chain); its parser would make them one composite joint named otherwise;
- a free joint held at the file's pose, as the harness holds it (an MJCF body's pose is its free-flyer's
  configuration, MuJoCo's qpos0, not its neutral one; a URDF floating joint's is its origin): the joints
  that remain are the harness's. With `free`, the free-flyer is kept;
- with `ball_hinges`, a `type="ball"` joint written as the three hinges `<ball>_x .. _z` about its body's axes,
  as the harness reads it (harness/model/mjcf.py; nested bodies, as above): its joints are then the
  harness's. Without, it is Pinocchio's spherical joint (a quaternion: what `harness audit` compares with).
A file it still cannot read raises its own error (a ValueError or RuntimeError with its message).
"""

from __future__ import annotations

import itertools
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin

from harness.base.tomlio import MAX_XML_BYTES, read_bounded

ROOT_BODY = "pinocchio_reading_root"  # the body that takes a file's root bodies (Pinocchio reads the first alone)
MAX_INCLUDES = 100  # nested or repeated includes beyond this: a file that includes itself


def parse(path: Path, free: bool = False, ball_hinges: bool = False) -> tuple[pin.Model, list[str]]:
    """Pinocchio's model of the URDF or MJCF file at `path` (told by its root element, <robot> or
    <mujoco>), with every free joint held at the file's pose (with `free`, kept: a floating base's
    free-flyer, placed where the file draws the base), a ball joint as the harness's three hinges with
    `ball_hinges` (the module docstring), and what was done to let its parser read the file, one line each."""
    root = ET.fromstring(read_bounded(path, MAX_XML_BYTES))
    notes = []
    if root.tag != "mujoco":
        model = pin.buildModelFromUrdf(str(path))  # a `floating` joint: its free-flyer
    else:
        notes = _readable(root, Path(path).parent, _ball_names(path) if ball_hinges else set())
        with tempfile.TemporaryDirectory() as folder:  # meshes are not read: the model's inertias are its own
            copy = Path(folder) / Path(path).name
            copy.write_text(ET.tostring(root, encoding="unicode"))
            model = pin.buildModelFromMJCF(str(copy))
    flyers = [j for j in range(1, model.njoints) if model.joints[j].shortname() == "JointModelFreeFlyer"]
    if flyers and not free:
        notes.append(f"free joint {', '.join(repr(model.names[j]) for j in flyers)} held at the file's pose, as the "
                     "harness holds it")
        model = pin.buildReducedModel(model, flyers, _at_the_files_pose(model, flyers, path, root.tag))
    return model, notes


def _at_the_files_pose(model: pin.Model, flyers: list[int], path: Path, tag: str):
    """Pinocchio's configuration with each free-flyer where the file draws its body: a URDF's floating
    joint at its origin (the free-flyer's placement: its neutral configuration), an MJCF free joint at
    MuJoCo's qpos0 (the body's pose, which Pinocchio's MJCF parser leaves to the free-flyer's
    configuration: its neutral one is the world's origin and axes)."""
    q = pin.neutral(model)
    if tag != "mujoco":
        return q
    import mujoco

    mj = mujoco.MjModel.from_xml_path(str(path))
    for j in flyers:
        k = mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_JOINT, model.names[j])
        if k < 0:  # an unnamed free joint: MuJoCo's only one
            k = int(next(i for i in range(mj.njnt) if mj.jnt_type[i] == mujoco.mjtJoint.mjJNT_FREE))
        p, w = mj.qpos0[mj.jnt_qposadr[k]:mj.jnt_qposadr[k] + 3], mj.qpos0[mj.jnt_qposadr[k] + 3:mj.jnt_qposadr[k] + 7]
        pose = pin.SE3(pin.Quaternion(w[0], w[1], w[2], w[3]).matrix(), p)
        at = model.joints[j].idx_q
        q[at:at + 7] = pin.SE3ToXYZQUAT(model.jointPlacements[j].inverse() * pose)
    return q


def _readable(root: ET.Element, folder: Path, balls: set[str] = frozenset()) -> list[str]:
    """The MJCF tree `root` made readable by Pinocchio's parser in place (the module docstring); what
    was done, one line each."""
    notes, count = [], 0
    while (found := _first_include(root)) is not None:
        parent, at, element = found
        count += 1
        if count > MAX_INCLUDES:
            raise ValueError(f"over {MAX_INCLUDES} <include> elements: a file that includes itself?")
        included = ET.fromstring(read_bounded(folder / element.get("file", ""), MAX_XML_BYTES))
        parent.remove(element)
        for k, child in enumerate(list(included)):
            parent.insert(at + k, child)
    if count:
        notes.append(f"{count} <include> file(s) written in place")
    for parent in [p for p in root.iter() if p.find("keyframe") is not None]:
        for key in parent.findall("keyframe"):
            parent.remove(key)
        notes.append("<keyframe> left out (Pinocchio's parser sizes it against a model of its own)")
    world = root.find("worldbody")
    bodies = [] if world is None else world.findall("body")
    if len(bodies) > 1:
        holder = ET.Element("body", {"name": ROOT_BODY})
        for b in bodies:
            world.remove(b)
            holder.append(b)
        world.append(holder)
        notes.append(f"its {len(bodies)} root bodies put under one massless body (Pinocchio's parser reads the first "
                     "alone)")
    if balls:
        notes += _balls_as_hinges(root, balls)
    chains = 0
    for body in list(root.iter("body")):
        joints = body.findall("joint")
        if len(joints) < 2:
            continue
        chains += 1
        rest = [c for c in body if c.tag != "joint"]
        for c in list(body):
            if c is not joints[0]:
                body.remove(c)
        holder = body
        for before, joint in itertools.pairwise(joints):
            holder = ET.SubElement(holder, "body", {"name": f"{body.get('name', 'body')}[{before.get('name', '')}]"})
            holder.append(joint)
        for c in rest:
            holder.append(c)
    if chains:
        notes.append(f"{chains} body(ies) of several joints written as nested bodies, one joint each (its parser "
                     "makes them one composite joint of another name)")
    return notes


def _ball_names(path: Path) -> set[str]:
    """The names of the MJCF file's ball joints as MuJoCo compiles it (a joint's type may come from a
    default class)."""
    import mujoco

    model = mujoco.MjModel.from_xml_path(str(path))
    return {model.joint(i).name for i in range(model.njnt) if model.jnt_type[i] == mujoco.mjtJoint.mjJNT_BALL}


def _balls_as_hinges(root: ET.Element, balls: set[str]) -> list[str]:
    """Each `<joint>` of the tree named in `balls` replaced, in place, by the hinges about its body's axes in
    the harness's order and names (harness/model/mjcf.py, BALL_AXES), at its `pos`."""
    from harness.model.mjcf import BALL_AXES

    count = 0
    for body in root.iter("body"):
        for k, joint in [(k, c) for k, c in enumerate(body) if c.tag == "joint" and c.get("name") in balls][::-1]:
            body.remove(joint)
            for a, axis in reversed(list(enumerate(BALL_AXES))):
                hinge = {"name": f"{joint.get('name', '')}_{axis}", "type": "hinge",
                         "axis": " ".join("1" if b == a else "0" for b in range(3))}
                body.insert(k, ET.Element("joint", hinge | ({"pos": joint.get("pos")} if joint.get("pos") else {})))
            count += 1
    return [f"{count} ball joint(s) written as the harness's three hinges about the body's axes"] if count else []


def _first_include(root: ET.Element) -> tuple[ET.Element, int, ET.Element] | None:
    for parent in root.iter():
        for k, child in enumerate(parent):
            if child.tag == "include":
                return parent, k, child
    return None


def free_inverse_dynamics(path: Path, free_joint: str, joints: list[str], gravity_W: np.ndarray, base, q: np.ndarray,
                          qd: np.ndarray, qdd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pinocchio's own parse of the robot file with its free-flyer `free_joint` kept (a URDF whose root
    link is the floating base: the free-flyer Pinocchio puts on it), rigid bodies (no armature), at the
    states (base, q, q', q''), base a harness.model.floating.BaseMotion and q (N, n) in the order of
    `joints`: the world's wrench on the base [F_W, M_W] (N, 6, harness/model/floating.py) and the joints'
    torques (N, n). The free-flyer's configuration is its placement's inverse times the base's pose;
    its velocities are the base's, in base axes."""
    from harness.model.floating import base_rows_from_pinocchio, to_pinocchio
    from harness.model.urdf import ROOT_FLOATING_JOINT

    model, _ = parse(path, free=True, ball_hinges=True)
    if not model.existJointName(free_joint) and free_joint == ROOT_FLOATING_JOINT:
        model = pin.buildModelFromUrdf(str(path), pin.JointModelFreeFlyer())  # a model file's floating root link
    model.gravity.linear = np.asarray(gravity_W, dtype=float)
    model.armature[:] = 0.0
    data = model.createData()
    flyer = model.getJointId(free_joint)
    if flyer >= model.njoints or model.joints[flyer].shortname() != "JointModelFreeFlyer":
        raise ValueError(f"Pinocchio's parser has no free-flyer {free_joint!r}")
    placement, fj = model.jointPlacements[flyer], model.joints[flyer]
    moved = [model.joints[model.getJointId(j)] for j in joints]
    R = base.R_WB
    tau_base, tau = np.empty((len(q), 6)), np.empty_like(q)
    _, v_ff, a_ff = to_pinocchio(base)  # velocities in base axes: the same in its free-flyer
    for k in range(len(q)):
        qq, vv, aa = pin.neutral(model), np.zeros(model.nv), np.zeros(model.nv)
        qq[fj.idx_q:fj.idx_q + 7] = pin.SE3ToXYZQUAT(placement.inverse() * pin.SE3(R[k], base.p_W[k]))
        vv[fj.idx_v:fj.idx_v + 6], aa[fj.idx_v:fj.idx_v + 6] = v_ff[k], a_ff[k]
        for j, jm in enumerate(moved):
            qq[jm.idx_q:jm.idx_q + jm.nq] = [np.cos(q[k, j]), np.sin(q[k, j])] if jm.nq == 2 else q[k, j]
            vv[jm.idx_v], aa[jm.idx_v] = qd[k, j], qdd[k, j]
        full = pin.rnea(model, data, qq, vv, aa)
        tau_base[k] = full[fj.idx_v:fj.idx_v + 6]
        tau[k] = [full[jm.idx_v] for jm in moved]
    return base_rows_from_pinocchio(base, tau_base), tau
