"""MuJoCo as the test bench (the part ADAMS plays in the paper, section 3).

`build_spec` takes the robot as MuJoCo's model description (harness/model/mjspec.py: one MuJoCo body
per massive body, a massless carriage merged into its child) and makes it a bench: every joint gets a
motor (gear 1), a site at its
point O_J on the outer body with force and torque sensors, and joint position, velocity and
actuator-force sensors; every centre of mass gets a site with an accelerometer and gyro (site
frame) and frame sensors (world frame: position, orientation, linear and angular velocity and
acceleration). Contacts are disabled. A joint's rotor inertia is MuJoCo's `armature` and its viscous
friction MuJoCo's `damping`; Coulomb friction and offset are applied at every evaluation of the
dynamics as the generalised force of harness/model/friction.py.

`simulate` drives every joint along its prescribed motion by computed torque: at each step the
engine's own inverse dynamics (mj_inverse) gives the torques for q''_cmd = q''_d + 2 w e' + w^2 e,
applied as motor controls, then mj_step integrates. At each output row mj_forward evaluates the
state with the controls in force, so forces, accelerations and drive torques in a row belong to
one and the same instant. The torques of every evaluation inside each step (the four RK4 stages)
are kept in the recording's `drive` (harness/base/series.py, Drive), so that another model can be
driven by exactly the same input.

A closed chain's loops (harness/model/loops.py) are equality constraints between two sites, made
stiff (LOOP_SOLIMP, a time constant of two steps); its drive gives the actuated joints the computed
torque projected through the loops, G^T tau, and the passive joints nothing (`_loop_projection`), and
each row records every loop's gap and the loops' wrench on every body.
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Callable, Iterator
from contextlib import contextmanager

import mujoco
import numpy as np

from harness.base.series import Drive, TimeSeries
from harness.engines.simulation import EVALUATIONS_PER_STEP, Simulation
from harness.model import drives, friction
from harness.model.mjspec import add_contacts, add_robot, new_spec
from harness.model.quaternion import to_matrix
from harness.model.spec import Joint, RobotSpec

_MJ_INTEGRATOR = {"RK4": mujoco.mjtIntegrator.mjINT_RK4, "Euler": mujoco.mjtIntegrator.mjINT_EULER,
                  "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST}


def _driven(spec: RobotSpec, gravity_W: np.ndarray, integrator: str, timestep: float,
            floating: bool = False, ground: tuple = ()) -> tuple[mujoco.MjSpec, dict[str, mujoco.MjsBody]]:
    """The robot with its integrator and timestep, contacts off, and one motor per joint
    (`drive_<joint>`, control = torque): what `build_spec` and `dynamics_spec` share. With `floating`,
    its floating base on a free joint (harness/model/mjspec.py, add_robot); with `ground` (contacts, their
    ground points and frames), its feet held there as stiffly as a closed chain's loops (add_contacts)."""
    ms = new_spec(spec.name, gravity_W)
    ms.option.integrator = _MJ_INTEGRATOR[integrator]
    ms.option.timestep = float(timestep)
    ms.option.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
    elements = add_robot(ms, spec, floating=floating)
    if ground:
        add_contacts(ms, spec, elements, *ground)
    for joint in spec.joints:
        ms.add_actuator(name=f"drive_{joint.name}", target=joint.name, trntype=mujoco.mjtTrn.mjTRN_JOINT,
                        gear=[1.0, 0, 0, 0, 0, 0])
    if spec.loops or ground:  # stiff loops (LOOP_SOLIMP), their Jacobian dense for the drive's projection
        ms.option.jacobian = mujoco.mjtJacobian.mjJAC_DENSE
        ms.option.tolerance = LOOP_SOLVER_TOLERANCE
        for eq in ms.equalities:
            eq.solref, eq.solimp = [LOOP_TIME_CONSTANT_STEPS * float(timestep), 1.0], list(LOOP_SOLIMP)
    return ms, elements


