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

from harness.engines.recording import Recording
from harness.model.kinematics import cross, forward_kinematics, rotate
from harness.model.spec import RobotSpec
from harness.papers.graph_theory_2021.cardano import A_0i_components
from harness.papers.graph_theory_2021.dynamics import GraphModel
from harness.papers.graph_theory_2021.topology import joint_arms_components


@dataclass(frozen=True, eq=False)
class GraphInverse:
    tau: np.ndarray  # (N, joints of the spec)
    F_W: np.ndarray  # (N, joints of the spec, 3) force element of each joint (inner on outer)
    M_W: np.ndarray  # (N, joints of the spec, 3) moment about each joint point


def inverse_dynamics(spec: RobotSpec, model: GraphModel, rec: Recording) -> GraphInverse:
    """From a recording: Cardano angles, centre-of-mass accelerations, angular velocities and
    accelerations as measured, and the joint coordinates."""
    top = model.topology
    b = [rec.body_index(x) for x in top.bodies]
    q = rec.q[:, [rec.joint_index(j) for j in top.joints]]
    a_c, w_c, wd_c = (_components(x, b) for x in (rec.a_W, rec.omega_W, rec.omegadot_W))
    # the angles only feed sines and cosines, which read a strided view as fast: no copy
    return newton_euler(spec, model, q, A_0i_components(np.moveaxis(_bodies(rec.theta, b), -1, 0)), a_c, w_c, wd_c)


BLOCK = 2048  # states evaluated together from joint coordinates: about 12 MiB of scratch (Panda), whatever N


def inverse_dynamics_of_motion(spec: RobotSpec, model: GraphModel, q: np.ndarray, qd: np.ndarray,
                               qdd: np.ndarray) -> GraphInverse:
    """From joint coordinates alone (spec joint order, (N, n)): the body motion by forward
    kinematics of the tree (harness/model/kinematics.py), then Newton-Euler as on a recording; in
    blocks of BLOCK states, so that the scratch memory is bounded and the time linear in N."""
    q, qd, qdd = (np.atleast_2d(np.asarray(x, dtype=float)) for x in (q, qd, qdd))
    N = len(q)
    if N <= BLOCK:
        return _of_motion(spec, model, q, qd, qdd)
    n = len(spec.joints)
    tau, F_W, M_W = np.empty((N, n)), np.empty((N, n, 3)), np.empty((N, n, 3))
    for start in range(0, N, BLOCK):
        rows = slice(start, start + BLOCK)
        out = _of_motion(spec, model, q[rows], qd[rows], qdd[rows])
        tau[rows], F_W[rows], M_W[rows] = out.tau, out.F_W, out.M_W
    return GraphInverse(tau, F_W, M_W)


def _of_motion(spec: RobotSpec, model: GraphModel, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> GraphInverse:
    kin = forward_kinematics(spec, q, qd, qdd, velocities=False)
    top = model.topology
    b = [kin.body_index(x) for x in top.bodies]
    cols = [spec.joint_names.index(j) for j in top.joints]
    A_c = np.ascontiguousarray(np.moveaxis(_bodies(kin.R_WB, b), (-2, -1), (0, 1)))
    return newton_euler(spec, model, q[:, cols], A_c,
                        *(_components(x, b) for x in (kin.a_W_com, kin.omega_W, kin.omegadot_W)))


def _bodies(x: np.ndarray, bodies: list[int]) -> np.ndarray:
    """x[:, bodies], without a copy when they are all the bodies in order."""
    return x if bodies == list(range(x.shape[1])) else x[:, bodies]


def _components(x: np.ndarray, bodies: list[int]) -> np.ndarray:
    """(N, nb, 3) -> (3, N, n) of the bodies listed, as one contiguous array (what follows runs four
    times faster on it than on a strided view)."""
    return np.ascontiguousarray(np.moveaxis(_bodies(x, bodies), -1, 0))


def newton_euler(spec: RobotSpec, model: GraphModel, q: np.ndarray, A_c: np.ndarray, a_c: np.ndarray,
                 w_c: np.ndarray, wd_c: np.ndarray) -> GraphInverse:
    """Eqs. 22-23 solved for the force elements and joint moments, all samples at once. Inputs in
    the graph's order and component-major form: q (N, joints), A_c (3, 3, N, n) with A_c[i, j] the
    entries A(0i)_ij, and the world components of r_i'', omega_i, omega_i' as (3, N, n) arrays.
    Every step is then an operation on whole (N, n) arrays, and each sum over joints one matrix
    product (the (N, n, 3) layout made it 2.5 times slower)."""
    top = model.topology
    F = -((model.m * (a_c - model.g_W[:, None, None])) @ np.linalg.inv(top.S_e.astype(float)).T)
    c_out, c_in = joint_arms_components(top, A_c, q)
    P_out, P_in = (top.S == -1).astype(float), (top.S == 1).astype(float)
    # sum_k C_e,ik x F_k, joint by joint: C = -c on the outer body, +c on the inner one
    C_x_F = cross(c_in, F, axis=0) @ P_in.T - cross(c_out, F, axis=0) @ P_out.T
    # J omega' + omega x J omega with J = A diag(J_B) A^T: in body components, then turned back
    A_T = np.swapaxes(A_c, 0, 1)
    w_B, wd_B = rotate(A_T, w_c), rotate(A_T, wd_c)
    J = model.J.T[:, None, :]  # (3, 1, n)
    euler = rotate(A_c, J * wd_B + cross(w_B, J * w_B, axis=0))
    M = -((euler + C_x_F) @ np.linalg.inv(top.S.astype(float)).T)

    # each spec joint's wrench is that of the graph joint it is or carries (a carriage transmits its
    # child's); its drive is the moment (revolute) or force (prismatic) along its axis in the world
    carried = [spec.carried_joint(j.name) for j in spec.joints]
    k = [top.joints.index(c.name) for c in carried]
    F_out, M_out = np.moveaxis(F[:, :, k], 0, -1), np.moveaxis(M[:, :, k], 0, -1)
    tau = np.empty((len(q), len(spec.joints)))
    for jj, (joint, c) in enumerate(zip(spec.joints, carried, strict=True)):
        # the axis turns with the outer body of a revolute joint, with the inner body of a prismatic one
        on = c.child if joint.revolute else (joint.parent if joint.parent in top.bodies else None)
        if on is None:  # a rail fixed to the ground
            u = joint.axis_W0[:, None]
        else:
            u = np.einsum("ijn,j->in", A_c[..., top.bodies.index(on)], spec.body(on).R_WB0.T @ joint.axis_W0)
        tau[:, jj] = np.einsum("an,an->n", (M if joint.revolute else F)[:, :, k[jj]], u)
    return GraphInverse(tau, F_out, M_out)
