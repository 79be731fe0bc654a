"""Inverse dynamics by the graph-theory model: joint force elements, active moments and drive
torques from the recorded motion alone (sections 2.1-2.2); no recorded joint force is read.

Newton (Eq. 22) with Eq. 17: m_i (r_i'' - g) = -sum_k S_e,ik F_k, so F = -S_e^-1 [m (r'' - g)].
S_e of a tree, in root-first order, is upper triangular with -1 on its diagonal, so this is back
substitution: the outermost body first. Euler (Eq. 23) with Eqs. 20, 26:
J_i omega_i' + omega_i x J_i omega_i = -sum_k (C_e,ik x F_k + S_ik M_k), so
M = -S^-1 [J omega' + omega x J omega + sum_k C_e,ik x F_k], M_k the moment about O_k.
The drive of O_k is the component of M_k (revolute) or F_k (prismatic) along its axis. A
massless carriage transmits its child's wrench unchanged, so the rail's wrench is O1's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from harness.base.heap import keep_heap
from harness.base.series import TimeSeries
from harness.model.kinematics import KinematicsBuffers, cross, forward_kinematics, joint_axes_W, rotate
from harness.model.spec import RobotSpec
from harness.papers.graph_theory_2021.cardano import A_0i_components
from harness.papers.graph_theory_2021.dynamics import GraphModel
from harness.papers.graph_theory_2021.topology import Topology, joint_arms_components


@dataclass(frozen=True, eq=False)
class GraphInverse:
    tau: np.ndarray  # (N, joints of the spec)
    F_W: np.ndarray  # (N, joints of the spec, 3) force element of each joint (inner on outer)
    M_W: np.ndarray  # (N, joints of the spec, 3) moment about each joint point


def inverse_dynamics(spec: RobotSpec, model: GraphModel, rec: TimeSeries) -> GraphInverse:
    """From a recording: Cardano angles, centre-of-mass accelerations, angular velocities and
    accelerations as measured, and the joint coordinates."""
    top = model.topology
    b = [rec.body_index(x) for x in top.bodies]
    q = rec.q[:, [rec.joint_index(j) for j in top.joints]]
    a, w, wd = (_samples_last(x, b) for x in (rec.a_W, rec.omega_W, rec.omegadot_W))
    # the angles only feed sines and cosines, which read a strided view as fast: no copy
    A = A_0i_components(_select(rec.theta, b).transpose(2, 1, 0))
    F, M = newton_euler(model, A, a, w, wd, *joint_arms_components(top, A, np.ascontiguousarray(q.T)))
    if any(j.revolute and spec.body(j.child).massless for j in spec.joints):
        # a hinge that turns a carriage: its axis turns with the hinges before it, read off the joint coordinates
        axes = joint_axes_W(spec, top.bodies, A.transpose(3, 2, 0, 1), rec.q[:, [rec.joint_index(j)
                                                                                   for j in spec.joint_names]])
        tau, F_W, M_W = joint_drives(spec, top, F, M, lambda jj, on: axes[:, jj].T)
    else:
        tau, F_W, M_W = joint_drives(spec, top, F, M, lambda jj, on: np.einsum(
            "ijn,j->in", A[:, :, top.bodies.index(on)], spec.body(on).R_WB0.T @ spec.joints[jj].axis_W0))
    return GraphInverse(np.ascontiguousarray(tau.T), F_W.transpose(2, 1, 0), M_W.transpose(2, 1, 0))


BLOCK = 2048  # states evaluated together from joint coordinates: 10 to 14 MiB of scratch (Panda), whatever N


def inverse_dynamics_of_motion(spec: RobotSpec, model: GraphModel, q: np.ndarray, qd: np.ndarray,
                               qdd: np.ndarray) -> GraphInverse:
    """From joint coordinates alone (spec joint order, (N, n)): the body motion by forward
    kinematics of the tree (harness/model/kinematics.py), then Newton-Euler as on a recording; in
    blocks of BLOCK states, so that the scratch memory is bounded and the time linear in N, the
    kinematics of each block written into the same arrays, the heap kept from block to block
    (harness/base/heap.py)."""
    keep_heap()
    q, qd, qdd = (np.atleast_2d(np.asarray(x, dtype=float)) for x in (q, qd, qdd))
    N, n = q.shape
    tau, F_W, M_W = np.empty((N, n)), np.empty((3, n, N)), np.empty((3, n, N))
    buffers = KinematicsBuffers.of(spec, min(N, BLOCK))
    for start in range(0, N, BLOCK):
        rows = slice(start, start + BLOCK)
        tau_T, F_W[:, :, rows], M_W[:, :, rows] = _of_motion(spec, model, q[rows], qd[rows], qdd[rows], buffers)
        tau[rows] = tau_T.T
    return GraphInverse(tau, F_W.transpose(2, 1, 0), M_W.transpose(2, 1, 0))


def _of_motion(spec: RobotSpec, model: GraphModel, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray,
               buffers: KinematicsBuffers) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One block: the drive torques (n, N) and the joints' F, M (3, n, N), spec joint order. The
    joint arms C_e,ik (Eq. 19) are read off the kinematics, which has every joint point and centre
    of mass in the world already: the joint point of the outer body less either body's centre of
    mass; so is each drive's axis."""
    args, buffers = motion_terms(spec, model, q, qd, qdd, buffers)
    F, M = newton_euler(model, *args)
    return joint_drives(spec, model.topology, F, M, lambda jj, on: buffers.axes[:, jj])


