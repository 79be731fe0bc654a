"""The bench's drive of a robot whose floating base moves (a scenario's `[base_motion]`): computed
torque on every coordinate, the base's six included, each evaluation of the dynamics.

The base is held by nothing but the wrench the drive has the world apply to it: MuJoCo's free joint
(harness/model/floating.py: qpos [p_W, w x y z], qvel [v_W, omega_B]) is driven as a joint is, its
generalised force [F_W, M_B] applied as qfrc_applied, the joints' torques as their motors' controls.
The tracking error is taken on the manifold: e = q_d (-) q (MuJoCo's mj_differentiatePos: the
position's difference, and the base's rotation from q to q_d as the body-axes rotation vector
log(R^T R_d), exact at any angle), and

    q''_cmd = q''_d + 2 w (q'_d - q') + w^2 e,    tau = M q''_cmd + bias - passive - applied

(M with the rotor inertias; passive the viscous friction; applied the joints' Coulomb friction and offset
set here). The base's six rows of tau are the world's wrench on the base: what the bench records as its
answer (`base_rows`), with the base's pose, twist and acceleration.

Standing on contacts (harness/model/contacts.py: MuJoCo's connect equalities, a sole's weld, held or released
between rows, `hold`), the world acts through them: with J the held contacts' rows of MuJoCo's constraint
Jacobian (efc_J, world components, d(x_foot - x_ground)/dq), the contact forces mu the least-squares
solution of J_base^T mu = tau_base, and

    ctrl = tau_joints - J_joints^T mu,    applied on the base = tau_base - J_base^T mu

MuJoCo's constraint forces are then mu (its constrained dynamics, M q'' + bias = passive + applied +
ctrl + J^T lambda, are met by q''_cmd and lambda = mu, to its loops' softness): the base is held by its
feet, and by the world's own wrench only where they cannot balance it (fewer than three points, or
three in a line), recorded as before. Each contact's force on its body (a sole's moment too: `_weld_wrench`),
where its point is and whether it held are recorded beside the base's rows. Two soles, or more points than
the base's rows need, are statically indeterminate: mu is then the least-norm split among them.
"""

from __future__ import annotations

from collections.abc import Callable

import mujoco
import numpy as np

from harness.engines.simulation import EVALUATIONS_PER_STEP, Simulation
from harness.model import drives, floating, friction
from harness.model.floating import BaseMotion
from harness.model.spec import RobotSpec


