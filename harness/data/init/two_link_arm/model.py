"""Your code, judged by the harness: a dynamic model and an identification method.

Both are plugins, named in scenario.toml (`python = "my_robot:make_model"`). The harness calls
each factory with the robot description (a harness.model.spec.RobotSpec), the scenario's gravity
`gravity_W` (world components, m/s^2) and `parameters` (the extra keys of the scenario's table).

This file starts as a working example for robot.urdf, a two-link arm swinging about y: replace
TwoLinkArm with your model, and LeastSquares with your method (or keep it: it is generic).
"""

from pathlib import Path

import numpy as np

ROBOT_FILE = "robot.urdf"  # the robot the identification method below reads (a URDF or an MJCF file)

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