def motion_terms(spec: RobotSpec, model: GraphModel, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray,
                 buffers: KinematicsBuffers) -> tuple[tuple, KinematicsBuffers]:
    """`newton_euler`'s arguments from joint coordinates (A, r'', omega, omega', the joints' arms from the
    outer and inner bodies' centres of mass), and the buffers the kinematics was written into."""
    if len(q) != buffers.N:  # a last, shorter block
        buffers = KinematicsBuffers.of(spec, len(q))
    kin = forward_kinematics(spec, q, qd, qdd, velocities=False, buffers=buffers)
    top = model.topology
    b = [kin.body_index(x) for x in top.bodies]
    cols = [spec.joint_names.index(j) for j in top.joints]
    c = _select(buffers.c, b, axis=1)
    # the joint point of the outer body: the inner body's, slid along the axis across a prismatic joint
    O = np.take(buffers.points, cols, axis=1)
    for j, name in enumerate(top.joints):
        if not spec.joint(name).revolute:
            O[:, j] += buffers.axes[:, cols[j]] * q[:, cols[j]]
    c_out = O - c
    c_in = np.zeros_like(c_out)
    has_inner = top.inner >= 0
    c_in[:, has_inner] = O[:, has_inner] - c[:, top.inner[has_inner]]
    return (_select(buffers.R_WB, b, axis=2), _select(buffers.a, b, axis=1), _select(buffers.w, b, axis=1),
            _select(buffers.wd, b, axis=1), c_out, c_in), buffers


def _select(x: np.ndarray, index: list[int], axis: int = 1) -> np.ndarray:
    """x's entries listed along `axis` (bodies or joints), without a copy when they are all of them in order."""
    return x if index == list(range(x.shape[axis])) else np.take(x, index, axis=axis)


def _samples_last(x: np.ndarray, bodies: list[int]) -> np.ndarray:
    """(N, nb, 3) -> (3, n, N) of the bodies listed, as one contiguous array: what follows are then
    operations on whole (n, N) arrays, the samples contiguous (in an (N, n) layout the bodies'
    constants broadcast along an inner axis of n: the product with the masses took 3.7 times as long)."""
    return np.ascontiguousarray(_select(x, bodies).transpose(2, 1, 0))


def newton_euler(model: GraphModel, A: np.ndarray, a: np.ndarray, w: np.ndarray, wd: np.ndarray,
                 c_out: np.ndarray, c_in: np.ndarray, f_ext: np.ndarray | None = None,
                 m_ext: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Eqs. 22-23 solved for the force elements F_k and joint moments M_k (about O_k), all samples at
    once, in the graph's order. Component-major with the samples last: A (3, 3, n, N) with A[i, j]
    the entries A(0i)_ij; r_i'', omega_i, omega_i' and the arms from each joint's outer and inner
    body's centre of mass to the joint point (world components, zero where the inner body is the
    ground) each (3, n, N). Every step is an operation on whole (n, N) arrays, and each sum over
    joints one matrix product. Returns F, M, (3, n, N) each. `f_ext`, `m_ext` (3, n, N): forces on the
    bodies and their moments about each centre of mass from outside the tree (a closed chain's loops:
    harness/papers/graph_theory_2021/closed.py), on the right-hand side of Eqs. 22-23."""
    top = model.topology
    inertial = model.m[:, None] * (a - model.g_W[:, None, None])
    F = -(top.S_e_inv @ (inertial if f_ext is None else inertial - f_ext))
    P_out, P_in = top.outer_of, top.inner_of
    # sum_k C_e,ik x F_k, joint by joint: C = -c on the outer body, +c on the inner one
    C_x_F = P_in @ cross(c_in, F, axis=0)
    C_x_F -= P_out @ cross(c_out, F, axis=0)
    # J omega' + omega x J omega with J = A diag(J_B) A^T: in body components, then turned back
    A_T = np.swapaxes(A, 0, 1)
    w_B, wd_B = rotate(A_T, w), rotate(A_T, wd)
    J = model.J.T[:, :, None]  # (3, n, 1)
    body = cross(w_B, J * w_B, axis=0)
    body += J * wd_B
    C_x_F += rotate(A, body)
    if m_ext is not None:
        C_x_F -= m_ext
    M = -(top.S_inv @ C_x_F)
    return F, M


def joint_drives(spec: RobotSpec, top: Topology, F: np.ndarray, M: np.ndarray, axis_W) -> tuple:
    """Each spec joint's wrench is that of the graph joint it is or carries (a carriage transmits its
    child's); its drive is the moment (revolute) or force (prismatic) along its axis in the world,
    axis_W(jj, on) of the spec joint jj whose axis turns with body `on` (None: fixed to the ground).
    Returns tau (n_spec, N) and F, M (3, n_spec, N)."""
    carried = [spec.carried_joint(j.name) for j in spec.joints]
    k = [top.joints.index(c.name) for c in carried]
    F_out, M_out = _select(F, k, axis=1), _select(M, k, axis=1)
    tau = np.empty((len(spec.joints), F.shape[-1]))
    for jj, (joint, c) in enumerate(zip(spec.joints, carried, strict=True)):
        # the axis turns with the outer body of a revolute joint, with the inner body of a prismatic one
        on = c.child if joint.revolute else (joint.parent if joint.parent in top.bodies else None)
        u = joint.axis_W0[:, None] if on is None else axis_W(jj, on)
        np.einsum("an,an->n", (M_out if joint.revolute else F_out)[:, jj], u, out=tau[jj])
    return tau, F_out, M_out