class FreeBaseDrive:
    """MuJoCo's control callback for a robot on its free joint (module docstring): `callback` to set,
    `base_rows` to read the base's state and wrench after an evaluation, `stages_by_step` for the joints'
    torques at every evaluation of every step (while captured[1] holds), as harness/engines/mujoco.py's
    computed torque gives them."""

    def __init__(self, spec: RobotSpec, model: mujoco.MjModel, in_spec_order: tuple, base: BaseMotion,
                 simulation: Simulation, n_steps: int, contacts: tuple = ()):
        """in_spec_order (q, q', q'') and `base` the prescribed motion on the half-step grid; `contacts` the
        feet the model holds (harness/engines/mujoco.py, build_model's `ground`)."""
        if spec.loops:
            raise ValueError(f"{spec.name}: a floating base moved with loops is not simulated")
        self._model = model
        free = model.joint(spec.floating.joint)
        self.base_q, self.base_v = int(free.qposadr[0]), int(free.dofadr[0])
        self.qadr = np.array([model.joint(j).qposadr[0] for j in spec.joint_names], dtype=int)
        self.vadr = np.array([model.joint(j).dofadr[0] for j in spec.joint_names], dtype=int)
        self.act = np.array([model.actuator(f"drive_{j}").id for j in spec.joint_names], dtype=int)
        self.n = n = len(spec.joint_names)
        self.contacts = contacts
        self.eq_ids = np.array([model.equality(f"contact_{c.name}").id for c in contacts], dtype=int)
        self.site_ids = np.array([model.site(f"contact_{c.name}").id for c in contacts], dtype=int)
        self.soles = [c.sole for c in contacts]
        self.ROW = 25 + 10 * len(contacts)
        if model.nv != n + 6 or model.nu != n:
            raise RuntimeError("the MuJoCo model has other coordinates or actuators than the base and the joints")
        qpos, qvel, qacc = floating.to_mujoco(base)
        K = len(base)
        self.q_d, self.qd_d, self.qdd_d = np.empty((K, model.nq)), np.empty((K, model.nv)), np.empty((K, model.nv))
        bq, bv = slice(self.base_q, self.base_q + 7), slice(self.base_v, self.base_v + 6)
        self.q_d[:, bq], self.qd_d[:, bv], self.qdd_d[:, bv] = qpos, qvel, qacc
        self.q_d[:, self.qadr], self.qd_d[:, self.vadr], self.qdd_d[:, self.vadr] = in_spec_order
        if spec.transmission is None:  # each joint's own law
            self.dry = friction.Dry.of(tuple(spec.frictions))
            self.armature = friction.values(spec.frictions)[:, 0]
        else:  # the motors' laws through N (harness/model/drives.py), in the spec's joint order; their rotors' inertia
            # and viscous friction are MuJoCo's, on the motors' tendons (harness/model/mjspec.py)
            self.dry = drives.Dry(spec.frictions, spec.transmission)
            self.armature = drives.mass(spec.frictions, spec.transmission)
        self.per_step = EVALUATIONS_PER_STEP[simulation.integrator]
        self.n_steps = n_steps
        self.stages = np.empty((n_steps * self.per_step, n))
        self.captured = [0, False]
        self.half = simulation.timestep / 2.0
        w = simulation.tracking_bandwidth
        self.kp, self.kd = w * w, 2.0 * w

    def callback(self) -> Callable[[mujoco.MjModel, mujoco.MjData], None]:
        q_d, qd_d, qdd_d, half, kp, kd = self.q_d, self.qd_d, self.qdd_d, self.half, self.kp, self.kd
        vadr, qadr, act, base = self.vadr, self.qadr, self.act, slice(self.base_v, self.base_v + 6)
        dry, armature, stages, captured = self.dry, self.armature, self.stages, self.captured
        e, tau = np.empty(len(qd_d[0])), np.empty(len(qd_d[0]))
        standing, equality = len(self.contacts) > 0, int(mujoco.mjtConstraint.mjCNSTR_EQUALITY)
        if armature.ndim == 1:  # the rotors' part of the computed torque: diag(I_a) q'', or N^T diag(I_m) N q''
            def rotors(qdd: np.ndarray) -> np.ndarray:
                return armature * qdd
        else:
            def rotors(qdd: np.ndarray) -> np.ndarray:
                return armature @ qdd

        def drive(m: mujoco.MjModel, d: mujoco.MjData) -> None:
            k = round(d.time / half)
            mujoco.mj_differentiatePos(m, e, 1.0, d.qpos, q_d[k])  # q_d (-) q
            qacc_cmd = qdd_d[k] + kd * (qd_d[k] - d.qvel) + kp * e
            mujoco.mj_mulM(m, d, tau, qacc_cmd)
            applied = d.qfrc_applied
            applied[:] = 0.0
            if dry.any:  # the rigid-body torque: the computed torque less the rotor inertia's part
                rigid = (tau + d.qfrc_bias)[vadr] - rotors(qacc_cmd[vadr]) if dry.needs_load else None
                applied[vadr] = -dry(d.qvel[vadr], rigid, q=d.qpos[qadr] if dry.needs_position else None)
            full = tau + d.qfrc_bias - d.qfrc_passive - applied
            if standing:  # the held contacts balance the base's rows as far as they can (module docstring)
                J = d.efc_J[: d.nefc * m.nv].reshape(d.nefc, m.nv)[d.efc_type[: d.nefc] == equality]
                if len(J):
                    full -= J.T @ np.linalg.lstsq(J[:, base].T, full[base], rcond=None)[0]
            applied[base] = full[base]  # the world's wrench on the base (besides the contacts)
            d.ctrl[act] = full[vadr]
            if captured[1]:
                stages[captured[0]] = full[vadr]
                captured[0] += 1

        return drive

    def hold(self, d: mujoco.MjData, t0: float, t1: float) -> None:
        """Each contact held from t0 to t1 where it is planted then (at the middle: a lift's ends are rows)."""
        middle = np.array([(t0 + t1) / 2.0])
        d.eq_active[self.eq_ids] = [bool(c.planted(middle)[0]) for c in self.contacts]

    def base_rows(self, d: mujoco.MjData) -> np.ndarray:
        """(ROW,) the base's qpos (7), qvel (6), qacc (6) and the world's wrench on it (6), MuJoCo's convention,
        then each contact's force and moment on its body (world components, the moment about its point: a
        point's zero), its point and whether it held (10 each)."""
        bq, bv = self.base_q, self.base_v
        out = [d.qpos[bq:bq + 7], d.qvel[bv:bv + 6], d.qacc[bv:bv + 6], d.qfrc_applied[bv:bv + 6]]
        if len(self.contacts):
            m = self._model
            rows = np.flatnonzero(d.efc_type[: d.nefc] == int(mujoco.mjtConstraint.mjCNSTR_EQUALITY))
            for eq, site, sole in zip(self.eq_ids, self.site_ids, self.soles, strict=True):
                mine = rows[d.efc_id[rows] == eq]
                if not len(mine):
                    wrench = np.zeros(6)
                elif sole:
                    wrench = _weld_wrench(m, d, mine, site)
                else:
                    wrench = np.concatenate([d.efc_force[mine], np.zeros(3)])
                out += [wrench, d.site_xpos[site], [float(d.eq_active[eq])]]
        return np.concatenate(out)

    def stages_by_step(self) -> np.ndarray:
        """(steps, evaluations per step, joints) in the spec's joint order."""
        return self.stages[:self.captured[0]].reshape(self.n_steps, self.per_step, self.n)


