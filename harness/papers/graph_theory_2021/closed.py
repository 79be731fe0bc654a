"""A closed chain by the graph-theory method: the tree's Newton-Euler equations with the incidence
matrices (Eqs. 17-23, harness/papers/graph_theory_2021/inverse.py), the loops' forces as further
unknowns.

A loop (harness/model/loops.py) joins a point of body a to one of body b (a weld also their frames):
it acts on a with a force lambda_f at its joined point (and, for a weld, a moment lambda_m) and on b
with the opposite, which enter Newton's and Euler's equations of the two bodies beside gravity and
inertia. The tree's back substitution is linear in them, so every joint's force element and moment is

    F_k = F_k^0 + sum_c T^F_kc lambda_c,    M_k = M_k^0 + sum_c T^M_kc lambda_c,

F^0, M^0 the tree's own (no loop force) and T the tree's answer to a unit loop force component c
with no motion and no gravity. Each joint's drive is its moment (revolute) or force (prismatic)
along its axis, tau_j = tau_j^0 + sum_c t_jc lambda_c. A passive joint has no drive, tau_p = 0: n_p
equations for the loops' 3 (connect) or 6 (weld) components each, solved by least squares (least norm
where a planar loop leaves its out-of-plane force to no equation); the actuated joints' drives follow.
These are the first seed's Lagrange multipliers of the loops, from its incidence matrices rather than
from a constraint Jacobian, and independent of harness/model/closure.py's projection.

A joint coupling (q_f = r q_l + o: a mimic joint, a joint equality) acts inside its two joints: a
torque (or force) lambda on the follower's child about its axis, -r lambda on the leader's (the
coupling's power lambda (q'_f - r q'_l) is zero), so that the follower's drive is tau_f^0 - lambda and the
leader's tau_l^0 + r lambda; the joints' force elements and moments, which carry whatever drives the
joint, are unchanged.

Joint friction and rotor inertia (harness/model/friction.py) act between a joint's bodies and its
drive: a joint's drive gives tau_j + f_j, f_j its law at (q'_j, q''_j) and at the tree's rigid-body
torque tau_j^0 where the law reads the load. A passive joint has no drive, so its equation is
tau_p + f_p = 0: its friction enters the loops' forces, and the actuated joints' drives carry
tau_a + f_a.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from harness.model import friction
from harness.model.kinematics import KinematicsBuffers, cross
from harness.model.loops import coupling_row
from harness.model.spec import WORLD, RobotSpec
from harness.papers.graph_theory_2021.dynamics import GraphModel
from harness.papers.graph_theory_2021.inverse import joint_drives, motion_terms, newton_euler


@dataclass(frozen=True, eq=False)
class ClosedChainInverse:
    tau: np.ndarray  # (N, joints of the spec): the actuated joints' drives, zero on the passive ones
    lam: np.ndarray  # (N, loop rows): each loop's force on body a (world), then a weld's moment; a coupling's
    # torque on its follower
    F_W: np.ndarray  # (N, joints, 3) force element of each joint (inner on outer), loops' forces included
    M_W: np.ndarray  # (N, joints, 3) its moment about the joint point


def closed_chain_inverse(spec: RobotSpec, model: GraphModel, q: np.ndarray, qd: np.ndarray,
                         qdd: np.ndarray) -> ClosedChainInverse:
    """From every joint's (q, q', q'') (N, n, spec order) of a closed chain's consistent motion; the
    spec's joint friction and rotor inertia included (module docstring)."""
    q, qd, qdd = (np.atleast_2d(np.asarray(x, dtype=float)) for x in (q, qd, qdd))
    N = len(q)
    top = model.topology
    args, buffers = motion_terms(spec, model, q, qd, qdd, KinematicsBuffers.of(spec, N))
    A, a, w, wd, c_out, c_in = args
    axes = buffers.axes.copy()
    kin_bodies = [b.name for b in spec.bodies]
    R_WB = {name: buffers.R_WB[:, :, kin_bodies.index(name)].copy() for name in top.bodies}

    def drives(F, M):
        return joint_drives(spec, top, F, M, lambda jj, on: axes[:, jj])

    tau0, F0, M0 = drives(*newton_euler(model, A, a, w, wd, c_out, c_in))
    # the tree's answer to each unit loop force component, with no motion and no gravity
    still = np.broadcast_to(model.g_W[:, None, None], a.shape)
    zero = np.zeros_like(w)
    columns = []
    n = len(spec.joints)
    for loop in spec.loops:
        if not loop.joins_points:  # a coupling's torque lambda on its follower, -r lambda on its leader
            t_c = np.repeat(-coupling_row(spec, loop)[:, None], N, axis=1)  # the drives give the rest
            columns.append((t_c, np.zeros((3, n, N)), np.zeros((3, n, N))))
            continue
        ends = [(loop.body_a, loop.point_a_W0, 1.0), (loop.body_b, loop.point_b_W0, -1.0)]
        for kind in ("force", "moment") if loop.kind == "weld" else ("force",):
            for c in range(3):
                f_ext, m_ext = np.zeros_like(a), np.zeros_like(a)
                for body, point_W0, sign in ends:
                    if body == WORLD:
                        continue
                    i = top.bodies.index(body)
                    unit = np.zeros((3, N))
                    unit[c] = sign
                    if kind == "force":
                        arm_B = spec.body(body).arm_B(point_W0)
                        arm_W = np.einsum("abn,b->an", R_WB[body], arm_B)  # joined point less centre of mass
                        f_ext[:, i] += unit
                        m_ext[:, i] += cross(arm_W, unit, axis=0)
                    else:
                        m_ext[:, i] += unit
                columns.append(drives(*newton_euler(model, A, still, zero, zero, c_out, c_in, f_ext, m_ext)))
    t = np.stack([col[0] for col in columns], axis=-1)  # (n, N, rows)
    act = [spec.joint_names.index(j) for j in spec.actuated]
    passive = [k for k in range(len(spec.joints)) if k not in act]
    T_p = t[passive].transpose(1, 0, 2)  # (N, n_p, rows)
    f = friction.torque(spec.frictions, qd, qdd, tau0.T, q).T  # (n, N): each joint's law, zero where it has none
    lam = -(np.linalg.pinv(T_p, rcond=1e-9) @ (tau0[passive] + f[passive]).T[:, :, None])[:, :, 0]  # (N, rows)
    tau = tau0 + f + np.einsum("jnr,nr->jn", t, lam)
    tau[passive] = 0.0  # what the least squares leaves there is round-off (tests)
    F = F0 + np.einsum("ajnr,nr->ajn", np.stack([col[1] for col in columns], axis=-1), lam)
    M = M0 + np.einsum("ajnr,nr->ajn", np.stack([col[2] for col in columns], axis=-1), lam)
    return ClosedChainInverse(tau.T, lam, F.transpose(2, 1, 0), M.transpose(2, 1, 0))
