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
        shape = a.shape[1:] if a.shape == b.shape else np.broadcast_shapes(a.shape[1:], b.shape[1:])
        out = np.empty((3,) + shape, dtype=np.result_type(a, b))
        term = np.empty(shape, dtype=out.dtype)  # the subtracted product, one buffer for the three
        for k, (i, j) in enumerate(((1, 2), (2, 0), (0, 1))):
            np.multiply(a[i], b[j], out=out[k, ...])  # [k, ...]: a view even of a 0-d component
            np.multiply(a[j], b[i], out=term)
            out[k, ...] -= term
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


def _unit_skew(axis: np.ndarray) -> tuple[float, np.ndarray]:
    """|axis| and the cross-product matrix K of the unit axis (of axis itself when it is zero): a
    rotation by t |axis| about it is 1 + sin K + (1 - cos) K^2 (Rodrigues)."""
    axis = np.asarray(axis, dtype=float)
    norm = float(np.linalg.norm(axis))
    return norm, skew(axis / norm if norm > 0 else axis)


def axis_rotation(axis: np.ndarray, angle: np.ndarray, samples_last: bool = False) -> np.ndarray:
    """(N, 3, 3) rotations by angle (N,) |axis| about axis (3,) (a rotation vector s axis, as
    scipy's Rotation.from_rotvec reads it): Rodrigues' formula R = 1 + sin(t) K + (1 - cos(t)) K^2,
    K the cross-product matrix of the unit axis. Written here: scipy.spatial costs 0.25 to 0.6 s
    to import, more than a whole kr500 run's kinematics. `samples_last`: (3, 3, N) instead, each
    entry's samples contiguous (the batched regressor's layout, harness/model/regressor.py)."""
    norm, K = _unit_skew(axis)
    angle = np.asarray(angle, dtype=float) * norm
    if samples_last:
        return np.eye(3)[:, :, None] + np.sin(angle) * K[:, :, None] + (1.0 - np.cos(angle)) * (K @ K)[:, :, None]
    return np.eye(3) + np.sin(angle)[:, None, None] * K + (1.0 - np.cos(angle))[:, None, None] * (K @ K)


def _times_constant(R: np.ndarray, C: np.ndarray) -> np.ndarray:
    """R C for R (3, 3, N) component-major and a constant C (3, 3): row i of R C is C^T R[i], one
    matrix product over the stack of rows."""
    return np.matmul(C.T, R)


def _turned(R: np.ndarray, v: np.ndarray) -> np.ndarray:
    """R v for R (3, 3, N) component-major and a constant vector v (3,): (3, N), v^T R[i] per row."""
    return np.matmul(v, R)


def _point_acceleration(a_c, wd, w, r):
    """a_c + w' x r + w x (w x r), component-major (3, ...)."""
    return a_c + cross(wd, r, axis=0) + cross(w, cross(w, r, axis=0), axis=0)


def forward_kinematics(spec: RobotSpec, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray,
                       velocities: bool = True) -> TreeKinematics:
    """(q, q', q'') of shape (N, n_joints) in spec joint order -> TreeKinematics (`velocities` False:
    the centres of mass' velocities left out, NaN: Newton-Euler does not read them).

    Computed component-major, every quantity a (3, N) or (3, 3, N) array written into one array per
    kind, (n_bodies, 3, N) or (n_bodies, 3, 3, N), of which TreeKinematics holds (N, n, ...) views.
    A revolute joint's rotation by Rodrigues' formula folded into the product with the parent's,
    R_B = R_P + sin(q) R_P K + (1 - cos(q)) R_P K^2 (K the axis' cross-product matrix, constant),
    and t_B = O_J - R_B p_J0."""
    q, qd, qdd = (np.atleast_2d(np.asarray(x, dtype=float)) for x in (q, qd, qdd))
    N = q.shape[0]
    bodies = [b.name for b in spec.bodies]
    nb, nj = len(bodies), len(spec.joints)
    # body by body, each body's (3, N) or (3, 3, N) block contiguous (strided over the bodies, the
    # kinematics of 2048 Panda states ran about twice as long)
    R_c, R_WB_c = np.empty((nb, 3, 3, N)), np.empty((nb, 3, 3, N))
    c_c, a_c, w_c, wd_c = (np.empty((nb, 3, N)) for _ in range(4))
    v_c = np.empty((nb, 3, N)) if velocities else np.full((nb, 3, N), np.nan)
    t_c, axes_c, points_c = np.empty((nb, 3, N)), np.empty((nj, 3, N)), np.empty((nj, 3, N))
    identity, zero = np.eye(3)[:, :, None], np.zeros((3, 1))
    # per body, views into the arrays above: displacement (R, t), centre of mass c, v, a, omega, omega'
    state = {WORLD: (identity, zero, zero, zero, zero, zero, zero)}
    for k, joint in enumerate(spec.joints):
        R_P, t_P, c_P, v_P, a_P, w_P, wd_P = state[joint.parent]
        body = spec.body(joint.child)
        i = bodies.index(body.name)
        u = _turned(R_P, joint.axis_W0)
        O_J = _turned(R_P, joint.p_W0) + t_P
        s, sd, sdd = q[:, k], qd[:, k], qdd[:, k]
        R_B, t_B, c_B = R_c[i], t_c[i], c_c[i]
        a_O = _point_acceleration(a_P, wd_P, w_P, O_J - c_P)  # the parent's point at O_J
        if joint.revolute:
            norm, K = _unit_skew(joint.axis_W0)  # R_J by Rodrigues, as axis_rotation, folded into R_P R_J
            angle = s * norm
            R_B[...] = (R_P + _times_constant(R_P, K) * np.sin(angle)
                        + _times_constant(R_P, K @ K) * (1.0 - np.cos(angle)))
            r = _turned(R_B, body.p_W_com0 - joint.p_W0)  # c_B - O_J
            t_B[...] = O_J - _turned(R_B, joint.p_W0)
            c_B[...] = O_J + r
            w_c[i] = w_P + u * sd
            wd_c[i] = wd_P + u * sdd + cross(w_P, u, axis=0) * sd
            if velocities:
                v_c[i] = v_P + cross(w_P, O_J - c_P, axis=0) + cross(w_c[i], r, axis=0)
            a_c[i] = _point_acceleration(a_O, wd_c[i], w_c[i], r)
        else:
            R_B[...] = R_P
            t_B[...] = u * s + t_P
            c_B[...] = _turned(R_B, body.p_W_com0) + t_B
            w_c[i], wd_c[i] = w_P, wd_P
            d = c_B - O_J
            if velocities:
                v_c[i] = v_P + cross(w_P, c_B - c_P, axis=0) + u * sd
            a_c[i] = (_point_acceleration(a_O, wd_P, w_P, d) + u * sdd + 2.0 * cross(w_P, u, axis=0) * sd)
        R_WB_c[i] = _times_constant(R_B, body.R_WB0)
        state[body.name] = (R_B, t_B, c_B, v_c[i], a_c[i], w_c[i], wd_c[i])
        axes_c[k], points_c[k] = u, O_J
    for name in bodies:  # a body no joint moves (none in a spec: every body has its joint)
        if name not in state:
            raise ValueError(f"body {name!r} has no inner joint")
    vec = lambda x: x.transpose(2, 0, 1)  # noqa: E731  (n, 3, N) -> (N, n, 3), a view
    return TreeKinematics(tuple(bodies), R_WB_c.transpose(3, 0, 1, 2), vec(c_c), vec(v_c), vec(a_c),
                          vec(w_c), vec(wd_c), vec(axes_c), vec(points_c))
