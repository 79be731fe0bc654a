"""Loop closures of a closed chain and their constraint equations Phi(q) = 0.

A closed chain is read as a tree (the spec's bodies and joints: the spanning tree of the first
seed's graph, its incidence matrices' cut) and loops that close it. A loop joins body a to body b
(either may be the world):

    connect: a point of a and a point of b coincide        Phi = x_a - x_b              (3 rows)
    weld:    a frame of a and a frame of b coincide         Phi = [x_a - x_b; phi_ab]    (6 rows)

or couples two joints' coordinates (a URDF <mimic>, an MJCF joint equality of a linear polynomial):

    joint:   q_f = r q_l + o                                Phi = q_f - r q_l - o        (1 row)

whose Jacobian row is e_f - r e_l, the same at every q, and whose acceleration bias is zero.

with x the joined point now and phi_ab the rotation vector of R_a R_b^T (the joined frames now,
world components; zero when they coincide). Each point or frame is given where it is at q = 0 (all
joint coordinates zero) in the world frame, as the spec gives every body, and moves with its body:
x = R_B c_B + t_B with (R_B, t_B) the body's displacement from q = 0 (harness/model/kinematics.py).
At q = 0 the two need not coincide: the loop need only close somewhere.

Differentiating Phi along a motion gives the velocity and acceleration levels the passive joints
are solved from (harness/model/closure.py):

    J(q) q' = 0,     J(q) q'' + b(q, q') = 0,

J = dPhi/dq the constraint Jacobian (rows: the relative velocity of the joined points, then, for a
weld, the relative angular velocity w_a - w_b) and b the same rows' acceleration at q'' = 0 (the
points' centripetal and Coriolis terms). A joint j moves body X's point x with velocity
u_j x (x - O_j) q'_j (revolute, u_j its axis now, O_j its point) or u_j q'_j (prismatic) when X is
in the subtree j carries: the Jacobian is written from the tree's kinematics alone, and checked
against finite differences and MuJoCo's own constraint Jacobian (tests/test_closed_chains.py).
"""

from __future__ import annotations

import numpy as np

from harness.model.kinematics import TreeKinematics, cross, forward_kinematics, point_acceleration
from harness.model.spec import WORLD, Loop, RobotSpec


def carried(spec: RobotSpec, body: str) -> np.ndarray:
    """(n_joints,) 1.0 for each joint whose motion carries `body` (the joints from the world to it)."""
    out = np.zeros(len(spec.joints))
    while body != WORLD:
        joint = spec.inner_joint(body)
        out[spec.joint_names.index(joint.name)] = 1.0
        body = joint.parent
    return out


def _point_now(spec: RobotSpec, kin: TreeKinematics, body: str, point_W0: np.ndarray) -> np.ndarray:
    """(N, 3) where the point of `body` that is at point_W0 at q = 0 is now."""
    if body == WORLD:
        return np.broadcast_to(np.asarray(point_W0, dtype=float), kin.p_W_com.shape[:1] + (3,))
    i = kin.body_index(body)
    arm_B = spec.body(body).arm_B(point_W0)
    return kin.p_W_com[:, i] + kin.R_WB[:, i] @ arm_B


def _frame_now(spec: RobotSpec, kin: TreeKinematics, body: str, R_W_frame0: np.ndarray) -> np.ndarray:
    """(N, 3, 3) the orientation now of a frame fixed in `body`, given at q = 0."""
    if body == WORLD:
        return np.broadcast_to(R_W_frame0, kin.p_W_com.shape[:1] + (3, 3))
    i = kin.body_index(body)
    return kin.R_WB[:, i] @ (spec.body(body).R_WB0.T @ R_W_frame0)


def _rotation_vector(R: np.ndarray) -> np.ndarray:
    """(N, 3) the rotation vector of each rotation in R (N, 3, 3)."""
    from scipy.spatial.transform import Rotation  # only for welds

    return Rotation.from_matrix(R).as_rotvec()


