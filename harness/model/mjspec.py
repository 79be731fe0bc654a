"""The robot as MuJoCo's own model description (mujoco.MjSpec): one MuJoCo body per massive body,
whose frame is the paper's body frame (O_ci, e(i)), with its mass and principal inertias stated
explicitly; a massless carriage merged into its child (MuJoCo refuses moving bodies without mass),
its joint placed before the child's own. A joint's rotor inertia is MuJoCo's `armature` and its viscous
friction MuJoCo's `damping`; with a transmission (harness/model/drives.py) each motor is instead a fixed
tendon over the joints it turns with, its coefficients motor k's row of N (the tendon's length is the
motor's angle less its offset), carrying the motor's rotor inertia and viscous friction (MuJoCo adds
J^T armature J to the mass matrix and J^T (-damping J q') to the passive force: N^T I_m N and
N^T f_v N q', the law of drives.py). What the bench adds (motors, sensors, the integrator) is
harness/engines/mujoco.py's; the MJCF file written for others, harness/model/mjcf.py's.

MuJoCo refuses a moving body with a zero principal moment of inertia, which the paper's thin rods
(about their own axis) and point masses have. Such a moment is given MOMENT_FLOOR times the
model's largest principal moment: the torques then differ from the ideal body's by that order,
about 1e-12 relative, 1000 times below the agreement the gates require.
"""

from __future__ import annotations

import mujoco
import numpy as np

from harness.model.friction import NO_FRICTION
from harness.model.inertia import MOMENT_FLOOR
from harness.model.spec import WORLD, RobotSpec

_JOINT_TYPE = {True: mujoco.mjtJoint.mjJNT_HINGE, False: mujoco.mjtJoint.mjJNT_SLIDE}


def _quat(R: np.ndarray) -> np.ndarray:
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(R, dtype=float).ravel())
    return q


def add_robot(ms: mujoco.MjSpec, spec: RobotSpec, frictionloss: bool = False,
              floating: bool = False) -> dict[str, mujoco.MjsBody]:
    """The robot's bodies, joints and inertials added to `ms`, and its drives' tendons (`add_drives`,
    with their Coulomb friction as `frictionloss` where asked): its bodies by name. With `floating`, its
    floating base (spec.floating) a body on a free joint named as the file names it, its frame the file's
    base frame F (harness/model/floating.py: the free joint's qpos is F's pose) and its inertial stated in
    it, the joints from the world on it."""
    carried = [*spec.massive_bodies, *([spec.floating.body] if floating else [])]
    floor = MOMENT_FLOOR * max(float(np.max(b.principal_inertia)) for b in carried)
    root = ms.worldbody
    frames = {WORLD: (np.eye(3), np.zeros(3))}
    if floating:
        fb = spec.floating
        R_WF, p_WF = fb.R_WF0, fb.p_WF0
        root = ms.worldbody.add_body(name=fb.body.name, pos=p_WF, quat=_quat(R_WF))
        root.add_freejoint(name=fb.joint)
        root.explicitinertial = True
        root.mass, root.ipos = fb.body.mass, R_WF.T @ (fb.body.p_W_com0 - p_WF)
        root.iquat = _quat(R_WF.T @ fb.body.R_WB0)
        root.inertia = np.maximum(fb.body.principal_inertia, floor)
        frames[WORLD] = (R_WF, p_WF)
    elements = {WORLD: root}
    for body in spec.massive_bodies:
        parent, chain = spec.massive_parent(body.name)
        R_WP, p_WP = frames[parent]
        holder = elements[parent]
        if floating and parent == WORLD and chain[0].name not in spec.floating.joints:  # on the ground
            (R_WP, p_WP), holder = (np.eye(3), np.zeros(3)), ms.worldbody
        R_WB, p_WB = body.R_WB0, body.p_W_com0
        el = holder.add_body(name=body.name, pos=R_WP.T @ (p_WB - p_WP), quat=_quat(R_WP.T @ R_WB))
        elements[body.name], frames[body.name] = el, (R_WB, p_WB)
        for joint in chain:
            # rotor inertia enters MuJoCo's mass matrix, viscous friction its passive force -f_v q';
            # Coulomb friction and offset are applied by `simulate` (MuJoCo's frictionloss is a
            # constraint solved with regularisation, not the smooth law of harness/model/friction.py)
            own = joint.friction if spec.transmission is None else NO_FRICTION  # else the motors' tendons
            el.add_joint(name=joint.name, type=_JOINT_TYPE[joint.revolute], pos=body.arm_B(joint.p_W0),
                         axis=R_WB.T @ joint.axis_W0, armature=own.armature, damping=own.viscous)
        el.explicitinertial = True
        el.mass, el.ipos, el.iquat = body.mass, np.zeros(3), np.array([1.0, 0.0, 0.0, 0.0])
        el.inertia = np.maximum(body.principal_inertia, floor)
        if body.cylinder is not None:
            half = body.cylinder.length / 2
            el.add_geom(type=mujoco.mjtGeom.mjGEOM_CYLINDER, size=[body.cylinder.radius, 0, 0],
                        fromto=[-half, 0, 0, half, 0, 0], contype=0, conaffinity=0)
    if spec.transmission is not None:
        add_drives(ms, spec, frictionloss)
    add_loops(ms, spec, elements, frames)
    return elements


