"""The joint-torque regressor of a Pinocchio model for all samples at once: tau = Y(q, q', q'') pi,
pi the ten dynamic parameters of every joint's body in Pinocchio's order and frame
([m, m c, I_xx, I_xy, I_yy, I_xz, I_yz, I_zz], inertia about the joint frame's origin), Y the
matrix Pinocchio's computeJointTorqueRegressor gives sample by sample (checked against it to
round-off in tests/test_regressor.py). Pinocchio's call costs about 7 us a sample from Python; here
every step is an operation on (N,) arrays, a few times faster on long logs.

Featherstone's recursion in each joint's frame, spatial vectors [linear; angular] about the frame's
origin. Joint j's placement in its parent, liMi = (R, t) = M_j exp(S_j q_j), moves a motion from
the parent's frame into j's: w_j = R^T w_p, v_j = R^T (v_p + w_p x t). Velocities and spatial
accelerations go down the tree, gravity as the base's acceleration (-g, 0):

    v_j = X v_p + S_j q',    a_j = X a_p + S_j q'' + v_j x (S_j q')

Body j's wrench about its origin is linear in its parameters, f_j = I_j a_j + v_j x* I_j v_j, and
joint i's torque is sum over the bodies j it carries of s_ij . f_j, s_ij = X_{j<-i} S_i its motion
axis in j's frame. With beta = a_lin + w x v_lin (the origin's acceleration), h = m c and I the
inertia about the origin, the coefficients of s = (s_l, s_w) . f_j are

    m:  s_l . beta
    h:  w x (w x s_l) - a_w x s_l + beta x s_w
    I:  sym(s_w, a_w) + sym(s_w x w, w),   sym(y, x) = [y0 x0, y0 x1 + y1 x0, y1 x1, y0 x2 + y2 x0,
                                                        y1 x2 + y2 x1, y2 x2]

(y^T I x for the symmetric I). Revolute and prismatic joints about any axis, as
harness/engines/pinocchio.py builds them; `supports` says whether a model has only those.
"""

from __future__ import annotations

import numpy as np

from harness.model.kinematics import axis_rotation, cross, rotate

_REVOLUTE = {"JointModelRX": (1, 0, 0), "JointModelRY": (0, 1, 0), "JointModelRZ": (0, 0, 1)}
_PRISMATIC = {"JointModelPX": (1, 0, 0), "JointModelPY": (0, 1, 0), "JointModelPZ": (0, 0, 1)}


def _joint_axis(joint) -> tuple[bool, np.ndarray] | None:
    """(revolute, unit axis in the joint's frame), or None for a joint this module does not read."""
    name = joint.shortname()
    if name in _REVOLUTE:
        return True, np.array(_REVOLUTE[name], dtype=float)
    if name in _PRISMATIC:
        return False, np.array(_PRISMATIC[name], dtype=float)
    if name in ("JointModelRevoluteUnaligned", "JointModelPrismaticUnaligned"):
        axis = np.asarray(joint.extract().axis, dtype=float)
        return name == "JointModelRevoluteUnaligned", axis / np.linalg.norm(axis)
    return None


def supports(model) -> bool:
    """Whether every joint of the Pinocchio model is one degree of freedom this module reads."""
    return all(_joint_axis(model.joints[j]) is not None for j in range(1, model.njoints))


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _sym(y: np.ndarray, x: np.ndarray) -> list[np.ndarray]:
    return [y[0] * x[0], y[0] * x[1] + y[1] * x[0], y[1] * x[1], y[0] * x[2] + y[2] * x[0],
            y[1] * x[2] + y[2] * x[1], y[2] * x[2]]