# A loop's constraint is soft in MuJoCo: its impedance and reference acceleration make the loop's gap
# close as a damped spring. Stiff settings for closed chains: a time constant of 2 steps (MuJoCo's
# smallest, solref's time constant is clamped at twice the step) and an impedance of 0.9999 (MuJoCo's
# largest: the constraint force reaches 99.99 % of what a rigid loop needs). The built-in four-bar's
# 2 s run (scenarios/fourbar.toml, RK4): largest gap 1.7e-8 m at a 1 ms step, 4.2e-9 m at 0.5 ms (the
# gap goes as the step squared), against 3.0e-4 m with MuJoCo's defaults (solref 0.02 1, solimp 0.9
# 0.95 0.001 0.5 2) at 1 ms; the joints then track the motion to 8.8e-8, 2.2e-8 and 1.4e-3 rad.
LOOP_TIME_CONSTANT_STEPS = 2.0
LOOP_SOLIMP = (0.9999, 0.9999, 0.001, 0.5, 2.0)
# MuJoCo's constraint solver stops where its gradient is below tolerance times its scale; warm-started
# from the last step's accelerations it often stops there before its first Newton step, with the
# constraint forces off by about that tolerance (MuJoCo's default 1e-8). The loops' soft constraints
# make its cost quadratic, so one Newton step solves them to round-off: 1e-13 lets it take that step.
# The built-in gripper (two joint couplings, RK4, 0.25 ms) then agrees with Pinocchio to 1.5e-15 in its
# actuated torques, where the default left 1.7e-9; the four-bar's and parallelogram's figures, set by
# their loops' gaps, are as they were (7.7e-13 and 8.2e-13).
LOOP_SOLVER_TOLERANCE = 1e-13


def build_spec(spec: RobotSpec, gravity_W: np.ndarray, integrator: str = "RK4",
               timestep: float = 5e-4, floating: bool = False, ground: tuple = ()) -> mujoco.MjSpec:
    """The robot as MuJoCo's own model description (mujoco.MjSpec), which `build_model` compiles.
    Every number is set as the double it is, never through text (MuJoCo's own XML writer,
    `MjSpec.to_xml`, keeps six significant digits: harness/model/mjcf.py writes a file that reloads)."""
    ms, elements = _driven(spec, gravity_W, integrator, timestep, floating, ground)
    for body in spec.massive_bodies:
        el = elements[body.name]
        el.add_site(name=f"com_{body.name}", pos=np.zeros(3))
        # A carriage's joint shares its point with the child's joint (checked by the spec).
        chain = spec.massive_parent(body.name)[1]
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


ACCELERATION_STEP = 1024.0  # s: the Euler step of `acceleration_model` (a power of two: q'' = (q'_next - q') / h exact)


def acceleration_model(spec: RobotSpec, gravity_W: np.ndarray) -> mujoco.MjModel:
    """The robot as MuJoCo's forward dynamics of one state at a time, for `mujoco.rollout` to
    evaluate a batch of states in one call (harness/engines/rollout.py): one Euler step of
    ACCELERATION_STEP from (q, q') under the generalised force qfrc_applied gives q'_next = q' + h q'',
    with every force explicit (its damping too: mjDSBL_EULERDAMP), no actuator (the force is applied
    as it is), sensors and contacts off. The step's h is a power of two, so that
    q'' = (q'_next - q') / h loses at most the last bit of max(|q'| / h, |q''|)."""
    ms = new_spec(spec.name, gravity_W)
    ms.option.integrator = _MJ_INTEGRATOR["Euler"]
    ms.option.timestep = ACCELERATION_STEP
    off = mujoco.mjtDisableBit
    ms.option.disableflags |= off.mjDSBL_CONTACT | off.mjDSBL_EULERDAMP | off.mjDSBL_SENSOR
    add_robot(ms, spec)
    return ms.compile()


