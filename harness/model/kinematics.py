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

import weakref
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
    over the samples (v of fewer dimensions, or of length 1 along them): the three products summed
    (three times faster than einsum's broadcasting), the same bits."""
    if v.shape == A_c.shape[1:]:
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


def joint_axes_W(spec: RobotSpec, bodies, R_WB: np.ndarray, q: np.ndarray) -> np.ndarray:
    """(N, n, 3) every joint's axis in the world now, u = R_P u_J0, from the orientations R_WB (N, len(bodies),
    3, 3) of the bodies named (every massive body at least) and the joint coordinates q (N, n), spec joint
    order. A body's displacement from the initial pose is R_WB R_WB0^T; a massless carriage, which nothing
    records, has its parent's followed by its inner joint's, R_P R_J (the module docstring), so a chain of
    hinges through carriages (a ball joint read as three hinges) turns its middle axes with the hinges
    before them."""
    index = {b: k for k, b in enumerate(bodies)}
    N = len(q)
    turned: dict[str, np.ndarray] = {WORLD: np.broadcast_to(np.eye(3), (N, 3, 3))}

    def displacement(body: str) -> np.ndarray:
        if body not in turned:
            if body in index:
                turned[body] = R_WB[:, index[body]] @ spec.body(body).R_WB0.T
            else:  # a massless carriage: its parent's displacement and its own joint's
                joint = spec.inner_joint(body)
                R_P = displacement(joint.parent)
                k = spec.joint_names.index(joint.name)
                turned[body] = R_P @ axis_rotation(joint.axis_W0, q[:, k]) if joint.revolute else R_P
        return turned[body]

    return np.stack([displacement(j.parent) @ j.axis_W0 for j in spec.joints], axis=1)


def _times_constant(R: np.ndarray, C_T: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """R C for R (3, 3, N) component-major and a constant C given as its transpose C_T: row i of R C
    is C^T R[i], one matrix product over the stack of rows."""
    return np.matmul(C_T, R, out=out)


def _turned(R: np.ndarray, v: np.ndarray) -> np.ndarray:
    """R v for R (3, 3, N) component-major and a constant vector v (3,): (3, N), v^T R[i] per row."""
    return np.matmul(v, R)


def point_acceleration(a_c, wd, w, r):
    """a_c + w' x r + w x (w x r), component-major (3, ...)."""
    out = cross(w, cross(w, r, axis=0), axis=0)
    out += cross(wd, r, axis=0)
    out += a_c
    return out


@dataclass(frozen=True, eq=False)
class _Step:
    """One joint of the recursion and the constants it reads (initial-pose world components)."""

    parent: int  # body index of the inner body, -1 for the world
    child: int  # body index of the outer body
    revolute: bool
    u0: np.ndarray  # (3,) axis
    p0: np.ndarray  # (3,) joint point
    K_T: np.ndarray  # (3, 3) transposed cross-product matrix of the unit axis (revolute)
    KK_T: np.ndarray  # (3, 3) the same of K^2
    norm: float  # |axis|: a revolute joint turns by q |axis|
    r0: np.ndarray  # (3,) joint point to centre of mass (revolute), the centre of mass (prismatic)
    R_WB0_T: np.ndarray  # (3, 3) the outer body's initial orientation, transposed


_STEPS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _steps(spec: RobotSpec) -> tuple[_Step, ...]:
    """The recursion's constants of a spec, computed once per spec (a spec is immutable)."""
    steps = _STEPS.get(spec)
    if steps is None:
        bodies = [b.name for b in spec.bodies]
        steps = []
        for joint in spec.joints:
            body = spec.body(joint.child)
            norm, K = _unit_skew(joint.axis_W0)
            steps.append(_Step(bodies.index(joint.parent) if joint.parent != WORLD else -1,
                               bodies.index(joint.child), joint.revolute, joint.axis_W0, joint.p_W0, K.T,
                               (K @ K).T, norm,
                               body.p_W_com0 - joint.p_W0 if joint.revolute else body.p_W_com0, body.R_WB0.T))
        reached = {s.child for s in steps}
        for i, name in enumerate(bodies):  # a body no joint moves (none in a spec: every body has its joint)
            if i not in reached:
                raise ValueError(f"body {name!r} has no inner joint")
        steps = _STEPS[spec] = tuple(steps)
    return steps


@dataclass(frozen=True, eq=False)
class KinematicsBuffers:
    """The arrays forward_kinematics writes for N states, to be written again by the next N states
    (what a TreeKinematics read from them shows changes then): blocks of states evaluated one after
    another reuse them instead of allocating and freeing megabytes each time, which the C library
    returns to the system and takes back, page by page (the Panda's kinematics in blocks of 2048
    states took 1.75 times as long)."""

    N: int
    R: np.ndarray  # (n_bodies, 3, 3, N) each body's displacement R_B, a contiguous block per body
    t: np.ndarray  # (n_bodies, 3, N) and t_B
    R_WB: np.ndarray  # (3, 3, n_bodies, N)
    c: np.ndarray  # (3, n_bodies, N) centre of mass
    a: np.ndarray
    w: np.ndarray
    wd: np.ndarray
    axes: np.ndarray  # (3, n_joints, N)
    points: np.ndarray

    @classmethod
    def of(cls, spec: RobotSpec, N: int) -> KinematicsBuffers:
        nb, nj = len(spec.bodies), len(spec.joints)
        return cls(N, np.empty((nb, 3, 3, N)), np.empty((nb, 3, N)), np.empty((3, 3, nb, N)),
                   *(np.empty((3, nb, N)) for _ in range(4)), np.empty((3, nj, N)), np.empty((3, nj, N)))


def forward_kinematics(spec: RobotSpec, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray,
                       velocities: bool = True, buffers: KinematicsBuffers | None = None,
                       accelerations: bool = True) -> TreeKinematics:
    """(q, q', q'') of shape (N, n_joints) in spec joint order -> TreeKinematics (`velocities` False:
    the centres of mass' velocities left out, NaN: Newton-Euler does not read them; `accelerations`
    False: the bodies' accelerations and angular accelerations left out, NaN, for positions alone).

    Computed component-major with the samples last, every quantity a (3, N) or (3, 3, N) array
    written into one array per kind, (3, n_bodies, N) or (3, 3, n_bodies, N) (those of `buffers`
    where they are given), of which TreeKinematics holds (N, n, ...) views. A revolute
    joint's rotation by Rodrigues' formula folded into the product with the parent's,
    R_B = R_P + sin(q) R_P K + (1 - cos(q)) R_P K^2 (K the axis' cross-product matrix, constant),
    and t_B = O_J - R_B p_J0."""
    q, qd, qdd = (np.ascontiguousarray(np.atleast_2d(np.asarray(x, dtype=float)).T) for x in (q, qd, qdd))
    N = q.shape[1]
    steps = _steps(spec)
    nb = len(spec.bodies)
    if buffers is None or buffers.N != N:
        buffers = KinematicsBuffers.of(spec, N)
    R, t, R_WB, c, a, w, wd, axes, points = (buffers.R, buffers.t, buffers.R_WB, buffers.c, buffers.a, buffers.w,
                                             buffers.wd, buffers.axes, buffers.points)
    v = np.empty((3, nb, N)) if velocities else np.broadcast_to(np.nan, (3, nb, N))
    for k, st in enumerate(steps):
        i, P = st.child, st.parent
        s, sd, sdd = q[k], qd[k], qdd[k]
        R_B, t_B = R[i], t[i]
        if P < 0:  # on the world: at rest, its frame the initial pose's
            R_P, u, O_J = np.broadcast_to(np.eye(3)[:, :, None], (3, 3, N)), st.u0[:, None], st.p0[:, None]
            w_P = wd_P = c_P = v_P = None
            a_O = np.zeros((3, 1))
        else:
            R_P, w_P, wd_P, c_P, v_P = R[P], w[:, P], wd[:, P], c[:, P], v[:, P]
            u = _turned(R_P, st.u0)
            O_J = _turned(R_P, st.p0)
            O_J += t[P]
            a_O = point_acceleration(a[:, P], wd_P, w_P, O_J - c_P) if accelerations else None  # parent's, at O_J
        w_B, wd_B = w[:, i], wd[:, i]
        if st.revolute:
            angle = s * st.norm
            _times_constant(R_P, st.K_T, out=R_B)
            R_B *= np.sin(angle)
            turn = _times_constant(R_P, st.KK_T)
            turn *= 1.0 - np.cos(angle)
            R_B += turn
            R_B += R_P
            r = _turned(R_B, st.r0)  # c_B - O_J
            np.subtract(O_J, _turned(R_B, st.p0), out=t_B)
            np.add(O_J, r, out=c[:, i])
            np.multiply(u, sd, out=w_B)
            if P >= 0:
                w_B += w_P
            if velocities:
                v[:, i] = cross(w_B, r, axis=0) + (0.0 if P < 0 else v_P + cross(w_P, O_J - c_P, axis=0))
            if accelerations:
                np.multiply(u, sdd, out=wd_B)
                if P >= 0:
                    wd_B += wd_P
                    wd_B += cross(w_P, u, axis=0) * sd
                a[:, i] = point_acceleration(a_O, wd_B, w_B, r)
        else:
            R_B[...] = R_P
            np.multiply(u, s, out=t_B)
            if P >= 0:
                t_B += t[P]
            np.add(_turned(R_B, st.r0), t_B, out=c[:, i])
            if P < 0:
                w_B[...], wd_B[...] = 0.0, 0.0
                if velocities:
                    v[:, i] = u * sd
                if accelerations:
                    a[:, i] = u * sdd
            else:
                w_B[...], wd_B[...] = w_P, wd_P
                if velocities:
                    v[:, i] = v_P + cross(w_P, c[:, i] - c_P, axis=0) + u * sd
                if accelerations:
                    acc = u * sdd
                    acc += 2.0 * cross(w_P, u, axis=0) * sd
                    acc += point_acceleration(a_O, wd_P, w_P, c[:, i] - O_J)
                    a[:, i] = acc
        _times_constant(R_B, st.R_WB0_T, out=R_WB[:, :, i])
        axes[:, k], points[:, k] = u, O_J
    vec = lambda x: x.transpose(2, 1, 0)  # noqa: E731  (3, n, N) -> (N, n, 3), a view
    if not accelerations:
        a = wd = np.broadcast_to(np.nan, (3, nb, N))
    return TreeKinematics(tuple(b.name for b in spec.bodies), R_WB.transpose(3, 2, 0, 1), vec(c), vec(v),
                          vec(a), vec(w), vec(wd), vec(axes), vec(points))
