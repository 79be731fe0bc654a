"""MuJoCo as the test bench (the part ADAMS plays in the paper, section 3).

`build_spec` builds MuJoCo's model description (mujoco.MjSpec) from a RobotSpec: one MuJoCo body per massive body, whose
frame is the paper's body frame (O_ci, e(i)), with its mass and principal inertias stated
explicitly; a massless carriage is merged into its child (MuJoCo refuses moving bodies without
mass), its joint placed before the child's own. Every joint gets a motor (gear 1), a site at its
point O_J on the outer body with force and torque sensors, and joint position, velocity and
actuator-force sensors; every centre of mass gets a site with an accelerometer and gyro (site
frame) and frame sensors (world frame: position, orientation, linear and angular velocity and
acceleration). Contacts are disabled. A joint's rotor inertia is MuJoCo's `armature` and its viscous
friction MuJoCo's `damping`; Coulomb friction and offset are applied at every evaluation of the
dynamics as the generalised force of harness/model/friction.py.

MuJoCo refuses a moving body with a zero principal moment of inertia, which the paper's thin rods
(about their own axis) and point masses have. Such a moment is given MOMENT_FLOOR times the
model's largest principal moment: the torques then differ from the ideal body's by that order,
about 1e-12 relative, 1000 times below the agreement the gates require.

`simulate` drives every joint along its prescribed motion by computed torque: at each step the
engine's own inverse dynamics (mj_inverse) gives the torques for q''_cmd = q''_d + 2 w e' + w^2 e,
applied as motor controls, then mj_step integrates. At each output row mj_forward evaluates the
state with the controls in force, so forces, accelerations and drive torques in a row belong to
one and the same instant. The torques of every evaluation inside each step (the four RK4 stages)
are kept in `meta["drive_stages"]`, so that another model can be driven by exactly the same input.
"""

from __future__ import annotations

import copy
import logging
from collections.abc import Callable, Sequence

import mujoco
import numpy as np
from mujoco import rollout as mujoco_rollout

from harness.base.numerics import sampled
from harness.engines.recording import Recording
from harness.engines.simulation import Simulation
from harness.model import friction
from harness.model.quaternion import to_matrix
from harness.model.spec import WORLD, Body, Joint, RobotSpec

_MJ_INTEGRATOR = {"RK4": mujoco.mjtIntegrator.mjINT_RK4, "Euler": mujoco.mjtIntegrator.mjINT_EULER,
                  "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST}
_JOINT_TYPE = {True: mujoco.mjtJoint.mjJNT_HINGE, False: mujoco.mjtJoint.mjJNT_SLIDE}
MOMENT_FLOOR = 1e-12


def _quat(R: np.ndarray) -> np.ndarray:
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(R, dtype=float).ravel())
    return q


def _massive_parent(spec: RobotSpec, body: Body) -> tuple[str, list[Joint]]:
    """The nearest massive ancestor (or world) and the joints from it to `body`, inner first."""
    chain = [spec.inner_joint(body.name)]
    parent = chain[0].parent
    while parent != WORLD and spec.body(parent).massless:
        chain.insert(0, spec.inner_joint(parent))
        parent = chain[0].parent
    return parent, chain


