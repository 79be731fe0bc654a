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
are in joints.toml and the model file. With drives (harness/model/drives.py: motors behind the joints
through a transmission N) no joint has friction of its own: drives.toml holds N, the motors' offsets
and each motor's law, as a model file's `[drives]` reads them, and the URDF has no <dynamics>.
"""

from __future__ import annotations

import dataclasses
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin
import tomli_w

from harness.model import friction
from harness.model.friction import FRICTION_KEYS, JointFriction
from harness.model.inertia import about_centre_of_mass
from harness.model.spec import RobotSpec

URDF_FILE, JOINTS_FILE, MODEL_FILE, MJCF_FILE, README_FILE = "robot.urdf", "joints.toml", "robot.toml", "robot.xml", \
    "README.md"
DRIVES_FILE = "drives.toml"
LEAST_SQUARES_FILE = "least_squares.toml"  # the least-squares fit (harness/identify/ls_model.py)


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


def write_urdf(spec: RobotSpec, theta: np.ndarray, frictions: tuple[JointFriction, ...],
               base_theta: np.ndarray | None = None) -> str:
    """The model's URDF with every moving body's identified <inertial> and each joint's
    <dynamics damping friction>. theta: (n, 10) in the spec's joint order. With `base_theta` (10,), a
    floating base's (in its link's frame, about its origin: harness/identify/floating_id.py): its link's
    <inertial> too, the links fixed to it without theirs, and a `floating` joint from a `world` link
    where the file has none (named as the harness names a model file's floating root link)."""
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
        if name in moving or (owner(name) is None and base_theta is None):
            continue
        for old in el.findall("inertial"):  # merged into its body (or the floating base), whose values hold it
            el.remove(old)
    if base_theta is not None:
        _floating_base(root, links[spec.floating.body.name], base_theta)
    for k, jname in enumerate(spec.joint_names):
        link = links[child_of[jname]]
        for old in link.findall("inertial"):
            link.remove(old)
        link.insert(0, _inertial(*link_inertial(theta[k], rotations[jname])))
        jel = joints[jname]
        for old in jel.findall("dynamics"):
            jel.remove(old)
        if spec.transmission is None:  # with drives, the motors' laws are in drives.toml
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


def _inertial(m: float, c: np.ndarray, I_c: np.ndarray) -> ET.Element:
    inertial = ET.Element("inertial")
    ET.SubElement(inertial, "origin", xyz=_fmt(c), rpy="0 0 0")
    ET.SubElement(inertial, "mass", value=repr(float(m)))
    ET.SubElement(inertial, "inertia", **{f"i{'xyz'[i]}{'xyz'[k]}": repr(float(I_c[i, k]))
                                           for i, k in ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))})
    return inertial


def _floating_base(root: ET.Element, link: ET.Element, theta: np.ndarray) -> None:
    """The floating base's link given its identified inertial (theta in its own frame), and the URDF a
    `floating` joint from a `world` link to it where it has none."""
    from harness.model.urdf import ROOT_FLOATING_JOINT

    link.insert(0, _inertial(*about_centre_of_mass(theta)))
    if any(j.get("type") == "floating" for j in root.findall("joint")):
        return
    root.insert(0, ET.Element("link", name="world"))
    joint = ET.Element("joint", name=ROOT_FLOATING_JOINT, type="floating")
    ET.SubElement(joint, "parent", link="world")
    ET.SubElement(joint, "child", link=link.get("name"))
    root.insert(1, joint)


def _joints_table(frictions: tuple[JointFriction, ...], names: list[str]) -> dict:
    return {"joints": {jname: {k: float(getattr(f, k)) for k in FRICTION_KEYS}
                       for jname, f in zip(names, frictions, strict=True)}}


