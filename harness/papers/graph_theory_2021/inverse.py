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

from harness.cardano import A_0i
from harness.kinematics import forward_kinematics
from harness.papers.graph_theory_2021.dynamics import GraphModel
from harness.papers.graph_theory_2021.topology import joint_arms
from harness.recording import Recording
from harness.spec import RobotSpec


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
    return newton_euler(spec, model, q, A_0i(rec.theta[:, b]), rec.a_W[:, b], rec.omega_W[:, b],
                        rec.omegadot_W[:, b])


def inverse_dynamics_of_motion(spec: RobotSpec, model: GraphModel, q: np.ndarray, qd: np.ndarray,
                               qdd: np.ndarray) -> GraphInverse:
    """From joint coordinates alone (spec joint order, (N, n)): the body motion by forward
    kinematics of the tree (harness/kinematics.py), then Newton-Euler as on a recording."""
    kin = forward_kinematics(spec, q, qd, qdd)
    top = model.topology
    b = [kin.body_index(x) for x in top.bodies]
    cols = [spec.joint_names.index(j) for j in top.joints]
    return newton_euler(spec, model, np.atleast_2d(q)[:, cols], kin.R_WB[:, b], kin.a_W_com[:, b],
                        kin.omega_W[:, b], kin.omegadot_W[:, b])


def newton_euler(spec: RobotSpec, model: GraphModel, q: np.ndarray, A: np.ndarray, a: np.ndarray,
                 w: np.ndarray, wd: np.ndarray) -> GraphInverse:
    """Eqs. 22-23 solved for the force elements and joint moments, all samples at once. Inputs in
    the graph's order: q (N, joints), A = A(0i) (N, n, 3, 3), and world components of r_i'',
    omega_i, omega_i' (N, n, 3)."""
    top = model.topology
    J_W = A @ (model.J[..., :, None] * np.swapaxes(A, -1, -2))  # A diag(J) A^T
    S_inv = np.linalg.inv(top.S_e.astype(float))
    F = -(S_inv @ (model.m[:, None] * (a - model.g_W)))  # matmul broadcasts over samples
    c_out, c_in = joint_arms(top, A, q)
    P_out, P_in = (top.S == -1).astype(float), (top.S == 1).astype(float)
    # sum_k C_e,ik x F_k, joint by joint: C = -c on the outer body, +c on the inner one
    C_x_F = P_in @ np.cross(c_in, F) - P_out @ np.cross(c_out, F)
    euler = (J_W @ wd[..., None])[..., 0] + np.cross(w, (J_W @ w[..., None])[..., 0])
    M = -(np.linalg.inv(top.S.astype(float)) @ (euler + C_x_F))

    N = len(q)
    tau = np.empty((N, len(spec.joints)))
    F_out, M_out = np.empty((N, len(spec.joints), 3)), np.empty((N, len(spec.joints), 3))
    index = {name: k for k, name in enumerate(top.joints)}
    for jj, joint in enumerate(spec.joints):
        carried = spec.carried_joint(joint.name)  # a carriage's joint: the wrench of the joint it carries
        k = index[carried.name]
        F_out[:, jj], M_out[:, jj] = F[:, k], M[:, k]
        j = top.bodies.index(carried.child)
        if joint.revolute:
            u = A[:, j] @ (spec.body(carried.child).R_WB0.T @ joint.axis_W0)
            tau[:, jj] = np.einsum("na,na->n", M[:, k], u)
        else:
            inner = joint.parent if joint.parent in top.bodies else None
            if inner is None:
                u = np.broadcast_to(joint.axis_W0, (N, 3))
            else:
                i = top.bodies.index(inner)
                u = A[:, i] @ (spec.body(inner).R_WB0.T @ joint.axis_W0)
            tau[:, jj] = np.einsum("na,na->n", F[:, k], u)
    return GraphInverse(tau, F_out, M_out)