def inverse_dynamics(spec: RobotSpec, gravity_W: np.ndarray, q: np.ndarray, qd: np.ndarray,
                     qdd: np.ndarray) -> np.ndarray:
    """MuJoCo's inverse dynamics (mj_inverse's qfrc_inverse, (N, n) spec joint order) of the bench's model
    of `spec` (rotor inertia and viscous friction on the joints, or on the motors' tendons), plus the dry
    terms the bench applies beside them (Coulomb, offset and the families' terms, through N:
    harness/model/drives.py, Dry). With loops, qfrc_inverse less the constraint force MuJoCo's soft
    model makes of q'' (harness/model/closure.py projects it away)."""
    model = build_spec(spec, gravity_W).compile()
    data = mujoco.MjData(model)
    ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, j) for j in spec.joint_names]
    cols, pos = model.jnt_dofadr[ids], model.jnt_qposadr[ids]
    tau = np.empty_like(q)
    for k in range(len(q)):
        data.qpos[pos], data.qvel[cols], data.qacc[cols] = q[k], qd[k], qdd[k]
        mujoco.mj_inverse(model, data)
        tau[k] = data.qfrc_inverse[cols]
    dry = drives.Dry(spec.frictions, spec.transmission)
    if not dry.any:
        return tau
    if not dry.needs_load:
        return tau + dry(qd, q=q)
    # the load law reads the rigid bodies' torque: MuJoCo's own, its model without the drives
    return tau + dry(qd, inverse_dynamics(spec.rigid(), gravity_W, q, qd, qdd), q=q)


def _measured_at(spec: RobotSpec, joint: Joint) -> Joint:
    """The joint whose site measures `joint`: itself, or for a carriage's inner joint the
    carriage's outer joint (same point, same wrench: the carriage has no mass)."""
    return spec.carried_joint(joint.name)


def build_model(spec: RobotSpec, gravity_W: np.ndarray, simulation: Simulation,
                floating: bool = False, ground: tuple = ()) -> mujoco.MjModel:
    return build_spec(spec, gravity_W, simulation.integrator, simulation.timestep, floating, ground).compile()


def _log_warning(message: str) -> None:
    """MuJoCo's warnings go to the log, not to a MUJOCO_LOG.TXT in the working directory; while a
    simulation runs (`controlled`) they are only collected, and it decides what to do with them."""
    _WARNINGS.append(message)
    if not _COLLECTING[0]:
        logging.getLogger("harness.mujoco").warning(message)


_WARNINGS: list[str] = []
_COLLECTING = [False]
mujoco.set_mju_user_warning(_log_warning)

# MuJoCo's own verdict that a state is not finite or beyond its bounds (it then resets the data)
_UNSTABLE = (mujoco.mjtWarning.mjWARN_BADQPOS, mujoco.mjtWarning.mjWARN_BADQVEL, mujoco.mjtWarning.mjWARN_BADQACC,
             mujoco.mjtWarning.mjWARN_BADCTRL)


@contextmanager
def controlled(callback: Callable, keep_warnings: bool = True) -> Iterator[int]:
    """MuJoCo's control callback set to `callback` while the block runs, and MuJoCo's warnings
    collected, not logged (the block reads them from the index it is given on, in _WARNINGS). At its
    end they are logged (`keep_warnings`) or dropped (a diverged rollout is its NaN, not a warning line)."""
    mujoco.set_mjcb_control(callback)
    warned = len(_WARNINGS)
    _COLLECTING[0] = True
    try:
        yield warned
    finally:
        mujoco.set_mjcb_control(None)
        _COLLECTING[0] = False
        if not keep_warnings:
            del _WARNINGS[warned:]
    for message in _WARNINGS[warned:]:  # a block that raised says why itself
        logging.getLogger("harness.mujoco").warning(message)


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