def drives_table(spec: RobotSpec, frictions: tuple[JointFriction, ...]) -> dict:
    """A model file's `[drives]` (harness/model/drive_tables.py, read_drives): the motors, N whole, their
    offsets and each motor's law."""
    t = spec.transmission
    return {"drives": {"motors": list(t.motors), "transmission": [[float(x) for x in row] for row in t.N],
                       "offset": [float(x) for x in t.offset],
                       **{m: {k: float(getattr(f, k)) for k in FRICTION_KEYS}
                          for m, f in zip(t.motors, frictions, strict=True)}}}


def _drive_tables(spec: RobotSpec, frictions: tuple[JointFriction, ...]) -> dict:
    """The drives' laws as a model file states them: per joint, or with a transmission per motor."""
    return _joints_table(frictions, spec.joint_names) if spec.transmission is None else drives_table(spec, frictions)


def joints_toml(spec: RobotSpec, frictions: tuple[JointFriction, ...]) -> str:
    """[joints.<name>] armature, viscous, coulomb, offset, coulomb_velocity (SI), as a model file reads
    them (written by tomli-w: every float to the last bit, any joint name quoted as TOML needs)."""
    return tomli_w.dumps(_joints_table(frictions, spec.joint_names))


def model_toml(spec: RobotSpec, frictions: tuple[JointFriction, ...], description: str,
               gravity_W: np.ndarray | None = None) -> str:
    """A model file that `harness run` loads: the exported URDF, each joint's friction and, where given,
    the gravity the parameters were identified at ([model] gravity: a base off level, which a URDF cannot
    hold)."""
    comment = "".join(f"# {line}\n" for line in description.splitlines())
    model = {"name": f"{spec.name}_identified"}
    if gravity_W is not None:
        model["gravity"] = [float(g) for g in gravity_W]
    return comment + "\n" + tomli_w.dumps({"model": model, "urdf": {"file": URDF_FILE},
                                           **_drive_tables(spec, frictions)})


def export(spec: RobotSpec, theta: np.ndarray, frictions: tuple[JointFriction, ...],
           description: str, gravity_W: np.ndarray | None = None) -> dict[str, str]:
    """{relative path: text} of the exported model: theta (n, 10) each joint's body, `frictions` each
    joint's whole friction law. The MJCF file and the README are added by the caller
    (harness/model/mjcf.py writes MJCF; `readme`)."""
    files = ({f"identified/{JOINTS_FILE}": joints_toml(spec, frictions)} if spec.transmission is None else
             {f"identified/{DRIVES_FILE}": tomli_w.dumps(drives_table(spec, frictions))})
    if spec.urdf is not None:
        files[f"identified/{URDF_FILE}"] = write_urdf(spec, theta, frictions)
        files[f"identified/{MODEL_FILE}"] = model_toml(spec, frictions, description, gravity_W)
    return files


def identified_spec(spec: RobotSpec, theta: np.ndarray, frictions: tuple[JointFriction, ...]) -> RobotSpec:
    """The robot with the identified parameters: each joint's child body from its ten parameters
    theta[k] (in the joint frame: at the joint point, world axes at q = 0), centre of mass
    p_J + h / m, principal moments and axes of the inertia about it; each joint's friction law
    `frictions[k]`. The geometry of the joints is the model's."""
    bodies = {b.name: b for b in spec.bodies}
    for k, joint in enumerate(spec.joints):
        m, c_J, I_c = about_centre_of_mass(theta[k])
        moments, axes = np.linalg.eigh((I_c + I_c.T) / 2)
        if np.linalg.det(axes) < 0:
            axes[:, 2] *= -1
        bodies[joint.child] = dataclasses.replace(bodies[joint.child], mass=m, I_B=np.diag(moments), R_WB0=axes,
                                                  p_W_com0=joint.p_W0 + c_J, cylinder=None)
    return dataclasses.replace(spec.with_frictions(frictions), name=f"{spec.name}_identified",
                               bodies=tuple(bodies[b.name] for b in spec.bodies))