def _robot(ms: mujoco.MjSpec, spec: RobotSpec) -> dict[str, mujoco.MjsBody]:
    """The robot's bodies, joints and inertials added to `ms`: its bodies by name."""
    elements = {WORLD: ms.worldbody}
    frames = {WORLD: (np.eye(3), np.zeros(3))}
    floor = MOMENT_FLOOR * max(float(np.max(b.principal_inertia)) for b in spec.massive_bodies)
    for body in spec.massive_bodies:
        parent, chain = _massive_parent(spec, body)
        R_WP, p_WP = frames[parent]
        R_WB, p_WB = body.R_WB0, body.p_W_com0
        el = elements[parent].add_body(name=body.name, pos=R_WP.T @ (p_WB - p_WP), quat=_quat(R_WP.T @ R_WB))
        elements[body.name], frames[body.name] = el, (R_WB, p_WB)
        for joint in chain:
            # rotor inertia enters MuJoCo's mass matrix, viscous friction its passive force -f_v q';
            # Coulomb friction and offset are applied by `simulate` (MuJoCo's frictionloss is a
            # constraint solved with regularisation, not the smooth law of harness/model/friction.py)
            el.add_joint(name=joint.name, type=_JOINT_TYPE[joint.revolute], pos=body.arm_B(joint.p_W0),
                         axis=R_WB.T @ joint.axis_W0, armature=joint.friction.armature, damping=joint.friction.viscous)
        el.explicitinertial = True
        el.mass, el.ipos, el.iquat = body.mass, np.zeros(3), np.array([1.0, 0.0, 0.0, 0.0])
        el.inertia = np.maximum(body.principal_inertia, floor)
        if body.cylinder is not None:
            half = body.cylinder.length / 2
            el.add_geom(type=mujoco.mjtGeom.mjGEOM_CYLINDER, size=[body.cylinder.radius, 0, 0],
                        fromto=[-half, 0, 0, half, 0, 0], contype=0, conaffinity=0)
    return elements


def _new_spec(name: str, gravity_W: np.ndarray) -> mujoco.MjSpec:
    ms = mujoco.MjSpec()
    ms.modelname = name
    ms.compiler.degree = False
    ms.compiler.autolimits = True
    ms.compiler.inertiafromgeom = mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_FALSE
    ms.option.gravity = np.asarray(gravity_W, dtype=float)
    return ms


def _driven(spec: RobotSpec, gravity_W: np.ndarray, integrator: str,
            timestep: float) -> tuple[mujoco.MjSpec, dict[str, mujoco.MjsBody]]:
    """The robot with its integrator and timestep, contacts off, and one motor per joint
    (`drive_<joint>`, control = torque): what `build_spec` and `dynamics_spec` share."""
    ms = _new_spec(spec.name, gravity_W)
    ms.option.integrator = _MJ_INTEGRATOR[integrator]
    ms.option.timestep = float(timestep)
    ms.option.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
    elements = _robot(ms, spec)
    for joint in spec.joints:
        ms.add_actuator(name=f"drive_{joint.name}", target=joint.name, trntype=mujoco.mjtTrn.mjTRN_JOINT,
                        gear=[1.0, 0, 0, 0, 0, 0])
    return ms, elements


def build_spec(spec: RobotSpec, gravity_W: np.ndarray, integrator: str = "RK4",
               timestep: float = 5e-4) -> mujoco.MjSpec:
    """The robot as MuJoCo's own model description (mujoco.MjSpec), which `build_model` compiles.
    Every number is set as the double it is, never through text (MuJoCo's own XML writer,
    `MjSpec.to_xml`, keeps six significant digits: see `mjcf` for a file that reloads)."""
    ms, elements = _driven(spec, gravity_W, integrator, timestep)
    for body in spec.massive_bodies:
        el = elements[body.name]
        el.add_site(name=f"com_{body.name}", pos=np.zeros(3))
        # A carriage's joint shares its point with the child's joint (checked by the spec).
        chain = _massive_parent(spec, body)[1]
        el.add_site(name=f"joint_{chain[-1].name}", pos=body.arm_B(chain[-1].p_W0))
    S, site, jnt = mujoco.mjtSensor, mujoco.mjtObj.mjOBJ_SITE, mujoco.mjtObj.mjOBJ_JOINT

    def sensor(kind, name: str, objtype, objname: str) -> None:
        ms.add_sensor(name=name, type=kind, objtype=objtype, objname=objname)

    for joint in spec.joints:
        at = f"joint_{_measured_at(spec, joint).name}"
        sensor(S.mjSENS_FORCE, f"force_{joint.name}", site, at)
        sensor(S.mjSENS_TORQUE, f"torque_{joint.name}", site, at)
        sensor(S.mjSENS_JOINTPOS, f"q_{joint.name}", jnt, joint.name)
        sensor(S.mjSENS_JOINTVEL, f"qd_{joint.name}", jnt, joint.name)
        sensor(S.mjSENS_JOINTACTFRC, f"tau_{joint.name}", jnt, joint.name)
    for body in spec.massive_bodies:
        com = f"com_{body.name}"
        sensor(S.mjSENS_ACCELEROMETER, f"acc_{body.name}", site, com)
        sensor(S.mjSENS_GYRO, f"gyro_{body.name}", site, com)
        for kind, name in ((S.mjSENS_FRAMEPOS, "framepos"), (S.mjSENS_FRAMEQUAT, "framequat"),
                           (S.mjSENS_FRAMELINVEL, "framelinvel"), (S.mjSENS_FRAMEANGVEL, "frameangvel"),
                           (S.mjSENS_FRAMELINACC, "framelinacc"), (S.mjSENS_FRAMEANGACC, "frameangacc")):
            sensor(kind, f"{name}_{body.name}", site, com)
    return ms


