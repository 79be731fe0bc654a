"""A floating base: its motion in the harness's one convention, and each engine's, stated once.

The base is a rigid body joined to the world by six degrees of freedom (MuJoCo's free joint,
Pinocchio's free-flyer, a URDF's `floating` joint). Its frame B is the file's: the MJCF body's frame,
the URDF link's (RobotSpec.floating: (R_WF0, p_WF0) where the file draws it, the pose at which
RobotSpec gives every body and joint); the base's pose (R_WB, p_WB) is that frame's, as a log or a
motion-capture system gives a base link's pose.

The harness's convention (`BaseMotion`), every vector in world axes:
    pose          p_WB (3), quaternion w x y z of R_WB (4)
    velocity      v_W, the base frame's origin's velocity; omega_W, the base's angular velocity
    acceleration  their time derivatives a_W = v_W', alpha_W = omega_W'
    base rows     the wrench the world must exert on the base: force F_W and moment M_W about
                  the base origin (the inverse dynamics' six base rows)

Each engine's (measured with MuJoCo 4.0 and Pinocchio 4.1 to 1e-14: ../DESIGN.md, "Floating bases
and ball joints"; tests/test_floating.py kills a mutant of each):
    MuJoCo's free joint   qpos [p_W, w x y z], qvel [v_W, omega_B], qacc [a_W, alpha_B]
                          (omega_B = R^T omega_W, and alpha_B = R^T alpha_W), qfrc [F_W, M_B]
    Pinocchio free-flyer  q [p_W, x y z w], v [R^T v_W, omega_B], a = v' in base axes:
                          [R^T a_W - omega_B x R^T v_W, alpha_B], rnea's base rows [F_B, M_B]
A mass matrix is compared in the harness's velocities: M_h = T^T M_engine T, T the map from the
harness's base velocity to the engine's (blockdiag(1, R^T) for MuJoCo, blockdiag(R^T, R^T) for
Pinocchio; the identity on the joints).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from harness.model import quaternion
from harness.model.kinematics import cross


@dataclass(frozen=True, eq=False)
class BaseMotion:
    """The base's pose, twist and its derivative at N states, the harness's convention (module
    docstring): each (N, 3) but the quaternion (N, 4, w x y z, unit)."""

    p_W: np.ndarray
    quat_wxyz: np.ndarray
    v_W: np.ndarray
    omega_W: np.ndarray
    a_W: np.ndarray
    alpha_W: np.ndarray

    @property
    def R_WB(self) -> np.ndarray:
        """(N, 3, 3) the base's orientation."""
        return quaternion.to_matrix(self.quat_wxyz)

    def __len__(self) -> int:
        return len(self.p_W)

    def take(self, rows: np.ndarray) -> BaseMotion:
        """The states at `rows` (indices or a mask)."""
        return BaseMotion(*(x[rows] for x in (self.p_W, self.quat_wxyz, self.v_W, self.omega_W, self.a_W,
                                              self.alpha_W)))

    def rows(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The motion as three row arrays, what a recording keeps (harness/base/series.py): the pose
        [p_W, quaternion w x y z] (N, 7), the twist [v_W, omega_W] (N, 6) and its rate [a_W, alpha_W] (N, 6)."""
        return (np.concatenate([self.p_W, self.quat_wxyz], axis=1), np.concatenate([self.v_W, self.omega_W], axis=1),
                np.concatenate([self.a_W, self.alpha_W], axis=1))

    @classmethod
    def from_rows(cls, pose: np.ndarray, twist: np.ndarray, rate: np.ndarray) -> BaseMotion:
        """The motion from `rows`' three arrays."""
        return cls(pose[:, :3], pose[:, 3:7], twist[:, :3], twist[:, 3:], rate[:, :3], rate[:, 3:])


def _in_base(R_WB: np.ndarray, x_W: np.ndarray) -> np.ndarray:
    """(N, 3) world vectors x_W in base axes, R^T x."""
    return np.einsum("nji,nj->ni", R_WB, x_W)


def _in_world(R_WB: np.ndarray, x_B: np.ndarray) -> np.ndarray:
    return np.einsum("nij,nj->ni", R_WB, x_B)


def to_mujoco(base: BaseMotion) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """MuJoCo's free joint's (qpos (N, 7), qvel (N, 6), qacc (N, 6))."""
    R = base.R_WB
    return (np.concatenate([base.p_W, base.quat_wxyz], axis=1),
            np.concatenate([base.v_W, _in_base(R, base.omega_W)], axis=1),
            np.concatenate([base.a_W, _in_base(R, base.alpha_W)], axis=1))


def from_mujoco(qpos: np.ndarray, qvel: np.ndarray, qacc: np.ndarray) -> BaseMotion:
    """The motion from MuJoCo's free joint's qpos (N, 7), qvel (N, 6) and qacc (N, 6): `to_mujoco`'s inverse."""
    quat = qpos[:, 3:7] / np.linalg.norm(qpos[:, 3:7], axis=1, keepdims=True)
    R = quaternion.to_matrix(quat)
    return BaseMotion(qpos[:, :3], quat, qvel[:, :3], _in_world(R, qvel[:, 3:]), qacc[:, :3], _in_world(R, qacc[:, 3:]))


def tracking_error(actual: BaseMotion, wanted: BaseMotion) -> tuple[np.ndarray, np.ndarray]:
    """(N,) m and (N,) rad: how far the base's origin is from where it is wanted, and the angle of the
    rotation between the two orientations, 2 atan2(|v|, |w|) of the quaternion q_wanted^-1 q (on SO(3):
    the same for q and -q: `quaternion.angle`)."""
    w1, v1 = wanted.quat_wxyz[:, 0], wanted.quat_wxyz[:, 1:]
    w2, v2 = actual.quat_wxyz[:, 0], actual.quat_wxyz[:, 1:]
    w = w1 * w2 + np.sum(v1 * v2, axis=1)  # the relative quaternion's scalar and vector parts
    v = w1[:, None] * v2 - w2[:, None] * v1 - np.cross(v1, v2)
    return np.linalg.norm(actual.p_W - wanted.p_W, axis=1), quaternion.angle(np.concatenate([w[:, None], v], axis=1))


def to_pinocchio(base: BaseMotion) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pinocchio's free-flyer's (q (N, 7), v (N, 6), a (N, 6))."""
    R = base.R_WB
    v_B, omega_B = _in_base(R, base.v_W), _in_base(R, base.omega_W)
    a_B = _in_base(R, base.a_W) - cross(omega_B, v_B)
    return (np.concatenate([base.p_W, base.quat_wxyz[:, [1, 2, 3, 0]]], axis=1),
            np.concatenate([v_B, omega_B], axis=1),
            np.concatenate([a_B, _in_base(R, base.alpha_W)], axis=1))


def base_rows_from_mujoco(base: BaseMotion, qfrc_base: np.ndarray) -> np.ndarray:
    """(N, 6) [F_W, M_W] from MuJoCo's free joint's generalised force [F_W, M_B]."""
    return np.concatenate([qfrc_base[:, :3], _in_world(base.R_WB, qfrc_base[:, 3:])], axis=1)


def base_rows_from_pinocchio(base: BaseMotion, tau_base: np.ndarray) -> np.ndarray:
    """(N, 6) [F_W, M_W] from Pinocchio's free-flyer rows of rnea, [F_B, M_B]."""
    R = base.R_WB
    return np.concatenate([_in_world(R, tau_base[:, :3]), _in_world(R, tau_base[:, 3:])], axis=1)


def velocity_map(base: BaseMotion, engine: str, n_joints: int) -> np.ndarray:
    """(N, 6 + n, 6 + n) T: the engine's velocity from the harness's, v_engine = T v_harness."""
    R_T = np.swapaxes(base.R_WB, 1, 2)
    T = np.broadcast_to(np.eye(6 + n_joints), (len(base), 6 + n_joints, 6 + n_joints)).copy()
    T[:, 3:6, 3:6] = R_T
    if engine == "pinocchio":
        T[:, :3, :3] = R_T
    elif engine != "mujoco":
        raise ValueError(f"no engine {engine!r}")
    return T


def random_base_motion(count: int, seed: int, reach: float = 1.0, speed: float = 1.0,
                       acceleration: float = 5.0) -> BaseMotion:
    """`count` random base states: positions uniform within +-reach (m), orientations uniform on SO(3)
    (normalised Gaussian quaternions, w >= 0), every twist and acceleration component within
    +-speed and +-acceleration (SI)."""
    rng = np.random.default_rng(seed)
    quat = rng.normal(size=(count, 4))
    quat /= np.linalg.norm(quat, axis=1, keepdims=True)
    quat *= np.where(quat[:, :1] < 0, -1.0, 1.0)

    def uniform(size: float) -> np.ndarray:
        return rng.uniform(-size, size, (count, 3))

    return BaseMotion(uniform(reach), quat, uniform(speed), uniform(speed), uniform(acceleration),
                      uniform(acceleration))


def not_free(robot, done: str) -> str | None:
    """Why the floating base of `robot` (a RobotSpec) cannot be `done` ("moved by the bench", "read from a
    log"), None where it can: a robot without a floating base, or with loops (an open tree of joints, driven
    directly or through [drives], is judged with its base free)."""
    if robot.floating is None:
        return (f"model {robot.name!r} has no floating base (an MJCF free joint, a URDF floating joint or "
                "[urdf] floating = true)")
    if robot.loops:
        return (f"model {robot.name!r} has loops: a floating base is {done} only on an open tree of joints")
    return None