def identified_floating_spec(spec: RobotSpec, theta: np.ndarray, frictions: tuple[JointFriction, ...]) -> RobotSpec:
    """A floating robot with the identified parameters: theta (1 + n, 10) the base's body (in its frame F,
    about F's origin, as harness/identify/floating_id.py fits it) and then each joint's (`identified_spec`)."""
    fb = spec.floating
    m, c_F, I_c_F = about_centre_of_mass(theta[0])
    I_W = fb.R_WF0 @ I_c_F @ fb.R_WF0.T
    moments, axes = np.linalg.eigh((I_W + I_W.T) / 2)
    if np.linalg.det(axes) < 0:
        axes[:, 2] *= -1
    body = dataclasses.replace(fb.body, mass=m, I_B=np.diag(moments), R_WB0=axes, p_W_com0=fb.p_WF0 + fb.R_WF0 @ c_F,
                               cylinder=None)
    return dataclasses.replace(identified_spec(spec, theta[1:], frictions), floating=dataclasses.replace(fb, body=body))


def coulomb_mapping(spec: RobotSpec, qd: np.ndarray, tau: np.ndarray,
                    tau_rigid: np.ndarray | None = None) -> dict[str, dict[str, float]]:
    """Per joint, what MuJoCo's dry friction (`frictionloss` = f_c, a sharp sign) changes of the
    identified law's dry part (friction.Dry: f_c s + f_o and the families' terms, the viscous part
    being MuJoCo's damping), at the velocities qd (N, n) of torques tau (N, n) (tau_rigid, the
    rigid-body torques, for a load-dependent law): the gap |f_c sign(q') - dry(q')|, its largest
    value over the largest |tau| (at a velocity reversal) and its RMS over the RMS torque."""
    t = spec.transmission
    if t is not None:  # a motor's friction, at its rates, against its torque (with drives: per motor)
        qd, tau = t.motor_rates(qd), t.motor_torques(tau)
        tau_rigid = None if tau_rigid is None else t.motor_torques(tau_rigid)
    coulomb = np.array([f.coulomb for f in spec.frictions])
    # a spring is MuJoCo's own (`stiffness`): the law's dry part without it (its position term at q = 0)
    gap = np.abs(coulomb * np.sign(qd) - friction.dry(spec.frictions, qd, tau_rigid, q=np.zeros_like(qd)))
    out = {}
    for k, name in enumerate(spec.drive_names):
        largest, rms = float(np.max(np.abs(tau[:, k]))), float(np.sqrt(np.mean(tau[:, k] ** 2)))
        out[name] = {"largest": float(np.max(gap[:, k])) / largest if largest > 0 else float("nan"),
                     "rms": float(np.sqrt(np.mean(gap[:, k] ** 2))) / rms if rms > 0 else float("nan")}
    return out