def simulate(spec: RobotSpec, gravity_W: np.ndarray, prescribed: Callable, output_steps: int, output_dt: float,
             simulation: Simulation, base: Callable | None = None, contacts: tuple = ()) -> TimeSeries:
    """Forward-simulate the robot with mj_step along the prescribed motion (`prescribed(t)` ->
    (q, q', q''), each (len(t), n) in the spec's joint order) and record `output_steps + 1` rows
    from t = 0, `output_dt` apart. `simulation.timestep` must divide `output_dt`. With `base` (t ->
    harness.model.floating.BaseMotion), the floating base moves along it, driven by the world's wrench
    (harness/engines/free_base.py), and the recording keeps the base's motion and that wrench; with
    `contacts` (harness/model/contacts.py) the base stands on them, and the recording keeps their wrenches."""
    ground = ()
    if contacts:
        from harness.model.contacts import ground_frames, ground_points

        base0, q0 = base(np.zeros(1)), prescribed(np.zeros(1))[0][0]
        ground = (contacts, ground_points(spec, contacts, base0, q0), ground_frames(spec, contacts, base0, q0))
    model = build_model(spec, gravity_W, simulation, floating=base is not None, ground=ground)
    data = mujoco.MjData(model)
    dt = simulation.timestep
    substeps = round(output_dt / dt)
    n_rows = output_steps + 1
    n_steps = (n_rows - 1) * substeps
    # The integrators evaluate the dynamics at whole and half steps (RK4 stages): the prescribed
    # motion is evaluated once, batched, on that half-step grid
    half_steps = np.arange(2 * n_steps + 2) * (dt / 2.0)
    in_spec_order = prescribed(half_steps)
    if base is None:
        drive = _ComputedTorque(spec, model, data, in_spec_order, simulation, n_steps)
    else:
        from harness.engines.free_base import FreeBaseDrive

        drive = FreeBaseDrive(spec, model, in_spec_order, base(half_steps), simulation, n_steps, contacts)
    base_rows = np.empty((n_rows, drive.ROW)) if base is not None else None
    data.qpos[:], data.qvel[:] = drive.q_d[0], drive.qd_d[0]
    sensor_rows = np.empty((n_rows, model.nsensordata))
    qacc_rows = np.empty((n_rows, drive.n))
    gap_rows = np.empty((n_rows, len(spec.loops)))
    body_ids = np.array([model.body(b.name).id for b in spec.massive_bodies])
    wrench_rows = np.empty((n_rows, len(body_ids), 6)) if spec.loops else None
    constraint_rows = np.empty((n_rows, drive.n)) if spec.loops else None
    with controlled(drive.callback()) as warned:
        for row in range(n_rows):
            data.time = row * substeps * dt
            if row == 0 and contacts:
                drive.hold(data, 0.0, substeps * dt)
            mujoco.mj_forward(model, data)
            sensor_rows[row] = data.sensordata
            qacc_rows[row] = data.qacc[drive.vadr]
            if base_rows is not None:
                base_rows[row] = drive.base_rows(data)
            if spec.loops:
                gap_rows[row] = _loop_gaps(model, data)
                wrench_rows[row] = _loop_wrenches(model, data, body_ids)
                constraint_rows[row] = data.qfrc_constraint[drive.vadr]  # contacts and limits off: the loops' alone
            if row < n_rows - 1:
                if contacts:  # whether each holds until the next row
                    drive.hold(data, data.time, data.time + substeps * dt)
                drive.captured[1] = True
                mujoco.mj_step(model, data, substeps)  # one call for the steps to the next row
                if len(_WARNINGS) > warned and any(data.warning[k].number for k in _UNSTABLE):
                    # MuJoCo has reset the data: stop at the first such row, with its first message
                    raise _diverged(model, data, (row + 1) * substeps * dt, _WARNINGS[warned])
                drive.captured[1] = False
    t = np.arange(n_rows) * substeps * dt
    meta = {"engine": "mujoco", "engine_version": mujoco.__version__, "warnings": _WARNINGS[warned:],
            "tracking_bandwidth": simulation.tracking_bandwidth}
    driven = Drive(simulation.integrator, dt, substeps, drive.stages_by_step(),
                   *(x[::2 * substeps] for x in in_spec_order))
    rec = dataclasses.replace(_recorded(spec, model, gravity_W, t, sensor_rows, qacc_rows, meta), drive=driven)
    if base_rows is not None:
        from harness.engines.free_base import recorded_base

        rec = dataclasses.replace(rec, **recorded_base(base_rows, contacts))
    if not spec.loops:
        return rec
    meta["loop_settings"] = {"solref": model.eq_solref[0].tolist(), "solimp": model.eq_solimp[0].tolist()}
    return dataclasses.replace(rec, loops=tuple(loop.name for loop in spec.loops), loop_gap=gap_rows,
                               loop_F_W=wrench_rows[:, :, :3], loop_M_W=wrench_rows[:, :, 3:], loop_tau=constraint_rows)