def _at(spec: RobotSpec, q: np.ndarray) -> TreeKinematics:
    """The tree's positions at q (N, n) (its joints' axes and points; velocities zero, accelerations
    left out)."""
    zero = np.zeros_like(q)
    return forward_kinematics(spec, q, zero, zero, velocities=False, accelerations=False)


def residual(spec: RobotSpec, loops: tuple[Loop, ...], q: np.ndarray) -> np.ndarray:
    """Phi(q), (N, rows): each loop's x_a - x_b (m), then for a weld phi_ab (rad), loop by loop."""
    q = np.atleast_2d(q)
    return _residual(spec, loops, _at(spec, q), q)


def residual_and_jacobian(spec: RobotSpec, loops: tuple[Loop, ...], q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(Phi(q), J(q)) from one evaluation of the tree's positions (`residual`, `jacobian`)."""
    q = np.atleast_2d(q)
    kin = _at(spec, q)
    return _residual(spec, loops, kin, q), _jacobian(spec, loops, kin, len(q))


def coupling_row(spec: RobotSpec, loop: Loop) -> np.ndarray:
    """(n_joints,) a coupling's Jacobian row e_f - r e_l."""
    row = np.zeros(len(spec.joints))
    row[spec.joint_names.index(loop.follower)] = 1.0
    row[spec.joint_names.index(loop.leader)] -= loop.ratio
    return row


def _residual(spec: RobotSpec, loops: tuple[Loop, ...], kin: TreeKinematics, q: np.ndarray) -> np.ndarray:
    N = len(q)
    out = []
    for loop in loops:
        if not loop.joins_points:
            out.append((q @ coupling_row(spec, loop) - loop.offset)[:, None])
            continue
        out.append(_point_now(spec, kin, loop.body_a, loop.point_a_W0)
                   - _point_now(spec, kin, loop.body_b, loop.point_b_W0))
        if loop.kind == "weld":
            R_a = _frame_now(spec, kin, loop.body_a, loop.R_W_frame_a0)
            R_b = _frame_now(spec, kin, loop.body_b, loop.R_W_frame_b0)
            out.append(_rotation_vector(R_a @ np.swapaxes(R_b, -1, -2)))
    return np.concatenate(out, axis=1) if out else np.zeros((N, 0))


def _point_columns(spec: RobotSpec, kin: TreeKinematics, body: str, x_W: np.ndarray) -> np.ndarray:
    """(N, 3, n_joints): the velocity of the point of `body` at x_W (N, 3) per unit q'_j."""
    N, n = len(x_W), len(spec.joints)
    if body == WORLD:
        return np.zeros((N, 3, n))
    revolute = np.array([j.revolute for j in spec.joints])
    arm = x_W[:, None, :] - kin.p_W_joint  # (N, n, 3)
    cols = np.where(revolute[None, :, None], cross(kin.axis_W, arm), kin.axis_W)
    return np.swapaxes(cols * carried(spec, body)[None, :, None], 1, 2)


def _angular_columns(spec: RobotSpec, kin: TreeKinematics, body: str) -> np.ndarray:
    """(N, 3, n_joints): the angular velocity of `body` per unit q'_j."""
    N, n = kin.axis_W.shape[:2]
    if body == WORLD:
        return np.zeros((N, 3, n))
    revolute = np.array([j.revolute for j in spec.joints], dtype=float)
    return np.swapaxes(kin.axis_W * (revolute * carried(spec, body))[None, :, None], 1, 2)


def body_jacobian(spec: RobotSpec, body: str, q: np.ndarray, x_W: np.ndarray) -> np.ndarray:
    """(N, 6, n_joints): the velocity of the point of `body` at x_W (N, 3) and the body's angular velocity, per
    unit q'_j, at q (N, n) (the tree's world, where the spec draws it)."""
    kin = _at(spec, np.atleast_2d(q))
    return np.concatenate([_point_columns(spec, kin, body, x_W), _angular_columns(spec, kin, body)], axis=1)


def jacobian(spec: RobotSpec, loops: tuple[Loop, ...], q: np.ndarray) -> np.ndarray:
    """J(q) = dPhi/dq, (N, rows, n_joints) (module docstring): each joined point's velocity at where
    it is; a weld's rotation rows w_a - w_b, the derivative of phi_ab where the frames coincide."""
    q = np.atleast_2d(q)
    return _jacobian(spec, loops, _at(spec, q), len(q))


def _jacobian(spec: RobotSpec, loops: tuple[Loop, ...], kin: TreeKinematics, N: int) -> np.ndarray:
    out = []
    for loop in loops:
        if not loop.joins_points:
            out.append(np.broadcast_to(coupling_row(spec, loop), (N, 1, len(spec.joints))))
            continue
        out.append(_point_columns(spec, kin, loop.body_a, _point_now(spec, kin, loop.body_a, loop.point_a_W0))
                   - _point_columns(spec, kin, loop.body_b, _point_now(spec, kin, loop.body_b, loop.point_b_W0)))
        if loop.kind == "weld":
            out.append(_angular_columns(spec, kin, loop.body_a) - _angular_columns(spec, kin, loop.body_b))
    return np.concatenate(out, axis=1) if out else np.zeros((N, 0, len(spec.joints)))


def _point_acceleration(spec: RobotSpec, kin: TreeKinematics, body: str, x_W: np.ndarray) -> np.ndarray:
    """(N, 3) the acceleration of the point of `body` at x_W: a_c + w' x r + w x (w x r), r = x - c."""
    if body == WORLD:
        return np.zeros_like(x_W)
    i = kin.body_index(body)
    return point_acceleration(kin.a_W_com[:, i].T, kin.omegadot_W[:, i].T, kin.omega_W[:, i].T,
                              (x_W - kin.p_W_com[:, i]).T).T


def bias(spec: RobotSpec, loops: tuple[Loop, ...], q: np.ndarray, qd: np.ndarray) -> np.ndarray:
    """b(q, q') = Phi'' at q'' = 0, (N, rows): the joined points' relative acceleration, then for a
    weld the frames' relative angular acceleration w'_a - w'_b, with every q'' zero."""
    q, qd = np.atleast_2d(q), np.atleast_2d(qd)
    kin = forward_kinematics(spec, q, qd, np.zeros_like(q), velocities=False)
    out = []
    for loop in loops:
        if not loop.joins_points:  # a coupling's row is constant: no bias
            out.append(np.zeros((len(q), 1)))
            continue
        x_a = _point_now(spec, kin, loop.body_a, loop.point_a_W0)
        x_b = _point_now(spec, kin, loop.body_b, loop.point_b_W0)
        out.append(_point_acceleration(spec, kin, loop.body_a, x_a) - _point_acceleration(spec, kin, loop.body_b, x_b))
        if loop.kind == "weld":
            wd = [np.zeros_like(x_a) if b == WORLD else kin.omegadot_W[:, kin.body_index(b)]
                  for b in (loop.body_a, loop.body_b)]
            out.append(wd[0] - wd[1])
    return np.concatenate(out, axis=1) if out else np.zeros((len(q), 0))


def frames_now(spec: RobotSpec, frames: tuple[tuple[str, np.ndarray], ...], q: np.ndarray) -> np.ndarray:
    """(N, k, 3, 3) each frame's orientation at q (N, n), frames (body, its orientation at q = 0 in world), on
    the robot read where the file draws it."""
    kin = _at(spec, np.atleast_2d(q))
    return np.stack([_frame_now(spec, kin, body, R_W0) for body, R_W0 in frames], axis=1)


def joined_points(spec: RobotSpec, loops: tuple[Loop, ...], q: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """Each loop's joined points now, (x_a, x_b), each (N, 3) (a coupling joins none: both at the origin)."""
    q = np.atleast_2d(q)
    kin = _at(spec, q)
    return [(_point_now(spec, kin, lp.body_a, lp.point_a_W0), _point_now(spec, kin, lp.body_b, lp.point_b_W0))
            for lp in loops]
