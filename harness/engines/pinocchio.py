"""Pinocchio as the independent second opinion: a model built from the RobotSpec directly (not
from the MuJoCo model built for it, so that a mistake in either builder shows up as a disagreement), and
inverse dynamics by RNEA.

Every joint frame sits at its joint point with world-aligned axes at the initial pose; a joint's
axis is its world axis there. Each massive body is attached to its inner joint with its mass,
its centre of mass relative to the joint point, and its inertia about the centre of mass rotated
into the joint frame (R_WB0 I_B R_WB0^T). A massless carriage is a joint with no body. Gravity is
the scenario's. The drives' rotor inertia and friction (harness/model/drives.py: each joint's own law,
or each motor's through the transmission) are added to RNEA's torques and the rotors' inertia to CRBA's
matrix by that module's law, outside Pinocchio (its own armature is diagonal, and covers the rotor
inertia only).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from harness.base.series import TimeSeries
from harness.model import drives, friction
from harness.model.drives import Transmission
from harness.model.friction import JointFriction
from harness.model.spec import WORLD, RobotSpec


@dataclass(frozen=True, eq=False)
class PinocchioModel:
    model: pin.Model
    joint_ids: tuple[int, ...]  # Pinocchio joint index of each spec joint, spec order
    q_index: np.ndarray  # index into q (and v) of each spec joint
    frictions: tuple[JointFriction, ...] = ()  # per spec joint, or per motor of `transmission`
    transmission: Transmission | None = None  # the drives' (harness/model/drives.py)


def build_model(spec: RobotSpec, gravity_W: np.ndarray, floating: bool = False) -> PinocchioModel:
    """The spec as a Pinocchio model; with `floating`, its floating base (spec.floating) a free-flyer
    joint first, its frame the file's base frame F (harness/model/floating.py), the joints from the
    world on it."""
    model = pin.Model()
    model.name = spec.name
    ids: dict[str, int] = {WORLD: 0}
    R_WF, p_WF = np.eye(3), np.zeros(3)  # the frame of the joints from the world: the world's, or the base's
    if floating:
        fb = spec.floating
        R_WF, p_WF = fb.R_WF0, fb.p_WF0
        ids[WORLD] = model.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), fb.joint)
        I_F = R_WF.T @ fb.body.R_WB0 @ fb.body.I_B @ fb.body.R_WB0.T @ R_WF
        model.appendBodyToJoint(ids[WORLD], pin.Inertia(fb.body.mass, R_WF.T @ (fb.body.p_W_com0 - p_WF), I_F),
                                pin.SE3.Identity())
    # depth first: Pinocchio's CRBA and regressors take every subtree to occupy consecutive
    # velocity indices (in root-first, breadth-first order a branched tree's M loses its couplings)
    for joint in _depth_first(spec):
        parent = ids[joint.parent]
        jm = (pin.JointModelRevoluteUnaligned if joint.revolute else pin.JointModelPrismaticUnaligned)(
            np.asarray(joint.axis_W0, dtype=float))
        if joint.parent == WORLD and floating and joint.name not in spec.floating.joints:  # on the ground
            parent, placement = 0, pin.SE3(np.eye(3), joint.p_W0)
        elif joint.parent == WORLD:  # every joint frame world-aligned at q = 0
            placement = pin.SE3(R_WF.T, R_WF.T @ (joint.p_W0 - p_WF))
        else:
            placement = pin.SE3(np.eye(3), joint.p_W0 - spec.inner_joint(joint.parent).p_W0)
        jid = model.addJoint(parent, jm, placement, joint.name)
        ids[joint.child] = jid
        body = spec.body(joint.child)
        if not body.massless:
            I_J = body.R_WB0 @ body.I_B @ body.R_WB0.T
            model.appendBodyToJoint(jid, pin.Inertia(body.mass, body.p_W_com0 - joint.p_W0, I_J),
                                    pin.SE3.Identity())
    model.gravity.linear = np.asarray(gravity_W, dtype=float)
    joint_ids = tuple(ids[j.child] for j in spec.joints)
    q_index = np.array([model.joints[i].idx_q for i in joint_ids], dtype=int)  # an index even with no joint
    return PinocchioModel(model, joint_ids, q_index, spec.frictions, spec.transmission)


def _depth_first(spec: RobotSpec) -> list:
    order: list = []

    def visit(body: str) -> None:
        for joint in spec.outer_joints(body):
            order.append(joint)
            visit(joint.child)

    visit(WORLD)
    return order


@dataclass(frozen=True, eq=False)
class InverseDynamics:
    tau: np.ndarray  # (N, joints) drive force or torque along each axis, spec order
    F_W: np.ndarray  # (N, joints, 3) force of the inner on the outer body across each joint
    M_W: np.ndarray  # (N, joints, 3) its moment about the joint point
    base: np.ndarray | None = None  # (N, 6) a moving floating base's rows: the world's wrench [F_W, M_W] on it


@dataclass(frozen=True, eq=False)
class PointForce:
    """A force f_W (N, 3) on a spec joint's outer body at the world point x_W (N, 3), with a moment
    m_W (N, 3) or None: what a closed chain's loop applies (harness/model/closure.py, multipliers)."""

    joint: int  # the spec joint whose outer body it acts on
    x_W: np.ndarray
    f_W: np.ndarray
    m_W: np.ndarray | None = None


