"""An identified model, written for others to use: the robot's URDF with the identified inertial
parameters and friction, a joints.toml of each joint's friction and rotor inertia, and a model
file that `harness run` loads as any other.

The identified parameters of a link are Pinocchio's ten (m, m c, inertia about the joint point)
in the harness's joint frame: at the joint point, with world axes at q = 0. A URDF's link frame
sits at the same point (its joint's origin) turned by R, the link's orientation at q = 0, which
Pinocchio's own URDF parser gives (oMi of the joint at q = 0). In the link frame:
c_L = R^T h / m and I_c,L = R^T (I_O - m [c]x^T [c]x) R, written as <inertial> with rpy = 0. The
links merged into a body through fixed joints (a hand, a flange) lose their <inertial>: the body's
identified values hold them all. URDF's <dynamics> takes `damping` (viscous) and `friction`
(Coulomb); the rotor inertia, the offset and the Coulomb smoothing velocity have no URDF tag and
are in joints.toml and the model file.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin
import tomli_w

from harness.model.friction import FRICTION_KEYS, JointFriction
from harness.model.inertia import about_centre_of_mass
from harness.model.spec import RobotSpec

URDF_FILE, JOINTS_FILE, MODEL_FILE = "robot.urdf", "joints.toml", "robot.toml"


def link_inertial(theta: np.ndarray, R_WL: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """(m, c_L, I_c,L) in the link frame from the ten parameters in the world-aligned joint frame."""
    m, c_W, I_c_W = about_centre_of_mass(theta)
    return m, R_WL.T @ c_W, R_WL.T @ I_c_W @ R_WL


def _link_rotations(urdf: Path, joints: list[str]) -> dict[str, np.ndarray]:
    model = pin.buildModelFromUrdf(str(urdf))
    data = model.createData()
    pin.forwardKinematics(model, data, pin.neutral(model))
    return {j: data.oMi[model.getJointId(j)].rotation.copy() for j in joints}


def _fmt(v) -> str:
    return " ".join(repr(float(x)) for x in np.ravel(v))


def write_urdf(spec: RobotSpec, theta: np.ndarray, frictions: tuple[JointFriction, ...]) -> str:
    """The model's URDF with every moving body's identified <inertial> and each joint's
    <dynamics damping friction>. theta: (n, 10) in the spec's joint order."""
    tree = ET.parse(spec.urdf)
    root = tree.getroot()
    links = {el.get("name"): el for el in root.findall("link")}
    joints = {el.get("name"): el for el in root.findall("joint")}
    rotations = _link_rotations(spec.urdf, spec.joint_names)
    child_of = {name: el.find("child").get("link") for name, el in joints.items()}
    parent_of = {el.find("child").get("link"): el.find("parent").get("link") for el in joints.values()}
    moving = {child_of[j]: j for j in spec.joint_names}

    def owner(link: str) -> str | None:
        """The moving body a link belongs to: the child of its nearest moving ancestor joint."""
        while link not in moving:
            if link not in parent_of:
                return None
            link = parent_of[link]
        return link

    for name, el in links.items():
        if name in moving or owner(name) is None:
            continue
        for old in el.findall("inertial"):  # merged into its body, whose values hold it
            el.remove(old)
    for k, jname in enumerate(spec.joint_names):
        link = links[child_of[jname]]
        m, c, I_c = link_inertial(theta[k], rotations[jname])
        for old in link.findall("inertial"):
            link.remove(old)
        inertial = ET.Element("inertial")
        ET.SubElement(inertial, "origin", xyz=_fmt(c), rpy="0 0 0")
        ET.SubElement(inertial, "mass", value=repr(float(m)))
        ET.SubElement(inertial, "inertia", **{f"i{'xyz'[i]}{'xyz'[k]}": repr(float(I_c[i, k]))
                                               for i, k in ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))})
        link.insert(0, inertial)
        jel = joints[jname]
        for old in jel.findall("dynamics"):
            jel.remove(old)
        ET.SubElement(jel, "dynamics", damping=repr(float(frictions[k].viscous)),
                      friction=repr(float(frictions[k].coulomb)))
    for jname in spec.urdf_fixed:  # taken as fixed when identified: fixed in the export
        jel = joints[jname]
        jel.set("type", "fixed")
        for tag in ("axis", "limit", "dynamics", "mimic", "safety_controller", "calibration"):
            for old in jel.findall(tag):
                jel.remove(old)
    ET.indent(root)
    return '<?xml version="1.0"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def _joints_table(frictions: tuple[JointFriction, ...], names: list[str]) -> dict:
    return {"joints": {jname: {k: float(getattr(f, k)) for k in FRICTION_KEYS}
                       for jname, f in zip(names, frictions, strict=True)}}


def joints_toml(spec: RobotSpec, frictions: tuple[JointFriction, ...]) -> str:
    """[joints.<name>] armature, viscous, coulomb, offset, coulomb_velocity (SI), as a model file reads
    them (written by tomli-w: every float to the last bit, any joint name quoted as TOML needs)."""
    return tomli_w.dumps(_joints_table(frictions, spec.joint_names))


def model_toml(spec: RobotSpec, frictions: tuple[JointFriction, ...], description: str) -> str:
    """A model file that `harness run` loads: the exported URDF and each joint's friction."""
    comment = "".join(f"# {line}\n" for line in description.splitlines())
    return comment + "\n" + tomli_w.dumps({"model": {"name": f"{spec.name}_identified"}, "urdf": {"file": URDF_FILE},
                                           **_joints_table(frictions, spec.joint_names)})


def export(spec: RobotSpec, theta: np.ndarray, friction_values: np.ndarray, description: str) -> dict[str, str]:
    """{relative path: text} of the exported model; friction_values (n, 4) armature, viscous,
    coulomb, offset; the Coulomb smoothing velocity is the model's."""
    frictions = tuple(JointFriction(*(float(v) for v in row), coulomb_velocity=f.coulomb_velocity)
                      for row, f in zip(friction_values, spec.frictions, strict=True))
    files = {f"identified/{JOINTS_FILE}": joints_toml(spec, frictions)}
    if spec.urdf is not None:
        files[f"identified/{URDF_FILE}"] = write_urdf(spec, theta, frictions)
        files[f"identified/{MODEL_FILE}"] = model_toml(spec, frictions, description)
    return files