def add_loops(ms: mujoco.MjSpec, spec: RobotSpec, elements: dict, frames: dict) -> None:
    """Each loop of the spec (harness/model/loops.py) as an equality constraint between two sites,
    `<loop>_1` on body a and `<loop>_2` on body b, at its joined points (and, for a weld, with its
    joined frames): MuJoCo's site-based connect and weld make the sites' points (and frames)
    coincide, whatever the configuration the model is compiled at. A coupling is MuJoCo's joint
    equality of joint1 the follower and joint2 the leader, its polynomial q_1 - q_1,0 = a_0 + a_1 (q_2 -
    q_2,0) with a_0 the offset and a_1 the ratio (the joints' reference positions q_0 are zero here)."""
    kinds = {"connect": mujoco.mjtEq.mjEQ_CONNECT, "weld": mujoco.mjtEq.mjEQ_WELD}
    for loop in spec.loops:
        if not loop.joins_points:
            eq = ms.add_equality(name=loop.name, type=mujoco.mjtEq.mjEQ_JOINT, objtype=mujoco.mjtObj.mjOBJ_JOINT,
                                 name1=loop.follower, name2=loop.leader)
            eq.data[:5] = [loop.offset, loop.ratio, 0.0, 0.0, 0.0]
            continue
        names = []
        for side, (body, point, R) in enumerate(((loop.body_a, loop.point_a_W0, loop.R_W_frame_a0),
                                                 (loop.body_b, loop.point_b_W0, loop.R_W_frame_b0)), start=1):
            R_WE, p_WE = frames[body]
            R = R_WE if R is None else R
            names.append(f"{loop.name}_{side}")
            elements[body].add_site(name=names[-1], pos=R_WE.T @ (point - p_WE), quat=_quat(R_WE.T @ R))
        ms.add_equality(name=loop.name, type=kinds[loop.kind], objtype=mujoco.mjtObj.mjOBJ_SITE,
                        name1=names[0], name2=names[1])


def add_contacts(ms: mujoco.MjSpec, spec: RobotSpec, elements: dict, contacts: tuple, ground_W: np.ndarray,
                 ground_R: np.ndarray | None = None) -> None:
    """Each contact (harness/model/contacts.py) as MuJoCo's equality `contact_<name>` of a site on its body at
    its point (`contact_<name>`) and a site of the world at its ground point `ground_W` (k, 3),
    (`ground_<name>`): a point's connect holds the point where it stands; a sole's weld holds the site's frame
    (the body's axes, the world's at q = 0) at its frame on the ground, `ground_R` (k, 3, 3)."""
    for k, (c, g) in enumerate(zip(contacts, ground_W, strict=True)):
        body = spec.body(c.body)
        sole = c.sole
        elements[c.body].add_site(name=f"contact_{c.name}", pos=body.arm_B(c.point_W0),
                                  quat=_quat(body.R_WB0.T) if sole else [1.0, 0.0, 0.0, 0.0])
        ms.worldbody.add_site(name=f"ground_{c.name}", pos=np.asarray(g, dtype=float),
                              quat=_quat(ground_R[k]) if sole else [1.0, 0.0, 0.0, 0.0])
        ms.add_equality(name=f"contact_{c.name}", type=mujoco.mjtEq.mjEQ_WELD if sole else mujoco.mjtEq.mjEQ_CONNECT,
                        objtype=mujoco.mjtObj.mjOBJ_SITE, name1=f"contact_{c.name}", name2=f"ground_{c.name}")


def add_drives(ms: mujoco.MjSpec, spec: RobotSpec, frictionloss: bool = False) -> list[mujoco.MjsTendon]:
    """A fixed tendon per motor of the spec's transmission, named after the motor, over the joints in
    its row of N with N's entries as coefficients, carrying the motor's rotor inertia (`armature`) and
    viscous friction (`damping`), and with `frictionloss` its Coulomb friction (MuJoCo's dry friction,
    a sharp sign) and its spring (`stiffness` at length 0): for a file others simulate, not for the bench,
    which applies the smooth law and the spring itself."""
    t = spec.transmission
    tendons = []
    for k, (motor, law) in enumerate(zip(t.motors, spec.frictions, strict=True)):
        tendon = ms.add_tendon(name=motor, armature=law.armature, damping=law.viscous,
                               frictionloss=law.coulomb if frictionloss else 0.0)
        if frictionloss and law.stiffness:
            tendon.stiffness, tendon.springlength = [law.stiffness, 0.0, 0.0], [0.0, 0.0]
        for j, joint in enumerate(spec.joints):
            if t.N[k, j] != 0.0:
                tendon.wrap_joint(joint.name, float(t.N[k, j]))
        tendons.append(tendon)
    return tendons


def new_spec(name: str, gravity_W: np.ndarray) -> mujoco.MjSpec:
    """An empty MjSpec named `name`: radians, limits from ranges, inertials as stated, `gravity_W`."""
    ms = mujoco.MjSpec()
    ms.modelname = name
    ms.compiler.degree = False
    ms.compiler.autolimits = True
    ms.compiler.inertiafromgeom = mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_FALSE
    ms.option.gravity = np.asarray(gravity_W, dtype=float)
    return ms
