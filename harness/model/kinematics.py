"""Forward kinematics of a tree, for all samples at once: each body's orientation, centre-of-mass
position, velocity and acceleration, and angular velocity and acceleration, from (q, q', q'').

The spec gives every body and joint in world coordinates at the initial pose (q = 0). A body's
displacement from that pose is its parent's followed by its inner joint's, both written in
initial-pose world coordinates: x = R_B x0 + t_B with R_B = R_P R_J and
t_B = R_P (p_J0 - R_J p_J0 + s u_J0) + t_P (R_J = I, s = q for a prismatic joint; R_J the
rotation by q about u_J0, s = 0 for a revolute one). Velocities and accelerations are the usual
rigid-body recursions in world components:

    revolute:  w_B = w_P + u q',   w'_B = w'_P + u q'' + w_P x u q',
               a_Bc = a_P(O_J) + w'_B x r + w_B x (w_B x r),   r = c_B - O_J
    prismatic: w_B = w_P,          w'_B = w'_P,
               a_Bc = a_P(c_B) + u q'' + 2 w_P x u q'

with a_P(x) = a_Pc + w'_P x (x - c_P) + w_P x (w_P x (x - c_P)) the acceleration of the point of P
at x, and u = R_P u_J0 the joint axis now.

Written here rather than taken from Pinocchio's forwardKinematics, which works one state at a time
from Python: every step here is an operation on (N,) arrays, in the spec's own world-at-q = 0
frames that the graph model uses. Checked against Pinocchio state by state on five trees
(tests/test_kinematics.py).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from harness.model.spec import WORLD, RobotSpec


@dataclass(frozen=True, eq=False)
class TreeKinematics:
    """Every body of the spec (spec order), each array (N, n_bodies, ...), world components."""

    bodies: tuple[str, ...]
    R_WB: np.ndarray  # (N, n, 3, 3) body frame e(i) in world
    p_W_com: np.ndarray  # centre of mass O_ci
    v_W_com: np.ndarray
    a_W_com: np.ndarray
    omega_W: np.ndarray
    omegadot_W: np.ndarray
    axis_W: np.ndarray  # (N, n_joints, 3) each joint's axis now (spec joint order)
    p_W_joint: np.ndarray  # (N, n_joints, 3) each joint's point now, fixed in its inner body

    def body_index(self, name: str) -> int:
        return self.bodies.index(name)


def cross(a: np.ndarray, b: np.ndarray, axis: int = -1) -> np.ndarray:
    """a x b along `axis`: -1 for (..., 3) arrays, 0 for component-major (3, ...) ones; the rest
    broadcast. The same operations, so the same bits, as np.cross, at a third of its per-call cost
    (np.cross moves axes), which dominates on one state at a time (the forward simulation evaluates
    16,000 of them); component-major, each component is written in place into one array (three
    times faster on 10,000 states than stacking them)."""
    a, b = np.asarray(a), np.asarray(b)
    if axis == 0:
        out = np.empty((3,) + np.broadcast_shapes(a.shape[1:], b.shape[1:]), dtype=np.result_type(a, b))
        for k, (i, j) in enumerate(((1, 2), (2, 0), (0, 1))):
            np.multiply(a[i], b[j], out=out[k, ...])  # [k, ...]: a view even of a 0-d component
            out[k, ...] -= a[j] * b[i]
        return out
    if axis != -1:
        raise ValueError(f"axis must be 0 or -1, got {axis}")
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    c0 = a1 * b2
    c0 -= a2 * b1
    c1 = a2 * b0
    c1 -= a0 * b2
    c2 = a0 * b1
    c2 -= a1 * b0
    out = np.empty(c0.shape + (3,), dtype=c0.dtype)
    out[..., 0], out[..., 1], out[..., 2] = c0, c1, c2
    return out


def rotate(A_c: np.ndarray, v: np.ndarray) -> np.ndarray:
    """A v in component-major form (the batched Newton-Euler and regressor): A_c (3, 3, ...) and
    v (3, ...) -> (3, ...). A v with every sample's own vector: einsum (1.4 times faster than the
    three products summed, on 10,000 samples of seven bodies); a vector fixed in the body, broadcast
    over the samples (v of fewer dimensions): the three products summed (three times faster than
    einsum's broadcasting), the same bits."""
    if v.ndim == A_c.ndim - 1:
        return np.einsum("ij...,j...->i...", A_c, v)
    out = np.empty((3,) + np.broadcast_shapes(A_c.shape[2:], v.shape[1:]))
    for i in range(3):
        np.multiply(A_c[i, 0], v[0], out=out[i])
        out[i] += A_c[i, 1] * v[1]
        out[i] += A_c[i, 2] * v[2]
    return out


def skew(v: np.ndarray) -> np.ndarray:
    """The cross-product matrix a~, a~ b = a x b, (..., 3) -> (..., 3, 3)."""
    v = np.asarray(v)
    out = np.zeros(v.shape + (3,), dtype=v.dtype)
    x, y, z = v[..., 0], v[..., 1], v[..., 2]
    out[..., 0, 1], out[..., 0, 2] = -z, y
    out[..., 1, 0], out[..., 1, 2] = z, -x
    out[..., 2, 0], out[..., 2, 1] = -y, x
    return out


def axis_rotation(axis: np.ndarray, angle: np.ndarray, samples_last: bool = False) -> np.ndarray:
    """(N, 3, 3) rotations by angle (N,) |axis| about axis (3,) (a rotation vector s axis, as
    scipy's Rotation.from_rotvec reads it): Rodrigues' formula R = 1 + sin(t) K + (1 - cos(t)) K^2,
    K the cross-product matrix of the unit axis. Written here: scipy.spatial costs 0.25 to 0.6 s
    to import, more than a whole kr500 run's kinematics. `samples_last`: (3, 3, N) instead, each
    entry's samples contiguous (the batched regressor's layout, harness/model/regressor.py)."""
    axis = np.asarray(axis, dtype=float)
    norm = np.linalg.norm(axis)
    angle = np.asarray(angle, dtype=float) * norm
    K = skew(axis / norm if norm > 0 else axis)
    if samples_last:
        return np.eye(3)[:, :, None] + np.sin(angle) * K[:, :, None] + (1.0 - np.cos(angle)) * (K @ K)[:, :, None]
    return np.eye(3) + np.sin(angle)[:, None, None] * K + (1.0 - np.cos(angle))[:, None, None] * (K @ K)


def _point_acceleration(a_c, wd, w, r):
    return a_c + cross(wd, r) + cross(w, cross(w, r))


def forward_kinematics(spec: RobotSpec, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> TreeKinematics:
    """(q, q', q'') of shape (N, n_joints) in spec joint order -> TreeKinematics."""
    q, qd, qdd = (np.atleast_2d(np.asarray(x, dtype=float)) for x in (q, qd, qdd))
    N = q.shape[0]
    zero3, eye = np.zeros((N, 3)), np.broadcast_to(np.eye(3), (N, 3, 3))
    # per body: displacement (R, t), centre of mass c, v, a, omega, omega'
    state = {WORLD: (eye, zero3, zero3, zero3, zero3, zero3, zero3)}
    axes, points = np.empty((N, len(spec.joints), 3)), np.empty((N, len(spec.joints), 3))
    for k, joint in enumerate(spec.joints):
        R_P, t_P, c_P, v_P, a_P, w_P, wd_P = state[joint.parent]
        body = spec.body(joint.child)
        u = R_P @ joint.axis_W0
        O_J = R_P @ joint.p_W0 + t_P
        s, sd, sdd = q[:, k], qd[:, k], qdd[:, k]
        if joint.revolute:
            R_J = axis_rotation(joint.axis_W0, s)
            R_B = R_P @ R_J
            t_B = (R_P @ (joint.p_W0 - R_J @ joint.p_W0)[..., None])[..., 0] + t_P
            c_B = R_B @ body.p_W_com0 + t_B
            w_B = w_P + u * sd[:, None]
            wd_B = wd_P + u * sdd[:, None] + cross(w_P, u) * sd[:, None]
            r = c_B - O_J
            v_B = v_P + cross(w_P, O_J - c_P) + cross(w_B, r)
            a_B = _point_acceleration(_point_acceleration(a_P, wd_P, w_P, O_J - c_P), wd_B, w_B, r)
        else:
            R_B = R_P
            t_B = (R_P @ joint.axis_W0) * s[:, None] + t_P
            c_B = R_B @ body.p_W_com0 + t_B
            w_B, wd_B = w_P, wd_P
            v_B = v_P + cross(w_P, c_B - c_P) + u * sd[:, None]
            a_B = (_point_acceleration(a_P, wd_P, w_P, c_B - c_P) + u * sdd[:, None]
                   + 2.0 * cross(w_P, u) * sd[:, None])
        state[body.name] = (R_B, t_B, c_B, v_B, a_B, w_B, wd_B)
        axes[:, k], points[:, k] = u, O_J
    names = tuple(b.name for b in spec.bodies)
    stack = lambda i: np.stack([state[b][i] for b in names], axis=1)  # noqa: E731
    R_WB = np.stack([state[b][0] @ spec.body(b).R_WB0 for b in names], axis=1)
    return TreeKinematics(names, R_WB, stack(2), stack(3), stack(4), stack(5), stack(6), axes, points)