def states(pm: PinocchioModel, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray,
           base=None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Pinocchio's configurations, velocities and accelerations, (N, nq), (N, nv), (N, nv), of the spec
    joints' states q, q', q'' (N, n; every other coordinate zero) and the spec joints' velocity indices (n,);
    with `base` (harness.model.floating.BaseMotion) and a model built with its floating base, the
    free-flyer's from the base's motion (harness/model/floating.py, to_pinocchio)."""
    model = pm.model
    v_index = np.array([model.joints[i].idx_v for i in pm.joint_ids], dtype=int)
    qq, vv, aa = np.zeros((len(q), model.nq)), np.zeros((len(q), model.nv)), np.zeros((len(q), model.nv))
    qq[:, pm.q_index], vv[:, v_index], aa[:, v_index] = q, qd, qdd
    if base is not None:
        from harness.model.floating import to_pinocchio

        qq[:, :7], vv[:, :6], aa[:, :6] = to_pinocchio(base)
    return qq, vv, aa, v_index


def rnea(pm: PinocchioModel, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray,
         external: tuple[PointForce, ...] = (), base=None) -> InverseDynamics:
    """RNEA at every sample (one call per state), with the joint wrenches data.f moved to world
    components: data.f[i] is the spatial force across joint i, [linear; angular] about the joint
    frame origin in the joint frame; oMi rotates it to the world. RNEA works with local placements
    and leaves data.oMi as it was, so forwardKinematics sets it for the same q. `external` forces
    act on the bodies (Pinocchio's fext, in each joint's frame about its origin): the torques are
    then M q'' + h - J^T f. With `base` (harness.model.floating.BaseMotion) and a model built with its
    floating base, the base moves so, and its six rows, the world's wrench on it, are kept (`base`)."""
    model = pm.model
    data = model.createData()
    N, nj = q.shape
    tau = np.empty((N, nj))
    F = np.empty((N, nj, 3))
    M = np.empty((N, nj, 3))
    qq, vv, aa, v_index = states(pm, q, qd, qdd, base)
    rows = np.empty((N, 6)) if base is not None else None
    fext = pin.StdVec_Force()
    for _ in range(model.njoints):
        fext.append(pin.Force.Zero())
    for k in range(N):
        if external:
            pin.forwardKinematics(model, data, qq[k])
            for i in range(model.njoints):
                fext[i] = pin.Force.Zero()
            for e in external:
                jid = pm.joint_ids[e.joint]
                R, p = data.oMi[jid].rotation, data.oMi[jid].translation
                moment = np.cross(e.x_W[k] - p, e.f_W[k]) + (0.0 if e.m_W is None else e.m_W[k])
                fext[jid] = fext[jid] + pin.Force(R.T @ e.f_W[k], R.T @ moment)
            full = pin.rnea(model, data, qq[k], vv[k], aa[k], fext)
        else:
            full = pin.rnea(model, data, qq[k], vv[k], aa[k])
            pin.forwardKinematics(model, data, qq[k])
        tau[k] = full[v_index]
        if rows is not None:
            rows[k] = full[:6]
        for j, jid in enumerate(pm.joint_ids):
            R = data.oMi[jid].rotation
            F[k, j] = R @ data.f[jid].linear
            M[k, j] = R @ data.f[jid].angular
    # the drives' friction and rotor inertia act between the bodies and their motors: in the
    # torques, not in the wrenches the joints transmit
    if rows is not None:
        from harness.model.floating import base_rows_from_pinocchio

        rows = base_rows_from_pinocchio(base, rows)
    return InverseDynamics(tau + drives.torque(pm.frictions, pm.transmission, qd, qdd, tau, q), F, M, rows)


def joint_torques(pm: PinocchioModel, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
    """(N, n): `rnea`'s joint torques alone (Pinocchio's rnea at every sample, the drives' friction and
    rotor inertia added), without the joint wrenches, whose forward kinematics cost twenty times the torques."""
    model = pm.model
    data = model.createData()
    qq, vv, aa = (np.zeros((len(q), model.nq)) for _ in range(3))
    qq[:, pm.q_index], vv[:, pm.q_index], aa[:, pm.q_index] = q, qd, qdd
    tau = np.empty((len(q), model.nv))
    for k in range(len(q)):
        tau[k] = pin.rnea(model, data, qq[k], vv[k], aa[k])
    tau = np.ascontiguousarray(tau[:, pm.q_index])  # row-major as `rnea`'s (the column selection is not):
    # the same numbers in the same order, so that what reduces them (a norm, a mean) sums them alike
    return tau + drives.torque(pm.frictions, pm.transmission, qd, qdd, tau, q)


def rnea_on_recording(spec: RobotSpec, gravity_W: np.ndarray, rec: TimeSeries) -> InverseDynamics:
    pm = build_model(spec, gravity_W)
    cols = [rec.joint_index(j) for j in spec.joint_names]
    return rnea(pm, rec.q[:, cols], rec.qd[:, cols], rec.qdd[:, cols])


def full_crba(model: pin.Model, data: pin.Data, q: np.ndarray) -> np.ndarray:
    """Pinocchio's CRBA at the configuration q as the whole symmetric mass matrix (CRBA fills its upper
    triangle alone)."""
    M = pin.crba(model, data, q)
    return np.triu(M) + np.triu(M, 1).T


def crba(pm: PinocchioModel, q: np.ndarray) -> np.ndarray:
    """Joint-space inertia matrix (CRBA) of the spec's joints at each configuration, (N, n, n)."""
    model = pm.model
    data = model.createData()
    out = np.empty((len(q), len(pm.q_index), len(pm.q_index)))
    full = np.zeros(model.nq)
    for k, qk in enumerate(q):
        full[pm.q_index] = qk
        out[k] = full_crba(model, data, full)[np.ix_(pm.q_index, pm.q_index)]
    return out + drives.mass(pm.frictions, pm.transmission) if pm.frictions else out


PROXIMAL = (1e-12, 1e-8, 20)  # accuracy, mu, iterations: mu > 0 keeps the constrained system regular where a
# planar loop's constraint row is zero (Pinocchio 4.1's defaults, mu = 0 and one iteration, answer the
# built-in four-bar as well: its acceleration equals harness/model/closure.py's to 2e-13 either way)


class NotSimulated(ValueError):
    """What Pinocchio's rigid loops do not simulate (constrained_rollout): friction that depends on the
    load, drives through a transmission."""


def constrained_rollout(pm: PinocchioModel, spec: RobotSpec, q0: np.ndarray, v0: np.ndarray,
                        stage_tau: np.ndarray, timestep: float, every: int) -> tuple[np.ndarray, np.ndarray]:
    """A closed chain's rigid forward dynamics, Pinocchio's constraintDynamics with every loop of the
    spec a RigidConstraintModel (a connect CONTACT_3D at its joined points, a weld CONTACT_6D at its
    joined frames; PROXIMAL settings), or, where every loop is a joint coupling (constant G), Pinocchio's
    CRBA and nonlinear effects projected, G^T M G q''_a = G^T (tau - h); integrated by RK4 from (q0, v0)
    (n,) under the joint torques given at each of its four stages, stage_tau (steps, 4, n) (the bench's
    drive stages), less each joint's friction at the stage's velocity (viscous, Coulomb, offset), its
    rotor inertia Pinocchio's armature: q and q' every `every` steps, each (steps // every + 1, n), spec
    joint order. Raises NotSimulated for friction that depends on the load (it would need the rigid-body
    torque the solve gives), for drives through a transmission and for couplings beside point loops."""
    model = pm.model
    law = pm.frictions if any(not f.none for f in pm.frictions) else ()
    if law:
        if pm.transmission is not None:
            raise NotSimulated("drives through a transmission are not simulated with rigid loops")
        dry = friction.Dry.of(law)
        if dry.needs_load:
            raise NotSimulated("a joint's friction depends on its load, which the rigid loops' solve gives: not "
                             "simulated with rigid loops")
        model = pin.Model(model)  # the armature set on a copy
        values = friction.values(law)
        model.armature[pm.q_index] = values[:, 0]
        viscous = values[:, 1]
    data = model.createData()
    couplings = [lp for lp in spec.loops if not lp.joins_points]
    if couplings and len(couplings) < len(spec.loops):
        raise NotSimulated("joint couplings beside point loops are not simulated with rigid loops (Pinocchio's "
                           "constraint models join frames, not joint coordinates)")
    pin.forwardKinematics(model, data, np.zeros(model.nq))
    cmodels, cdatas = pin.StdVec_RigidConstraintModel(), pin.StdVec_RigidConstraintData()
    for loop in spec.loops if not couplings else ():
        ends = []
        for body, p, R in ((loop.body_a, loop.point_a_W0, loop.R_W_frame_a0),
                           (loop.body_b, loop.point_b_W0, loop.R_W_frame_b0)):
            jid = 0 if body == WORLD else pm.joint_ids[spec.joint_names.index(spec.inner_joint(body).name)]
            ends.append((jid, data.oMi[jid].actInv(pin.SE3(np.eye(3) if R is None else R, np.asarray(p)))))
        kind = pin.ContactType.CONTACT_3D if loop.kind == "connect" else pin.ContactType.CONTACT_6D
        cm = pin.RigidConstraintModel(kind, model, ends[0][0], ends[0][1], ends[1][0], ends[1][1],
                                      pin.ReferenceFrame.LOCAL)
        cmodels.append(cm)
        cdatas.append(cm.createData())
    pin.initConstraintDynamics(model, data, cmodels, cdatas)
    prox = pin.ProximalSettings(*PROXIMAL)
    qq, vv, tt = np.zeros(model.nq), np.zeros(model.nv), np.zeros(model.nv)
    idx = pm.q_index

    if couplings:  # q' = G q'_a with G constant (harness/model/loops.py): G^T (M G q''_a + h) = G^T tau
        from harness.model.closure import ClosedChain, projection

        G = projection(ClosedChain.of(spec), np.zeros(len(idx)))[0]

    def qdd(q, v, tau):
        qq[idx], vv[idx], tt[idx] = q, v, (tau - viscous * v - dry(v, q=q)) if law else tau
        if not couplings:
            return pin.constraintDynamics(model, data, qq, vv, tt, cmodels, cdatas, prox)[idx]
        M = full_crba(model, data, qq)[np.ix_(idx, idx)]  # with the armature
        h = pin.nonLinearEffects(model, data, qq, vv)[idx]
        return G @ np.linalg.solve(G.T @ M @ G, G.T @ (tt[idx] - h))

    h = timestep
    q, v = np.array(q0, dtype=float), np.array(v0, dtype=float)
    out, out_v = [q.copy()], [v.copy()]
    for k, s in enumerate(stage_tau):
        a1 = qdd(q, v, s[0])
        v2 = v + h / 2 * a1
        a2 = qdd(q + h / 2 * v, v2, s[1])
        v3 = v + h / 2 * a2
        a3 = qdd(q + h / 2 * v2, v3, s[2])
        v4 = v + h * a3
        a4 = qdd(q + h * v3, v4, s[3])
        q = q + h / 6 * (v + 2 * v2 + 2 * v3 + v4)
        v = v + h / 6 * (a1 + 2 * a2 + 2 * a3 + a4)
        if (k + 1) % every == 0:
            out.append(q.copy()), out_v.append(v.copy())
    return np.array(out), np.array(out_v)
