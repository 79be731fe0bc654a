"""Your code, judged by the harness: a dynamic model and an identification method.

Both are plugins, named in scenario.toml (`python = "my_robot:make_model"`). The harness calls
each factory with the robot description (a harness.spec.RobotSpec), the scenario's gravity
`gravity_W` (world components, m/s^2) and `parameters` (the extra keys of the scenario's table).

This file starts as a working example for robot.urdf, a two-link arm swinging about y: replace
TwoLinkArm with your model, and LeastSquares with your method (or keep it: it is generic).
"""

from pathlib import Path

import numpy as np

# ------------------------------------------------------------------------------------------------
# The model under test: an object with `joint_names` and `inverse_dynamics(q, qd, qdd) -> tau`,
# arrays (N, n) in SI units, columns in the order of `joint_names`; optionally `mass_matrix(q)`,
# (N, n, n). Here: the closed-form Lagrange equations tau = M(q) q'' + C(q, q') q' + g(q).


class TwoLinkArm:
    joint_names = ("shoulder", "elbow")

    def __init__(self, gravity_W, m1=2.0, m2=1.2, l1=0.5, r1=0.25, r2=0.2, I1=0.04206667, I2=0.01615):
        self.g = -float(gravity_W[2])
        self.m1, self.m2, self.l1, self.r1, self.r2, self.I1, self.I2 = m1, m2, l1, r1, r2, I1, I2

    def mass_matrix(self, q):
        c2 = np.cos(q[:, 1])
        M22 = np.full_like(c2, self.I2 + self.m2 * self.r2**2)
        M12 = M22 + self.m2 * self.l1 * self.r2 * c2
        M11 = (self.I1 + self.m1 * self.r1**2 + self.I2
               + self.m2 * (self.l1**2 + self.r2**2 + 2 * self.l1 * self.r2 * c2))
        return np.stack([np.stack([M11, M12], -1), np.stack([M12, M22], -1)], -2)

    def inverse_dynamics(self, q, qd, qdd):
        h = self.m2 * self.l1 * self.r2 * np.sin(q[:, 1])
        coriolis = np.stack([-h * (2 * qd[:, 0] * qd[:, 1] + qd[:, 1] ** 2), h * qd[:, 0] ** 2], -1)
        c1, c12 = np.cos(q[:, 0]), np.cos(q[:, 0] + q[:, 1])
        gravity = -self.g * np.stack([(self.m1 * self.r1 + self.m2 * self.l1) * c1 + self.m2 * self.r2 * c12,
                                      self.m2 * self.r2 * c12], -1)
        return np.einsum("nij,nj->ni", self.mass_matrix(q), qdd) + coriolis + gravity


def make_model(robot, gravity_W, parameters):
    return TwoLinkArm(gravity_W, **parameters)


# ------------------------------------------------------------------------------------------------
# The identification method: an object with `joint_names` and `fit(q, qd, qdd, tau)` returning the
# identified model (a model as above). Where the identified model has `parameters`, (n, 10): per
# joint the child body's [m, m c, I_xx, I_xy, I_yy, I_xz, I_yz, I_zz] about the joint point in
# world axes at q = 0, the harness compares its base parameters with the robot's; with
# `covariance` (10 n, 10 n) of those parameters, it also reports intervals and their coverage.
# Here: ordinary least squares on Pinocchio's joint-torque regressor of the URDF, any robot whose
# joints have one coordinate each.


class LeastSquares:
    def __init__(self, urdf, gravity_W):
        import pinocchio as pin

        self.pin = pin
        self.model = pin.buildModelFromUrdf(str(urdf))
        if self.model.nq != self.model.nv:
            raise ValueError("this example handles joints of one coordinate each (revolute, prismatic)")
        self.model.gravity.linear = np.asarray(gravity_W, dtype=float)
        self.data = self.model.createData()
        self.joint_names = list(self.model.names)[1:]
        # theta_W = A theta_J: each body's parameters from its joint frame to world axes at q = 0
        pin.forwardKinematics(self.model, self.data, pin.neutral(self.model))
        n = self.model.njoints - 1
        self.A = np.zeros((10 * n, 10 * n))
        for j in range(n):
            R = self.data.oMi[j + 1].rotation
            for k in range(10):
                self.A[10 * j: 10 * j + 10, 10 * j + k] = _rotate_parameters(R, np.eye(10)[k])

    def regressor(self, q, qd, qdd):
        return np.concatenate([self.pin.computeJointTorqueRegressor(self.model, self.data, a, b, c)
                               for a, b, c in zip(q, qd, qdd, strict=True)])

    def fit(self, q, qd, qdd, tau):
        W, y = self.regressor(q, qd, qdd), tau.reshape(-1)
        theta_J, *_ = np.linalg.lstsq(W, y, rcond=None)  # the minimum-norm solution: exact on the base parameters
        dof = max(len(y) - np.linalg.matrix_rank(W), 1)
        cov_J = np.sum((y - W @ theta_J) ** 2) / dof * np.linalg.pinv(W.T @ W)
        return Fitted(self, theta_J, self.A @ theta_J, self.A @ cov_J @ self.A.T)


class Fitted:
    def __init__(self, method, theta_J, theta_W, cov_W):
        self.method, self.theta_J = method, theta_J
        self.joint_names = method.joint_names
        self.parameters = theta_W.reshape(-1, 10)
        self.covariance = cov_W

    def inverse_dynamics(self, q, qd, qdd):
        return (self.method.regressor(q, qd, qdd) @ self.theta_J).reshape(q.shape)


def _rotate_parameters(R, theta):
    """[m, h, I about the origin] of a frame turned by R: m, R h, R I R^T."""
    xx, xy, yy, xz, yz, zz = theta[4:]
    I = R @ np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]]) @ R.T
    return np.concatenate([[theta[0]], R @ theta[1:4], [I[0, 0], I[0, 1], I[1, 1], I[0, 2], I[1, 2], I[2, 2]]])


def make_method(robot, gravity_W, parameters):
    return LeastSquares(Path(__file__).parent / parameters.get("urdf", "robot.urdf"), gravity_W)