def readme(spec: RobotSpec, files: list[str], mapping: dict[str, dict[str, float]] | None, description: str,
           mjcf_refused: str | None = None) -> str:
    """identified/README.md: what each exported file holds and what a consumer of one alone loses;
    `mjcf_refused`, why there is no MJCF file."""
    lines = [f"# {spec.name}: the identified model", "", description, "",
             "Parameters in SI units (kg, m, kg m^2, N m s/rad, N m). Files:", ""]
    drives = spec.transmission is not None
    laws = DRIVES_FILE if drives else JOINTS_FILE
    if URDF_FILE in files and drives:
        lines += [f"- `{URDF_FILE}`: the model's URDF with each moving link's identified `<inertial>` (in its link "
                  "frame) and no `<dynamics>`: the friction and rotor inertia are the motors', behind the joints "
                  f"through the transmission (`{DRIVES_FILE}`). **Read alone it loses** every drive term."]
    elif URDF_FILE in files:
        lines += [f"- `{URDF_FILE}`: the model's URDF with each moving link's identified `<inertial>` (in its link "
                  "frame) and each joint's `<dynamics damping friction>` (viscous, Coulomb). **Read alone it loses** "
                  "the rotor inertia (armature), the Coulomb smoothing velocity (URDF's friction is a sharp sign), "
                  "the torque offset and the families' terms, which URDF has no tag for: a consumer of this file "
                  "alone predicts other torques than the identified model."]
    if drives:
        lines += [f"- `{DRIVES_FILE}`: a model file's `[drives]`: the motors, the transmission N (q_m = N q + offset, "
                  "tau_joint = N^T tau_motor, a row per motor), their offsets and per motor, in motor units, "
                  "`armature` (rotor inertia), `viscous`, `coulomb`, `offset`, `coulomb_velocity` and the family "
                  "chosen for it (harness/model/drives.py). Per motor the family: "
                  + ", ".join(f"`{m}` {f.family}" for m, f in zip(spec.drive_names, spec.frictions, strict=True))
                  + ". At the joints: I_a -> N^T diag(I_a) N, a friction f(q'_m) -> N^T f(N q')."]
    else:
        lines += [f"- `{JOINTS_FILE}`: per joint `armature`, `viscous`, `coulomb`, `offset`, `coulomb_velocity`, the "
                  "friction law I_a q'' + f_v q' + f_c tanh(q'/v_c) + f_o, and the terms of the family chosen for "
                  "the joint (`viscous_asymmetry`, `coulomb_asymmetry`, `stribeck` with `stribeck_velocity`, "
                  "`load_coulomb`, `stiffness`; zero where unused; harness/model/friction.py). Per joint the family: "
                  + ", ".join(f"`{j.name}` {j.friction.family}" for j in spec.joints) + "."]
    if MODEL_FILE in files:
        lines += [f"- `{MODEL_FILE}`: a model file that `harness run` loads as any other: `{URDF_FILE}` with "
                  f"`{laws}`'s values; together they are the whole identified model (`harness.identified_model` "
                  "reads it)."]
    if LEAST_SQUARES_FILE in files:
        lines += [f"- `{LEAST_SQUARES_FILE}`: the least-squares fit the run judged beside this one: each base "
                  "parameter's value, standard deviation and the combination of physical parameters it stands for, "
                  "with the regressor columns it multiplies (evaluated with "
                  f"`{MODEL_FILE}`'s kinematics and laws; `harness.identified_model(folder, fit=\"least squares\")`). "
                  "It is not a physical model: it predicts the torques, not a simulation."]
    if MJCF_FILE in files:
        drive = ("a fixed tendon per motor over the joints it turns with (coefficients: its row of N) carrying "
                 "its `armature`, `damping` (viscous) and `frictionloss` (Coulomb), and a motor on each tendon (gear "
                 "1: its control is the motor's torque); no motor offsets (MJCF has no place for them)"
                 if drives else "`armature`, `damping` (viscous), `frictionloss` (Coulomb), a motor per joint with the "
                                "effort limit as its force range")
        lines += [f"- `{MJCF_FILE}`: MJCF for MuJoCo, every number at full precision: bodies with the identified "
                  f"inertials, joint ranges, {drive}. MuJoCo applies Coulomb friction as dry friction "
                  "(a sharp sign, solved as a constraint), not the smooth tanh law, and has no torque offset and none "
                  "of the families' terms (asymmetry, Stribeck, load) but a spring (`stiffness`, at rest at 0: "
                  "the offset that sets its rest position is not in the file). "
                  "What this changes at the training span's velocities, per joint: the RMS change over the RMS "
                  "torque, and the largest change (at a velocity reversal) over the largest torque:"]
        lines += [f"  - `{j}`: RMS {v['rms']:.3g}, largest {v['largest']:.3g}" for j, v in (mapping or {}).items()]
        lines += ["  The inertial parameters, armature and viscous friction are the identified model's exactly."]
    elif mjcf_refused:
        lines += [f"- `{MJCF_FILE}` is not written: {mjcf_refused}."]
    lines += ["- `manifest.json`: the run that wrote these files (its id, as in the run's `results.json`) and each "
              "file's SHA-256: `harness.identified_model` refuses this folder when its files are not exactly those."]
    return "\n".join(lines) + "\n"