def dynamics_spec(spec: RobotSpec, gravity_W: np.ndarray, integrator: str = "RK4",
                  timestep: float = 5e-4) -> mujoco.MjSpec:
    """The robot for rollouts under joint torques: its bodies and joints (rotor inertia as armature,
    viscous friction as damping), one motor per joint (`drive_<joint>`, control = torque, N m) and
    only the sensors of q and q' (`q_<joint>`, `qd_<joint>`, joint by joint)."""
    ms, _ = _driven(spec, gravity_W, integrator, timestep)
    for joint in spec.joints:
        ms.add_sensor(name=f"q_{joint.name}", type=mujoco.mjtSensor.mjSENS_JOINTPOS, objtype=mujoco.mjtObj.mjOBJ_JOINT,
                      objname=joint.name)
        ms.add_sensor(name=f"qd_{joint.name}", type=mujoco.mjtSensor.mjSENS_JOINTVEL,
                      objtype=mujoco.mjtObj.mjOBJ_JOINT, objname=joint.name)
    return ms


def _measured_at(spec: RobotSpec, joint: Joint) -> Joint:
    """The joint whose site measures `joint`: itself, or for a carriage's inner joint the
    carriage's outer joint (same point, same wrench: the carriage has no mass)."""
    return spec.carried_joint(joint.name)


def build_model(spec: RobotSpec, gravity_W: np.ndarray, simulation: Simulation) -> mujoco.MjModel:
    return build_spec(spec, gravity_W, simulation.integrator, simulation.timestep).compile()


def _log_warning(message: str) -> None:
    """MuJoCo's warnings go to the log, not to a MUJOCO_LOG.TXT in the working directory; while
    `simulate` runs they are only collected, and it logs them once it has finished."""
    _WARNINGS.append(message)
    if not _COLLECTING[0]:
        logging.getLogger("harness.mujoco").warning(message)


_WARNINGS: list[str] = []
_COLLECTING = [False]
mujoco.set_mju_user_warning(_log_warning)

# MuJoCo's own verdict that a state is not finite or beyond its bounds (it then resets the data)
_UNSTABLE = (mujoco.mjtWarning.mjWARN_BADQPOS, mujoco.mjtWarning.mjWARN_BADQVEL, mujoco.mjtWarning.mjWARN_BADQACC,
             mujoco.mjtWarning.mjWARN_BADCTRL)


class Diverged(Exception):
    """The motion drove the simulation to non-finite values (or to MuJoCo's bound on them)."""

    def __init__(self, joint: str, t: float, engine_message: str):
        super().__init__(f"joint {joint} at t = {t:.6g} s")
        self.joint, self.t, self.engine_message = joint, t, engine_message