def _loop_wrenches(model: mujoco.MjModel, data: mujoco.MjData, body_ids: np.ndarray) -> np.ndarray:
    """(nb, 6): the force and the moment about its centre of mass that the loops apply to each body,
    world components. With contacts off and nothing applied, a body's external wrench (cfrc_ext, set by
    the force sensors' mj_rnePostConstraint: [moment about the subtree's centre of mass of its tree's
    root; force]) is its loops'."""
    ext = data.cfrc_ext[body_ids]
    c = data.subtree_com[model.body_rootid[body_ids]]
    F = ext[:, 3:]
    return np.concatenate([F, ext[:, :3] + np.cross(c - data.xipos[body_ids], F)], axis=1)


def _loop_gaps(model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    """(n_loops,) m: how far apart each loop's joined points are (the norm of its first three
    constraint residuals, efc_pos, in MuJoCo's order of equalities); a coupling's one residual, rad or m
    as its follower moves."""
    rows = np.flatnonzero(data.efc_type[: data.nefc] == int(mujoco.mjtConstraint.mjCNSTR_EQUALITY))
    ids = data.efc_id[rows]
    return np.array([np.linalg.norm(data.efc_pos[rows[ids == k][:3]]) for k in range(model.neq)])


def _loop_projection(spec: RobotSpec, vadr: np.ndarray) -> Callable[[mujoco.MjModel, mujoco.MjData, np.ndarray], None]:
    """For a closed chain, the computed torque tau (every dof's, what the tree would need) made the
    actuated joints' tau_a = G^T tau and zero on the passive ones (harness/model/closure.py), G from the
    loops' rows of MuJoCo's own constraint Jacobian at the state being evaluated (efc_J, dense: checked
    against the harness's J in tests/test_closed_chains.py). Under S^T tau_a the constrained dynamics
    give G^T (M q'' + h) = tau_a: the actuated joints follow q''_cmd, the passive ones what the loops
    make of it."""
    from harness.model.closure import RANK

    act = vadr[[spec.joint_names.index(a) for a in spec.actuated]]
    passive = np.setdiff1d(vadr, act)
    equality = int(mujoco.mjtConstraint.mjCNSTR_EQUALITY)

    def project(m: mujoco.MjModel, d: mujoco.MjData, tau: np.ndarray) -> None:
        J = d.efc_J[: d.nefc * m.nv].reshape(d.nefc, m.nv)[d.efc_type[: d.nefc] == equality]
        G_p = -np.linalg.pinv(J[:, passive], rcond=RANK) @ J[:, act]
        tau[act] += G_p.T @ tau[passive]
        tau[passive] = 0.0

    return project


class _ComputedTorque:
    """The bench's drive, MuJoCo's control callback: computed torque at the state being evaluated,
    tau = M q''_cmd + bias - passive - applied, q''_cmd = q''_d + 2 w (q'_d - q') + w^2 (q_d - q) (M
    with the rotor inertias, passive the viscous friction, applied the Coulomb friction and offset set
    here from the joint velocities), called by MuJoCo after the velocity stage of every evaluation (on
    the one MjData simulated: `callback`). While captured[1] holds, each evaluation's torques are kept
    (`stages`, captured[0] of them so far).

    The prescribed motion's columns are put in MuJoCo's order of coordinates once (depth-first; the
    spec's is breadth-first), so that the callback, run at every stage of every step, reads and writes
    MjData's arrays whole, through views taken once, and every product into an array made once (each
    attribute access of MjData builds a new array object, each indexing a copy). The gains are arrays,
    and every ufunc's output is passed by position: a Python float operand and the `out=` keyword each
    cost a numpy call more than its arithmetic on seven numbers (the same products, bit for bit)."""

    def __init__(self, spec: RobotSpec, model: mujoco.MjModel, data: mujoco.MjData, in_spec_order: tuple,
                 simulation: Simulation, n_steps: int):
        qadr = np.array([model.joint(j).qposadr[0] for j in spec.joint_names])
        self.vadr = vadr = np.array([model.joint(j).dofadr[0] for j in spec.joint_names])
        act = np.array([model.actuator(f"drive_{j}").id for j in spec.joint_names])
        self.n = n = len(spec.joint_names)
        if not (model.nq == model.nv == model.nu == n and np.array_equal(qadr, vadr)):
            raise RuntimeError("the MuJoCo model has other coordinates or actuators than the spec's joints")
        self.q_d, self.qd_d, self.qdd_d = (np.empty_like(x) for x in in_spec_order)
        for x, y in zip((self.q_d, self.qd_d, self.qdd_d), in_spec_order, strict=True):
            x[:, vadr] = y
        at_dof = np.argsort(vadr)  # the spec joint at each dof
        self.transmission = spec.transmission
        if spec.transmission is None:  # each joint's own law, at its dof
            self.dry = friction.Dry.of(tuple(spec.frictions[j] for j in at_dof))
            self.armature = friction.values(spec.frictions)[at_dof, 0]
        else:  # the motors' laws through N (harness/model/drives.py), in the spec's joint order
            self.dry = drives.Dry(spec.frictions, spec.transmission)
            self.armature = drives.mass(spec.frictions, spec.transmission)
        to_ctrl = np.empty(n, dtype=int)
        to_ctrl[act] = vadr  # ctrl[a] is the drive of the joint at dof to_ctrl[a]
        self.to_ctrl = None if np.array_equal(to_ctrl, np.arange(n)) else to_ctrl
        self.per_step = EVALUATIONS_PER_STEP[simulation.integrator]  # evaluations in a step
        self.n_steps = n_steps
        self.stages = np.empty((n_steps * self.per_step, n))  # every evaluation's drive torques, by dof
        self.captured = [0, False]  # how many rows of `stages` are written, whether to write the next
        self.half = simulation.timestep / 2.0
        self.qpos, self.qvel, self.ctrl = data.qpos, data.qvel, data.ctrl
        self.qfrc_bias, self.qfrc_passive, self.qfrc_applied = data.qfrc_bias, data.qfrc_passive, data.qfrc_applied
        self.e, self.ed, self.qacc_cmd, self.tau = (np.empty(n) for _ in range(4))
        w = simulation.tracking_bandwidth
        self.kp, self.kd = np.full(n, w * w), np.full(n, 2.0 * w)
        self.project = _loop_projection(spec, vadr) if spec.loops else None

    def callback(self) -> Callable[[mujoco.MjModel, mujoco.MjData], None]:
        """The drive as MuJoCo calls it, its arrays bound as the closure's locals (an attribute lookup
        per array at each of a run's evaluations costs 5 % of kr500_rail's simulation)."""
        if self.transmission is not None:
            return self._through_transmission()
        project = self.project
        q_d, qd_d, qdd_d, half, kp, kd = self.q_d, self.qd_d, self.qdd_d, self.half, self.kp, self.kd
        qpos, qvel, ctrl, to_ctrl = self.qpos, self.qvel, self.ctrl, self.to_ctrl
        qfrc_bias, qfrc_passive, qfrc_applied = self.qfrc_bias, self.qfrc_passive, self.qfrc_applied
        e, ed, qacc_cmd, tau = self.e, self.ed, self.qacc_cmd, self.tau
        dry, armature, stages, captured = self.dry, self.armature, self.stages, self.captured
        add, subtract, multiply = np.add, np.subtract, np.multiply

        def drive(m: mujoco.MjModel, d: mujoco.MjData) -> None:
            k = round(d.time / half)
            multiply(subtract(q_d[k], qpos, e), kp, e)
            multiply(subtract(qd_d[k], qvel, ed), kd, ed)
            add(add(qdd_d[k], ed, qacc_cmd), e, qacc_cmd)
            mujoco.mj_mulM(m, d, tau, qacc_cmd)
            if dry.any:  # the rigid-body torque: the computed torque less the rotor inertia's part
                rigid = tau + qfrc_bias - armature * qacc_cmd if dry.needs_load else None
                np.negative(dry(qvel, rigid, q=qpos if dry.needs_position else None), out=qfrc_applied)
            add(tau, qfrc_bias, tau)
            subtract(tau, qfrc_passive, tau)
            subtract(tau, qfrc_applied, tau)
            if project is not None:
                project(m, d, tau)
            if to_ctrl is None:
                ctrl[:] = tau
            else:
                np.take(tau, to_ctrl, out=ctrl)
            if captured[1]:
                stages[captured[0]] = tau
                captured[0] += 1

        return drive

    def _through_transmission(self) -> Callable[[mujoco.MjModel, mujoco.MjData], None]:
        """The drive of `callback` where the motors' dry friction acts through the transmission, read and
        applied in the spec's joint order (the dofs at `vadr`); the rotors' inertia and viscous friction
        are MuJoCo's, on the motors' tendons."""
        q_d, qd_d, qdd_d, half, kp, kd = self.q_d, self.qd_d, self.qdd_d, self.half, self.kp, self.kd
        qpos, qvel, ctrl, to_ctrl, vadr = self.qpos, self.qvel, self.ctrl, self.to_ctrl, self.vadr
        qfrc_bias, qfrc_passive, qfrc_applied = self.qfrc_bias, self.qfrc_passive, self.qfrc_applied
        e, ed, qacc_cmd, tau = self.e, self.ed, self.qacc_cmd, self.tau
        dry, rotors, stages, captured = self.dry, self.armature, self.stages, self.captured
        order = np.argsort(vadr)  # the spec joint at each dof

        def drive(m: mujoco.MjModel, d: mujoco.MjData) -> None:
            k = round(d.time / half)
            np.multiply(np.subtract(q_d[k], qpos, e), kp, e)
            np.multiply(np.subtract(qd_d[k], qvel, ed), kd, ed)
            np.add(np.add(qdd_d[k], ed, qacc_cmd), e, qacc_cmd)
            mujoco.mj_mulM(m, d, tau, qacc_cmd)
            if dry.any:  # the rigid-body torque: the computed torque less the rotors' part, N^T I_m N q''
                rigid = (tau + qfrc_bias)[vadr] - rotors @ qacc_cmd[vadr] if dry.needs_load else None
                qfrc_applied[:] = -dry(qvel[vadr], rigid, q=qpos[vadr] if dry.needs_position else None)[order]
            tau[:] = tau + qfrc_bias - qfrc_passive - qfrc_applied
            ctrl[:] = tau if to_ctrl is None else tau[to_ctrl]
            if captured[1]:
                stages[captured[0]] = tau
                captured[0] += 1

        return drive

    def stages_by_step(self) -> np.ndarray:
        """(steps, evaluations per step, joints) in the spec's joint order."""
        return self.stages[:self.captured[0], self.vadr].reshape(self.n_steps, self.per_step, self.n)


def _recorded(spec: RobotSpec, model: mujoco.MjModel, gravity_W: np.ndarray, t: np.ndarray, sensor_rows: np.ndarray,
              qacc_rows: np.ndarray, meta: dict) -> TimeSeries:
    """The bench's sensors, row by row, as the recording (world components)."""
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
        raise Diverged(bad[0] if bad else "?", float(t[row]), "a sensor reads a value that is not finite")

    # Force/torque sensors report the wrench of the parent on the child about the site, in the
    # site frame (the outer body's frame); rotate to world components.
    site_R = np.stack([to_matrix(sensor(f"framequat_{_site_body(spec, j)}")) for j in spec.joints],
                      axis=1)
    F_W = np.einsum("njab,njb->nja", site_R, per_joint("force"))
    M_W = np.einsum("njab,njb->nja", site_R, per_joint("torque"))
    return TimeSeries(
        t=t, joints=tuple(spec.joint_names), bodies=tuple(b.name for b in spec.massive_bodies),
        q=per_joint("q")[..., 0], qd=per_joint("qd")[..., 0], qdd=qacc_rows, tau=per_joint("tau")[..., 0],
        F_W=F_W, M_W=M_W, p_W=per_body("framepos"), v_W=per_body("framelinvel"), R_WB=to_matrix(per_body("framequat")),
        a_W=per_body("framelinacc") + gravity_W,  # framelinacc is a - g (proper)
        omega_W=per_body("frameangvel"), omegadot_W=per_body("frameangacc"), meta=meta,
    )


def _site_body(spec: RobotSpec, joint: Joint) -> str:
    """Name of the massive body carrying the site that measures `joint`."""
    return _measured_at(spec, joint).child


