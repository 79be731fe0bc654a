"""Forward simulation of the constrained graph model (Eq. 111 integrated in time).

Cardano angles cannot be integrated through gimbal lock, which B1 of kr500 meets at t = 0 and
six times more in kr500_rail. While integrating, each body's orientation is therefore carried as
a unit quaternion and its rates as omega^(i) (quasi-velocities); the equations keep the paper's
structure: per body Newton-Euler (Eqs. 22-23, here with D = E), the same joint constraint rows
(harness.papers.graph_theory_2021.constraints, "normal" formulation) and Lagrange multipliers:

    [[M0, G^T], [G, 0]] [(r'', omega'); lambda] = [Q0; zeta - 2 a Phi' - b^2 Phi],
    M0 = blockdiag(m_i E, J_i),  Q0 = [m_i g + F_i^a ; M_i^a(i) - omega x J_i omega],

with Baumgarte stabilisation (a = b = BAUMGARTE rad/s) against drift of Phi. The drives are the
torques MuJoCo applied at every stage of its RK4 steps, and the integrator is the same RK4 with
the same step, so both engines integrate the same input.

Open loop, that replay cannot follow MuJoCo for long when the motion is unstable: in kr500_rail
the joints about the arm's own axis (O4, O6) are centrifugally unstable while the column spins,
and a deviation of 1e-16 grows about 30-fold per 0.1 s. MuJoCo holds them because its drive is a
feedback law. `reference` adds the same kind of correction on top of the recorded torques,
tau = tau_MuJoCo + I_J (w^2 e + 2 w e') with e the deviation from the prescribed motion and I_J
the model's composite inertia about the joint at the initial pose; the correction vanishes when
the two models agree, and its size relative to the drive is reported with the deviation.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from harness.base.series import TimeSeries
from harness.model import quaternion
from harness.model.kinematics import cross
from harness.model.spec import RobotSpec
from harness.papers.graph_theory_2021.cardano import A_0i
from harness.papers.graph_theory_2021.constrained import active_wrenches
from harness.papers.graph_theory_2021.constraints import ConstraintSet, State
from harness.papers.graph_theory_2021.dynamics import GraphModel

BAUMGARTE = 10.0  # rad/s: constraint errors decay like exp(-10 t), critically damped
# The correction must be stiffer than the instability it holds (growth rate about 31/s in
# kr500_rail): at 100 rad/s it is, and RK4 at 0.5 ms stays far inside its stability limit.
CORRECTION_BANDWIDTH = 100.0


@dataclass(frozen=True, eq=False)
class ForwardResult:
    t: np.ndarray  # output rows
    q: np.ndarray  # (rows, joints) joint coordinates of the spec's joints from the body states
    r: np.ndarray  # (rows, n, 3) centres of mass
    q_error: np.ndarray  # (joints,) largest |q - q_MuJoCo| over the rows
    r_error: float  # largest |r - r_MuJoCo| over bodies and rows
    max_abs_phi: float  # largest constraint violation over the rows
    feedback_ratio: np.ndarray  # (joints,) largest |correction| / largest |recorded drive|
    completed: bool  # False when stopped early, the deviation having exceeded `stop_above`


def _unpack(x: np.ndarray, n: int):
    r, Q, v, w = np.split(x.reshape(n, 13), [3, 7, 10], axis=1)
    return r, Q, v, w


def composite_inertia(spec: RobotSpec, model: GraphModel) -> np.ndarray:
    """Per joint of the spec, at the initial pose: the outboard bodies' moment of inertia about a
    revolute axis, or their mass for a prismatic joint."""
    out = []
    for joint in spec.joints:
        total = 0.0
        for body in spec.outboard_bodies(joint.name):
            if body.massless:
                continue
            if joint.revolute:
                u, d = joint.axis_W0, body.p_W_com0 - joint.p_W0
                J_W = body.R_WB0 @ body.I_B @ body.R_WB0.T
                total += u @ J_W @ u + body.mass * np.sum(cross(d, u) ** 2)
            else:
                total += body.mass
        out.append(total)
    return np.array(out)


def forward_simulate(spec: RobotSpec, model: GraphModel, constraints: ConstraintSet, rec: TimeSeries,
                     drive_stages: np.ndarray, dt: float, substeps: int,
                     reference: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]] | None = None,
                     bandwidth: float = CORRECTION_BANDWIDTH, stop_above: float = np.inf,
                     on_progress: Callable[[float], None] | None = None) -> ForwardResult:
    """Integrate from the recording's first row; compare every output row with the recording.

    reference(t) -> (q, q') of the spec's joints enables the correction described above."""
    top, n = model.topology, model.topology.n
    b = [rec.body_index(name) for name in top.bodies]
    A0 = A_0i(rec.theta[0, b])
    x = np.concatenate([rec.p_W[0, b], quaternion.from_matrix(A0), rec.v_W[0, b],
                        np.einsum("iba,ib->ia", A0, rec.omega_W[0, b])], axis=1).ravel()
    M0 = np.zeros((6 * n, 6 * n))
    for i in range(n):
        M0[6 * i: 6 * i + 3, 6 * i: 6 * i + 3] = model.m[i] * np.eye(3)
        M0[6 * i + 3: 6 * i + 6, 6 * i + 3: 6 * i + 6] = np.diag(model.J[i])
    m = constraints.m
    K = np.zeros((6 * n + m, 6 * n + m))
    K[: 6 * n, : 6 * n] = M0
    gain = composite_inertia(spec, model)
    revolute = np.array([j.revolute for j in spec.joints])
    read_joints = JointReader(spec, model)
    largest_correction = np.zeros(len(spec.joints))

    def f(x: np.ndarray, tau: np.ndarray, t: float) -> np.ndarray:
        r, Q, v, w = _unpack(x, n)
        A = quaternion.to_matrix(Q / np.linalg.norm(Q, axis=1, keepdims=True))
        if reference is not None:
            q, qd = read_joints(r[None], A[None], v[None], w[None])
            q_ref, qd_ref = reference(np.array([t]))
            e = q_ref[0] - q[0]
            e = np.where(revolute, (e + np.pi) % (2 * np.pi) - np.pi, e)  # one state: angle mod 2 pi
            correction = gain * (bandwidth**2 * e + 2 * bandwidth * (qd_ref[0] - qd[0]))
            np.maximum(largest_correction, np.abs(correction), out=largest_correction)
            tau = tau + correction
        s = State.quasi(r[None], A[None], v[None], w[None])
        phi, G, zeta = (a[0] for a in constraints.evaluate(s))
        F_a, M_a = (a[0] for a in active_wrenches(spec, model, tau[None], A[None], r[None]))
        Jw = model.J * w
        Q0 = np.concatenate([model.m[:, None] * model.g_W + F_a,
                             np.einsum("iba,ib->ia", A, M_a) - cross(w, Jw)], axis=1).ravel()
        K[: 6 * n, 6 * n:] = G.T
        K[6 * n:, : 6 * n] = G
        rhs = np.concatenate([Q0, zeta - 2 * BAUMGARTE * (G @ s.q_dot[0]) - BAUMGARTE**2 * phi])
        acc = np.linalg.solve(K, rhs)[: 6 * n].reshape(n, 6)
        return np.concatenate([v, quaternion.derivative(Q, w), acc[:, :3], acc[:, 3:]], axis=1).ravel()

    q_rec = rec.q[:, [rec.joint_index(j) for j in spec.joint_names]]
    rows, completed = [x], True
    for step in range(drive_stages.shape[0]):
        tau, t = drive_stages[step], step * dt
        k1 = f(x, tau[0], t)
        k2 = f(x + dt / 2 * k1, tau[1], t + dt / 2)
        k3 = f(x + dt / 2 * k2, tau[2], t + dt / 2)
        k4 = f(x + dt * k3, tau[3], t + dt)
        x = x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        r, Q, v, w = _unpack(x, n)
        x = np.concatenate([r, Q / np.linalg.norm(Q, axis=1, keepdims=True), v, w], axis=1).ravel()
        if (step + 1) % substeps == 0:
            rows.append(x)
            if on_progress is not None:
                on_progress((step + 1) / drive_stages.shape[0])
            X = x.reshape(1, n, 13)
            q_now = read_joints(X[..., :3], quaternion.to_matrix(X[..., 3:7]),
                                X[..., 7:10], X[..., 10:])[0][0]
            if np.max(np.abs(q_now - q_rec[len(rows) - 1])) > stop_above:
                completed = False
                break

    X = np.array(rows).reshape(len(rows), n, 13)
    r, A = X[..., :3], quaternion.to_matrix(X[..., 3:7])
    q, _ = read_joints(r, A, X[..., 7:10], X[..., 10:])
    phi = constraints.evaluate(State.quasi(r, A, X[..., 7:10], X[..., 10:]))[0]
    k = len(rows)
    drive = np.max(np.abs(rec.tau[:, [rec.joint_index(j) for j in spec.joint_names]]), axis=0)
    return ForwardResult(rec.t[:k], q, r, np.max(np.abs(q - q_rec[:k]), axis=0),
                         float(np.max(np.linalg.norm(r - rec.p_W[:k, b], axis=-1))),
                         float(np.max(np.abs(phi))), largest_correction / np.maximum(drive, 1e-300),
                         completed)


@dataclass(frozen=True, eq=False)
class _Joint:
    revolute: bool
    axis_W0: np.ndarray
    carrier: int  # the body whose motion the joint's coordinate measures
    parent: int | None  # None: the world, or a carriage (never turns)
    child: int | None
    R0_parent_T: np.ndarray | None  # the parent's / child's initial orientation, transposed
    R0_child_T: np.ndarray | None
    arm_carrier: np.ndarray  # the joint point from the carrier's centre of mass, body frame
    arm_parent: np.ndarray | None  # the joint point from the parent's centre of mass, body frame
    p_W0: np.ndarray


class JointReader:
    """Joint coordinates and rates of the spec's joints from the bodies' states (N, n, ...):
    a revolute angle from the relative rotation about the axis and its rate from the relative
    angular velocity; a prismatic displacement of the joint point along the axis and its rate.
    Angles are unwrapped along the series. The tree is looked up once, here: the forward
    simulation reads the joints at every evaluation of its right-hand side."""

    def __init__(self, spec: RobotSpec, model: GraphModel):
        top = model.topology
        index = {b: i for i, b in enumerate(top.bodies)}
        self.joints = []
        for joint in spec.joints:
            carrier = spec.carried_joint(joint.name).child
            j = index[carrier]
            k = top.joints.index(spec.inner_joint(carrier).name)
            parent, child = index.get(joint.parent), index.get(joint.child)
            self.joints.append(_Joint(
                joint.revolute, joint.axis_W0, j, parent, child,
                None if parent is None else spec.body(joint.parent).R_WB0.T,
                None if child is None else spec.body(joint.child).R_WB0.T,
                top.c_B[j, k], None if parent is None else top.c_B[parent, top.joints.index(joint.name)],
                joint.p_W0))

    def __call__(self, r: np.ndarray, A: np.ndarray, v: np.ndarray,
                 omega_B: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        N = r.shape[0]
        eye = np.broadcast_to(np.eye(3), (N, 3, 3))
        w_W = np.einsum("niab,nib->nia", A, omega_B)
        zero = np.zeros((N, 3))
        out = np.zeros((N, len(self.joints)))
        rate = np.zeros((N, len(self.joints)))
        for jj, joint in enumerate(self.joints):
            i, j = joint.parent, joint.carrier
            R_in = eye if i is None else A[:, i] @ joint.R0_parent_T  # rotation from the initial pose
            u = np.einsum("nab,b->na", R_in, joint.axis_W0)
            if joint.revolute:
                R_out = eye if joint.child is None else A[:, joint.child] @ joint.R0_child_T
                R_rel = np.swapaxes(R_in, 1, 2) @ R_out
                vee = np.stack([R_rel[:, 2, 1] - R_rel[:, 1, 2], R_rel[:, 0, 2] - R_rel[:, 2, 0],
                                R_rel[:, 1, 0] - R_rel[:, 0, 1]], -1) / 2
                cos = (np.trace(R_rel, axis1=1, axis2=2) - 1) / 2
                angle = np.arctan2(vee @ joint.axis_W0, cos)
                out[:, jj] = np.unwrap(angle) if N > 1 else angle
                rate[:, jj] = np.einsum("na,na->n", u, w_W[:, j] - (zero if i is None else w_W[:, i]))
            else:
                arm = np.einsum("nab,b->na", A[:, j], joint.arm_carrier)
                point, point_dot = r[:, j] + arm, v[:, j] + cross(w_W[:, j], arm)
                if i is None:
                    origin, origin_dot, w_in = joint.p_W0, zero, zero
                else:
                    arm_i = np.einsum("nab,b->na", A[:, i], joint.arm_parent)
                    origin, origin_dot, w_in = r[:, i] + arm_i, v[:, i] + cross(w_W[:, i], arm_i), w_W[:, i]
                out[:, jj] = np.einsum("na,na->n", point - origin, u)
                rate[:, jj] = (np.einsum("na,na->n", point_dot - origin_dot, u)
                               + np.einsum("na,na->n", point - origin, cross(w_in, u)))
        return out, rate