def _diverged(model: mujoco.MjModel, data: mujoco.MjData, t: float, message: str) -> Diverged:
    """The joint and time of MuJoCo's first instability warning, `message` ("... in CTRL at
    ACTUATOR 1. ... Time = 0.0013."), where it can be read; else the last index MuJoCo noted and the
    end of the steps to the row being simulated (`t`)."""
    import re

    said = re.search(r"in (QPOS|QVEL|QACC|CTRL) at (DOF|ACTUATOR) (\d+)", message)
    when = re.search(r"Time = ([0-9]+(?:\.[0-9]+)?(?:[eE][+-]?[0-9]+)?)", message)
    if said:
        kind, index = said.group(2), int(said.group(3))
    else:
        stat = next((k for k in _UNSTABLE if data.warning[k].number), mujoco.mjtWarning.mjWARN_BADQACC)
        kind, index = ("ACTUATOR" if stat == mujoco.mjtWarning.mjWARN_BADCTRL else "DOF"), data.warning[stat].lastinfo
    joint = "?"
    if kind == "ACTUATOR" and 0 <= index < model.nu:
        joint = model.actuator(index).name.removeprefix("drive_")
    elif kind == "DOF" and 0 <= index < model.nv:
        joint = model.joint(model.dof_jntid[index]).name
    return Diverged(joint, float(when.group(1)) if when else t, message)


def _as_slice(index: np.ndarray) -> slice | np.ndarray:
    """index as a slice where its entries are consecutive."""
    if len(index) and np.array_equal(index, np.arange(index[0], index[0] + len(index))):
        return slice(int(index[0]), int(index[0]) + len(index))
    return index