def joint_torque_regressor(model, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray,
                           out: np.ndarray | None = None) -> np.ndarray:
    """(nv, 10 (njoints - 1), N) for q, q', q'' of shape (N, nq) in Pinocchio's order (nq = nv: one
    coordinate per joint): out[:, :, k] is sample k's computeJointTorqueRegressor. Samples last, so
    that each coefficient is written, and each joint's rows read, as one contiguous run. `out`: a
    zeroed array of that shape to write into; the entries written are the same every call, the
    others stay zero."""
    n = model.njoints - 1
    N = q.shape[0]
    if out is None:
        out = np.zeros((model.nv, 10 * n, N))
    q_c, qd_c, qdd_c = (np.ascontiguousarray(x.T) for x in (q, qd, qdd))  # (nq, N): each joint's row contiguous
    parents = [model.parents[j] for j in range(n + 1)]
    R, t, axis, revolute, idx = {}, {}, {}, {}, {}
    v_l, v_w, a_l, a_w = {}, {}, {}, {}
    zero = np.zeros((3, N))
    v_l[0], v_w[0] = zero, zero
    a_l[0], a_w[0] = np.broadcast_to(-np.asarray(model.gravity.linear, dtype=float)[:, None], (3, N)), zero
    for j in range(1, n + 1):
        rev, u = _joint_axis(model.joints[j])
        k = model.joints[j].idx_v
        revolute[j], axis[j], idx[j] = rev, u, k
        M = model.jointPlacements[j]
        x, xd, xdd = q_c[k], qd_c[k], qdd_c[k]
        if rev:  # R = R_M exp(u q)
            R[j] = np.einsum("ab,bcn->acn", M.rotation, axis_rotation(u, x, samples_last=True))
            t[j] = np.broadcast_to(M.translation[:, None], (3, N))
        else:
            R[j] = np.broadcast_to(M.rotation[:, :, None], (3, 3, N))
            t[j] = M.translation[:, None] + (M.rotation @ u)[:, None] * x
        p = parents[j]
        R_T = np.swapaxes(R[j], 0, 1)
        # into j's frame: w_j = R^T w_p, v_j = R^T (v_p + w_p x t)
        w_in = rotate(R_T, v_w[p])
        v_in = rotate(R_T, v_l[p] + cross(v_w[p], t[j], axis=0))
        al_in = rotate(R_T, a_l[p] + cross(a_w[p], t[j], axis=0))
        aw_in = rotate(R_T, a_w[p])
        S_qd = u[:, None] * xd
        if rev:
            v_w[j], v_l[j] = w_in + S_qd, v_in
            a_w[j] = aw_in + u[:, None] * xdd + cross(v_w[j], S_qd, axis=0)
            a_l[j] = al_in + cross(v_l[j], S_qd, axis=0)
        else:
            v_w[j], v_l[j] = w_in, v_in + S_qd
            a_w[j] = aw_in
            a_l[j] = al_in + u[:, None] * xdd + cross(v_w[j], S_qd, axis=0)
    # per body: its origin's (classical) acceleration
    beta = {j: a_l[j] + cross(v_w[j], v_l[j], axis=0) for j in range(1, n + 1)}
    children: dict[int, list[int]] = {j: [] for j in range(n + 1)}
    for j in range(1, n + 1):
        children[parents[j]].append(j)
    for i in range(1, n + 1):
        # joint i's axis carried down its subtree: s_c = X_{c<-p} s_p
        u, none = axis[i][:, None], np.zeros((3, 1))
        s = {i: (none, u) if revolute[i] else (u, none)}  # S_i = [0; u] or [u; 0], (linear, angular)
        stack = [i]
        row = out[idx[i]]
        while stack:
            j = stack.pop()
            s_l, s_w = s[j]
            w, aw, b = v_w[j], a_w[j], beta[j]
            cols = row[10 * (j - 1): 10 * j]
            cols[0] = _dot(s_l, b)
            cols[1:4] = cross(w, cross(w, s_l, axis=0), axis=0) - cross(aw, s_l, axis=0) + cross(b, s_w, axis=0)
            sw_x_w = cross(s_w, w, axis=0)
            for c, (y1, y2) in enumerate(zip(_sym(s_w, aw), _sym(sw_x_w, w), strict=True)):
                np.add(y1, y2, out=cols[4 + c])
            for c in children[j]:
                R_T = np.swapaxes(R[c], 0, 1)
                s[c] = rotate(R_T, s_l + cross(s_w, t[c], axis=0)), rotate(R_T, s_w)
                stack.append(c)
    return out
