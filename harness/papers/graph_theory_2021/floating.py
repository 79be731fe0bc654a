"""A floating base in the graph-theory method: the base as one more body B_0 joined to the ground by a
six-degree-of-freedom joint, as the first paper's rail is a one-degree-of-freedom one.

Each body's motion is the tree's (harness/model/kinematics.py, the base at the file's pose) carried by
the base's rigid motion from that pose, T = T_WB T_WF0^-1 (R_T = R_WB R_WF0^T; harness/model/floating.py
for the base's motion): for a point of a body at x (the tree's) with velocity v and acceleration a,

    r = R_T x + p_T,   r'' = a_T + R_T a + 2 omega x R_T v + alpha x R_T x + omega x (omega x R_T x)

(a_T the acceleration of the point of the base at the world's origin), and each body's angular velocity
omega + R_T omega_i, its angular acceleration alpha + R_T omega_i' + omega x R_T omega_i. With these,
Newton's and Euler's equations of the tree's bodies give every joint's force element and moment as for a
fixed base (Eqs. 22-23, harness/papers/graph_theory_2021/inverse.py: the joints from the ground now leave
the base); the base's own equations, with the joints on it pulling back, give the six-degree-of-freedom
joint's force element, the wrench the world exerts on the base about its frame's origin o:

    F_0 = m_0 (r_0'' - g) + sum_k F_k,
    M_0 = J_0 alpha + omega x J_0 omega + (r_0 - o) x m_0 (r_0'' - g) + sum_k (M_k + (O_k - o) x F_k)

over the joints k on the base (O_k their points). Independent of both engines' floating-base algorithms
(tests/test_floating.py compares them).
"""

from __future__ import annotations

import numpy as np

from harness.model.floating import BaseMotion
from harness.model.kinematics import cross, forward_kinematics
from harness.model.spec import WORLD, RobotSpec
from harness.papers.graph_theory_2021.dynamics import GraphModel
from harness.papers.graph_theory_2021.inverse import joint_drives, newton_euler


def _apply(R: np.ndarray, x: np.ndarray) -> np.ndarray:
    """(N, m, 3): R (N, 3, 3) applied to each of x's vectors (N, m, 3)."""
    return np.einsum("nij,nmj->nmi", R, x)


def floating_inverse_dynamics(spec: RobotSpec, model: GraphModel, base: BaseMotion, q: np.ndarray,
                              qd: np.ndarray, qdd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The base rows [F_W, M_W] (N, 6) and the joints' drives (N, n, spec order) at the states."""
    fb = spec.floating
    if fb is None:
        raise ValueError(f"{spec.name}: no floating base")
    if spec.loops:
        raise ValueError(f"{spec.name}: a floating base with loops is not computed")
    kin = forward_kinematics(spec, q, qd, qdd)
    R_T = base.R_WB @ fb.R_WF0.T  # (N, 3, 3) the base's rotation from its pose in the file
    w, al = base.omega_W[:, None, :], base.alpha_W[:, None, :]
    p_T = base.p_W - np.einsum("nij,j->ni", R_T, fb.p_WF0)
    # the acceleration of the base's point at the world's origin
    a_T = base.a_W - cross(base.alpha_W, base.p_W - p_T) - cross(base.omega_W, cross(base.omega_W,
                                                                                        base.p_W - p_T))

    def moved(x, v, a):  # a tree point's (N, m, 3) position and acceleration carried by the base's motion
        x_W = _apply(R_T, x)
        acc = (a_T[:, None, :] + _apply(R_T, a) + 2 * cross(w, _apply(R_T, v)) + cross(al, x_W)
               + cross(w, cross(w, x_W)))
        return x_W + p_T[:, None, :], acc

    top = model.topology
    b = [kin.body_index(x) for x in top.bodies]
    c, a = moved(kin.p_W_com[:, b], kin.v_W_com[:, b], kin.a_W_com[:, b])
    w_i = _apply(R_T, kin.omega_W[:, b])
    omega = w + w_i
    omegadot = al + _apply(R_T, kin.omegadot_W[:, b]) + cross(w, w_i)
    R_WB = R_T[:, None] @ kin.R_WB[:, b]
    cols = [spec.joint_names.index(j) for j in top.joints]
    O = _apply(R_T, kin.p_W_joint[:, cols]) + p_T[:, None, :]
    axes = _apply(R_T, kin.axis_W)
    for k, name in enumerate(top.joints):  # a prismatic joint's point on the outer body slides along its axis
        if not spec.joint(name).revolute:
            O[:, k] += axes[:, cols[k]] * q[:, cols[k], None]
    c_out = O - c
    c_in = np.zeros_like(c_out)
    inner = top.inner >= 0
    c_in[:, inner] = O[:, inner] - c[:, top.inner[inner]]

    def major(x):  # (N, n, 3) -> (3, n, N)
        return np.ascontiguousarray(x.transpose(2, 1, 0))

    F, M = newton_euler(model, R_WB.transpose(2, 3, 1, 0), major(a), major(omega), major(omegadot), major(c_out),
                        major(c_in))
    tau, _, _ = joint_drives(spec, top, F, M, lambda jj, on: axes[:, jj].T)
    # the base: its own Newton-Euler equations, the joints on it pulling back (F_k, M_k the joints' on their
    # outer bodies, about their points)
    body = fb.body
    x0 = body.p_W_com0[None, None, :].repeat(len(q), 0)
    c0, a0 = moved(x0, np.zeros_like(x0), np.zeros_like(x0))
    c0, a0 = c0[:, 0], a0[:, 0]
    m0 = body.mass * (a0 - model.g_W)
    R0 = R_T @ body.R_WB0
    J0 = R0 @ body.I_B @ np.swapaxes(R0, 1, 2)
    Jw = np.einsum("nij,nj->ni", J0, base.omega_W)
    M0 = np.einsum("nij,nj->ni", J0, base.alpha_W) + cross(base.omega_W, Jw) + cross(c0 - base.p_W, m0)
    F0 = m0.copy()
    on_base = [k for k, name in enumerate(top.joints) if top.inner[k] < 0 and _first(spec, name) in fb.joints]
    for k in on_base:
        F_k, M_k = F[:, k].T, M[:, k].T
        F0 += F_k
        M0 += M_k + cross(O[:, k] - base.p_W, F_k)
    return np.concatenate([F0, M0], axis=1), np.ascontiguousarray(tau.T)


def _first(spec: RobotSpec, name: str) -> str:
    """The joint from the world that starts the chain of massless carriages ending at graph joint `name`."""
    joint = spec.joint(name)
    while joint.parent != WORLD:
        joint = spec.inner_joint(joint.parent)
    return joint.name