def simulate(spec: RobotSpec, gravity_W: np.ndarray, prescribed: Callable, output_steps: int, output_dt: float,
             simulation: Simulation) -> Recording:
    """Forward-simulate the robot with mj_step along the prescribed motion (`prescribed(t)` ->
    (q, q', q''), each (len(t), n) in the spec's joint order) and record `output_steps + 1` rows
    from t = 0, `output_dt` apart. `simulation.timestep` must divide `output_dt`."""
    model = build_model(spec, gravity_W, simulation)
    data = mujoco.MjData(model)
    qadr = np.array([model.joint(j).qposadr[0] for j in spec.joint_names])
    vadr = np.array([model.joint(j).dofadr[0] for j in spec.joint_names])
    act = np.array([model.actuator(f"drive_{j}").id for j in spec.joint_names])
    n_joints = len(spec.joint_names)
    if not (model.nq == model.nv == model.nu == n_joints and np.array_equal(qadr, vadr)):
        raise RuntimeError("the MuJoCo model has other coordinates or actuators than the spec's joints")
    w = simulation.tracking_bandwidth
    dt = simulation.timestep
    substeps = round(output_dt / dt)
    n_rows = output_steps + 1
    n_steps = (n_rows - 1) * substeps
    # The integrators evaluate the dynamics at whole and half steps (RK4 stages): the prescribed
    # motion is evaluated once, batched, on that half-step grid, and its columns put in MuJoCo's
    # order of coordinates once (depth-first; the spec's is breadth-first), so that the callback
    # below, run at every stage of every step, reads and writes MjData's arrays whole, through views
    # taken once, and every product into an array made once (each attribute access of MjData builds
    # a new array object, each indexing a copy)
    half = dt / 2.0
    in_spec_order = prescribed(np.arange(2 * n_steps + 2) * half)
    q_d, qd_d, qdd_d = (np.empty_like(x) for x in in_spec_order)
    for x, y in zip((q_d, qd_d, qdd_d), in_spec_order, strict=True):
        x[:, vadr] = y
    at_dof = np.argsort(vadr)  # the spec joint at each dof
    dry = friction.Dry.of(tuple(spec.frictions[j] for j in at_dof))
    armature = friction.values(spec.frictions)[at_dof, 0]
    to_ctrl = np.empty(n_joints, dtype=int)
    to_ctrl[act] = vadr  # ctrl[a] is the drive of the joint at dof to_ctrl[a]
    to_ctrl = None if np.array_equal(to_ctrl, np.arange(n_joints)) else to_ctrl
    per_step = {"RK4": 4, "Euler": 1, "implicitfast": 1}[simulation.integrator]  # evaluations in a step
    stages = np.empty((n_steps * per_step, n_joints))  # the drive torques of every evaluation inside mj_step, by dof
    captured = [0, False]  # how many rows of `stages` are written, whether to write the next
    qpos, qvel, ctrl = data.qpos, data.qvel, data.ctrl
    qfrc_bias, qfrc_passive, qfrc_applied = data.qfrc_bias, data.qfrc_passive, data.qfrc_applied
    e, ed, qacc_cmd, tau = (np.empty(n_joints) for _ in range(4))
    # the gains as arrays, and every ufunc's output passed by position: a Python float operand and
    # the `out=` keyword each cost a numpy call more than its arithmetic on seven numbers (the same
    # products, bit for bit)
    kp, kd = np.full(n_joints, w * w), np.full(n_joints, 2.0 * w)
    add, subtract, multiply = np.add, np.subtract, np.multiply

    def drive(m: mujoco.MjModel, d: mujoco.MjData) -> None:
        """Computed torque at the state being evaluated: tau = M q''_cmd + bias - passive - applied,
        q''_cmd = q''_d + 2 w (q'_d - q') + w^2 (q_d - q) (M with the rotor inertias, passive the
        viscous friction, applied the Coulomb friction and offset set here from the joint
        velocities), called by MuJoCo after the velocity stage (on `data`, the one MjData simulated
        here, whose arrays are read through the views above)."""
        k = round(d.time / half)
        multiply(subtract(q_d[k], qpos, e), kp, e)
        multiply(subtract(qd_d[k], qvel, ed), kd, ed)
        add(add(qdd_d[k], ed, qacc_cmd), e, qacc_cmd)
        mujoco.mj_mulM(m, d, tau, qacc_cmd)
        if dry.any:  # the rigid-body torque: the computed torque less the rotor inertia's part
            rigid = tau + qfrc_bias - armature * qacc_cmd if dry.needs_load else None
            np.negative(dry(qvel, rigid), out=qfrc_applied)
        add(tau, qfrc_bias, tau)
        subtract(tau, qfrc_passive, tau)
        subtract(tau, qfrc_applied, tau)
        if to_ctrl is None:
            ctrl[:] = tau
        else:
            np.take(tau, to_ctrl, out=ctrl)
        if captured[1]:
            stages[captured[0]] = tau
            captured[0] += 1

    data.qpos[:], data.qvel[:] = q_d[0], qd_d[0]
    sensor_rows = np.empty((n_rows, model.nsensordata))
    qacc_rows = np.empty((n_rows, n_joints))
    mujoco.set_mjcb_control(drive)
    warned = len(_WARNINGS)
    _COLLECTING[0] = True
    try:
        for row in range(n_rows):
            data.time = row * substeps * dt
            mujoco.mj_forward(model, data)
            sensor_rows[row] = data.sensordata
            qacc_rows[row] = data.qacc[vadr]
            if row < n_rows - 1:
                captured[1] = True
                mujoco.mj_step(model, data, substeps)  # one call for the steps to the next row
                if len(_WARNINGS) > warned and any(data.warning[k].number for k in _UNSTABLE):
                    # MuJoCo has reset the data: stop at the first such row, with its first message
                    raise _diverged(model, data, (row + 1) * substeps * dt, _WARNINGS[warned])
                captured[1] = False
    finally:
        mujoco.set_mjcb_control(None)
        _COLLECTING[0] = False
    for message in _WARNINGS[warned:]:
        logging.getLogger("harness.mujoco").warning(message)
    drive_stages = stages[:captured[0], vadr].reshape(n_steps, per_step, n_joints)
    t = np.arange(n_rows) * substeps * dt
    q_ref, qd_ref, qdd_ref = (x[::2 * substeps] for x in in_spec_order)

    def sensor(name: str) -> np.ndarray:
        s = model.sensor(name)
        return sensor_rows[:, s.adr[0]: s.adr[0] + s.dim[0]]

    def per_joint(kind: str) -> np.ndarray:
        return np.stack([sensor(f"{kind}_{j}") for j in spec.joint_names], axis=1)

    def per_body(kind: str) -> np.ndarray:
        return np.stack([sensor(f"{kind}_{b.name}") for b in spec.massive_bodies], axis=1)

    if not np.all(np.isfinite(sensor_rows)):  # beyond what MuJoCo checks: a body's sensors
        row = int(np.flatnonzero(~np.all(np.isfinite(sensor_rows), axis=1))[0])
        bad = [j for j in spec.joint_names if not all(np.all(np.isfinite(sensor(f"{k}_{j}")[row]))
                                                       for k in ("q", "qd", "tau", "force", "torque"))]
        raise Diverged(bad[0] if bad else "?", row * substeps * dt, "a sensor reads a value that is not finite")

    # Force/torque sensors report the wrench of the parent on the child about the site, in the
    # site frame (the outer body's frame); rotate to world components.
    site_R = np.stack([to_matrix(sensor(f"framequat_{_site_body(spec, j)}")) for j in spec.joints],
                      axis=1)
    F_W = np.einsum("njab,njb->nja", site_R, per_joint("force"))
    M_W = np.einsum("njab,njb->nja", site_R, per_joint("torque"))
    R_WB = to_matrix(per_body("framequat"))
    q, qd = per_joint("q")[..., 0], per_joint("qd")[..., 0]
    meta = {
        "engine": "mujoco", "engine_version": mujoco.__version__,
        "integrator": simulation.integrator, "timestep": dt, "substeps": substeps,
        "warnings": _WARNINGS[warned:],
        "tracking_bandwidth": w,
        "q_ref": q_ref, "qd_ref": qd_ref, "qdd_ref": qdd_ref,
        "drive_stages": drive_stages,  # (steps, stages, joints): torques at every evaluation
    }
    return Recording(
        t=t, joints=tuple(spec.joint_names), bodies=tuple(b.name for b in spec.massive_bodies),
        q=q, qd=qd, qdd=qacc_rows, tau=per_joint("tau")[..., 0], F_W=F_W, M_W=M_W,
        p_W=per_body("framepos"), v_W=per_body("framelinvel"), R_WB=R_WB,
        a_W=per_body("framelinacc") + gravity_W,  # framelinacc is a - g (proper)
        omega_W=per_body("frameangvel"), omegadot_W=per_body("frameangacc"), meta=meta,
    )