def _weld_wrench(m: mujoco.MjModel, d: mujoco.MjData, rows: np.ndarray, site: int) -> np.ndarray:
    """(6,) a weld's force and moment on its body, world components, the moment about its site: the wrench
    [F; M] whose generalised force through the site's point and angular Jacobians (mj_jacSite, world axes) is
    the weld's, J_eq^T lambda (efc_J's and efc_force's rows of the weld). Convention-free: MuJoCo's rotation
    rows are the angular Jacobian turned and scaled by the weld's orientation error and torquescale, which this
    does not need to know."""
    jacp, jacr = np.zeros((3, m.nv)), np.zeros((3, m.nv))
    mujoco.mj_jacSite(m, d, jacp, jacr, site)
    J_eq = d.efc_J[: d.nefc * m.nv].reshape(d.nefc, m.nv)[rows]
    return np.linalg.lstsq(np.concatenate([jacp, jacr]).T, J_eq.T @ d.efc_force[rows], rcond=None)[0]


def recorded_base(rows: np.ndarray, contacts: tuple = ()) -> dict:
    """A recording's base fields (harness/base/series.py, the harness's convention) from `base_rows`' (N, ROW),
    and its contacts' (a point contact's moment zero)."""
    motion = floating.from_mujoco(rows[:, :7], rows[:, 7:13], rows[:, 13:19])
    pose, twist, rate = motion.rows()
    out = {"base_pose": pose, "base_twist_W": twist, "base_rate_W": rate,
           "base_wrench_W": floating.base_rows_from_mujoco(motion, rows[:, 19:25])}
    if contacts:
        each = rows[:, 25:].reshape(len(rows), len(contacts), 10)
        out.update(contacts=tuple(c.name for c in contacts), contact_F_W=each[..., :3], contact_M_W=each[..., 3:6],
                   contact_x_W=each[..., 6:9], contact_held=each[..., 9] > 0.5)
    return out