def _site_body(spec: RobotSpec, joint: Joint) -> str:
    """Name of the massive body carrying the site that measures `joint`."""
    return _measured_at(spec, joint).child


# --- rollouts: a model forward-simulated under given joint torques, many starts in one batch -------


PREDICTION_TIMESTEP = 0.001  # s: RK4 steps of a prediction (the log's torques read at every stage)
_BLOCK = 1024.0  # s: rollout b runs on the clock from b * _BLOCK, which tells the callback whose drive it is


def stage_times(steps: int, timestep: float) -> np.ndarray:
    """(2 steps + 1,): the times, from a rollout's start, at which RK4 evaluates the dynamics (each
    step's start, middle (twice) and end): where `rollouts` reads a drive."""
    return np.arange(2 * steps + 1) * (timestep / 2)


def rollouts(spec: RobotSpec, gravity_W: np.ndarray, frictions: Sequence[tuple[friction.JointFriction, ...]],
             q0: np.ndarray, qd0: np.ndarray, drives: np.ndarray,
             timestep: float = PREDICTION_TIMESTEP) -> tuple[np.ndarray, np.ndarray]:
    """B forward simulations of the robot in one batch of `mujoco.rollout` (RK4, `timestep`): rollout
    b starts at (q0[b], qd0[b]) (B, n) and is driven by the joint torques drives[b] (B, 2 steps + 1, n),
    given at `stage_times(steps, timestep)`, less the dry friction of its own law frictions[b]
    (friction.Dry: Coulomb, offset and the families' terms); its rotor inertia and viscous friction are
    MuJoCo's armature and damping, so laws that differ only in friction share the robot's inertials.
    Returns q and q' after each step, (B, steps, n) in the spec's joint order, NaN from the step at
    which a rollout diverged (a non-finite state, or MuJoCo's reset on one)."""
    model = build_spec(spec, gravity_W, "RK4", timestep).compile()
    data = mujoco.MjData(model)
    joint_ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, j) for j in spec.joint_names]
    qadr, vadr = model.jnt_qposadr[joint_ids], model.jnt_dofadr[joint_ids]
    B = len(q0)
    steps = (drives.shape[1] - 1) // 2
    laws, models, forcing = {}, {}, []  # each distinct law once: its model (armature, damping) and dry friction
    for fr in frictions:
        if id(fr) not in laws:
            k = friction.values(fr)
            m = model
            if fr != tuple(spec.frictions):
                m = copy.copy(model)
                m.dof_armature[vadr], m.dof_damping[vadr] = k[:, 0], k[:, 1]
            laws[id(fr)], models[id(fr)] = (friction.Dry.of(fr), k[:, 1]), m
        forcing.append(laws[id(fr)])
    half, last = timestep / 2, 2 * steps
    v_at = _as_slice(vadr)
    qvel, qfrc_applied = data.qvel, data.qfrc_applied  # views of the one MjData the rollouts run in

    def applied(m: mujoco.MjModel, d: mujoco.MjData) -> None:
        now = d.time
        b = min(int(now // _BLOCK), B - 1)  # (a rollout MuJoCo reset restarts at time 0: its NaN is set below)
        drive = drives[b, min(round((now - b * _BLOCK) / half), last)]
        dry, viscous = forcing[b]
        v = qvel[v_at]
        # load-dependent friction: the drive's torque less the rest of its friction stands for the
        # rigid-body torque (the rotor inertia's part, I_a q'', is not known before the step)
        qfrc_applied[v_at] = drive - (dry(v, drive - dry(v, load=False) - viscous * v) if dry.needs_load else dry(v))

    full = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state0 = np.empty(mujoco.mj_stateSize(model, full))
    mujoco.mj_getState(model, data, state0, full)  # the layout: time, qpos, qvel, ...
    state0 = np.tile(state0, (B, 1))
    clock = np.arange(B) * _BLOCK
    state0[:, 0] = clock
    state0[:, 1 + qadr], state0[:, 1 + model.nq + vadr] = q0, qd0
    mujoco.set_mjcb_control(applied)
    warned = len(_WARNINGS)
    _COLLECTING[0] = True
    try:
        state, _ = mujoco_rollout.rollout([models[id(fr)] for fr in frictions], data, state0,
                                          np.zeros((1, 1, model.nu)), nstep=steps)
    finally:
        mujoco.set_mjcb_control(None)
        _COLLECTING[0] = False
        del _WARNINGS[warned:]  # a diverged rollout is its NaN, not a warning line
    q, qd = state[:, :, 1 + qadr], state[:, :, 1 + model.nq + vadr]
    expected = clock[:, None] + np.arange(1, steps + 1) * timestep
    bad = ~(np.isfinite(q).all(axis=2) & np.isfinite(qd).all(axis=2)) | (np.abs(state[:, :, 0] - expected) > half)
    bad = np.logical_or.accumulate(bad, axis=1)
    return np.where(bad[..., None], np.nan, q), np.where(bad[..., None], np.nan, qd)


def log_drives(t: np.ndarray, tau: np.ndarray, start_times: np.ndarray, steps: int, timestep: float,
               delay: np.ndarray | None = None) -> np.ndarray:
    """(B, 2 steps + 1, n): a log's torques tau (N, n) at times t (N,) read at the stage times of rollouts
    starting at `start_times` (B,), by linear interpolation; with `delay` (n,) or (B, n), each joint's
    channel read that much later (a channel behind its encoder)."""
    at = start_times[:, None] + stage_times(steps, timestep)  # (B, S)
    shift = np.zeros((len(start_times), tau.shape[1])) if delay is None else np.broadcast_to(
        delay, (len(start_times), tau.shape[1]))
    return np.stack([np.interp(at + shift[:, j:j + 1], t, tau[:, j]) for j in range(tau.shape[1])], axis=-1)


def predict(spec: RobotSpec, gravity_W: np.ndarray, t: np.ndarray, q: np.ndarray, qd: np.ndarray, tau: np.ndarray,
            starts: np.ndarray, horizons: tuple[float, ...], timestep: float = PREDICTION_TIMESTEP,
            delay: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """How far a model drifts from a measured motion under its measured torques. From each start row
    s, MuJoCo starts at the measured (q, q') and integrates (`rollouts`: RK4, `timestep`) with the
    joint torques read from the log (linear interpolation in time, at every stage of every step; each
    channel `delay` (n,) s later where given), less the model's dry friction; at each horizon the error
    q_sim - q_meas and q'_sim - q'_meas. t (N,),
    q, qd, tau (N, n) in the spec's joint order; returns two (starts, horizons, n) arrays, NaN where
    the simulation diverged."""
    steps = [round(h / timestep) for h in horizons]
    drives = log_drives(t, tau, t[starts], steps[-1], timestep, delay)
    q_sim, qd_sim = rollouts(spec, gravity_W, [tuple(spec.frictions)] * len(starts), q[starts], qd[starts], drives,
                             timestep)
    at = t[starts][:, None] + np.array(steps) * timestep  # (starts, horizons)
    rows = np.array(steps) - 1
    return q_sim[:, rows] - sampled(t, q, at), qd_sim[:, rows] - sampled(t, qd, at)


# --- the robot as an MJCF file for others to simulate ----------------------------------------------


def mjcf(spec: RobotSpec, gravity_W: np.ndarray, comment: str = "") -> str:
    """The robot as an MJCF file: its bodies with their inertials, hinge and slide joints with their
    ranges, `armature` (rotor inertia), `damping` (viscous friction) and `frictionloss` (Coulomb
    friction, which MuJoCo applies as dry friction: the mapping of the smooth law is the caller's to
    state), and a motor per joint (gear 1) with the joint's effort limit as its force range. Built
    with MjSpec and written by MuJoCo's own writer, then every number it wrote rewritten from the
    MjSpec's doubles at full precision (the writer keeps six digits), so the file reloads to the bit.
    `comment` (plain text) heads the file."""
    import xml.etree.ElementTree as ET

    ms = _new_spec(spec.name, gravity_W)
    _robot(ms, spec)
    for joint in spec.joints:
        j = ms.joint(joint.name)
        j.frictionloss = joint.friction.coulomb
        lo, hi = (spec.limits or {}).get(joint.name, (-np.inf, np.inf))
        if np.isfinite(lo) and np.isfinite(hi):
            j.range = [lo, hi]
        effort = (spec.drive_limits or {}).get(joint.name, {}).get("effort")
        motor = ms.add_actuator(name=joint.name, target=joint.name, trntype=mujoco.mjtTrn.mjTRN_JOINT,
                                gear=[1.0, 0, 0, 0, 0, 0])
        if effort is not None:
            motor.forcerange = [-effort, effort]
    ms.compile()  # what MuJoCo refuses is refused here, not by the reader of the file
    root = ET.fromstring(ms.to_xml())
    for el in root.iter():
        _exact_numbers(el, ms, root)
    ET.indent(root)
    head = "".join(f"<!-- {line} -->\n" for line in comment.replace("--", "- -").splitlines())
    return head + ET.tostring(root, encoding="unicode") + "\n"


# what each MJCF attribute holds in the MjSpec element it belongs to
_ATTRIBUTES = {"body": {"pos": "pos", "quat": "quat"},
               "inertial": {"pos": "ipos", "quat": "iquat", "mass": "mass", "diaginertia": "inertia"},
               "joint": {"pos": "pos", "axis": "axis", "range": "range", "armature": "armature",
                         "damping": "damping", "frictionloss": "frictionloss"},
               "general": {"gear": "gear", "forcerange": "forcerange"},
               "option": {"gravity": "gravity"}}


def _exact_numbers(el, ms: mujoco.MjSpec, root) -> None:
    """Every number MuJoCo's writer put in `el` replaced by the double the MjSpec holds."""
    names = _ATTRIBUTES.get(el.tag)
    if names is None:
        return
    if el.tag == "inertial":
        owner = next(b for b in root.iter("body") if el in list(b))
        source = ms.body(owner.get("name"))
    elif el.tag == "option":
        source = ms.option
    else:
        source = {"body": ms.body, "joint": ms.joint, "general": ms.actuator}[el.tag](el.get("name"))
    for attribute, field in names.items():
        if el.get(attribute) is None:
            continue
        values = np.atleast_1d(np.asarray(getattr(source, field), dtype=float))
        written = len(el.get(attribute).split())
        el.set(attribute, " ".join(repr(float(v)) for v in values[:written]))
