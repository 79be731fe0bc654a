"""A user's own dynamic model of the two-link arm: closed-form Lagrange equations written by hand,
tau = M(q) q'' + C(q, q') q' + g(q), with its own parameter values. The harness judges it against
MuJoCo and Pinocchio.

Angles turn about +y, so a link at angle q points along (cos q, 0, -sin q): the textbook planar
2R arm with height z = -(x-z plane's y'). Link i: mass m_i, length l_i, centre of mass r_i from its
joint, moment of inertia I_i about its centre of mass and the y axis.
"""

import numpy as np

PARAMETERS = {"m1": 2.0, "m2": 1.2, "l1": 0.5, "r1": 0.25, "r2": 0.2, "I1": 0.04206667, "I2": 0.01615}


class TwoLinkArm:
    joint_names = ("shoulder", "elbow")  # the order of my columns

    def __init__(self, gravity_W, **overrides):
        self.p = {**PARAMETERS, **overrides}
        self.g = -float(gravity_W[2])  # gravity along -z

    def mass_matrix(self, q):
        p, c2 = self.p, np.cos(q[:, 1])
        M11 = p["I1"] + p["I2"] + p["m1"] * p["r1"] ** 2 + p["m2"] * (p["l1"] ** 2 + p["r2"] ** 2
                                                                       + 2 * p["l1"] * p["r2"] * c2)
        M12 = p["I2"] + p["m2"] * (p["r2"] ** 2 + p["l1"] * p["r2"] * c2)
        M22 = np.full_like(c2, p["I2"] + p["m2"] * p["r2"] ** 2)
        return np.stack([np.stack([M11, M12], -1), np.stack([M12, M22], -1)], -2)

    def inverse_dynamics(self, q, qd, qdd):
        p, g = self.p, self.g
        s2 = np.sin(q[:, 1])
        c1, c12 = np.cos(q[:, 0]), np.cos(q[:, 0] + q[:, 1])
        h = p["m2"] * p["l1"] * p["r2"] * s2
        coriolis = np.stack([-h * (2 * qd[:, 0] * qd[:, 1] + qd[:, 1] ** 2), h * qd[:, 0] ** 2], -1)
        gravity = -g * np.stack([(p["m1"] * p["r1"] + p["m2"] * p["l1"]) * c1 + p["m2"] * p["r2"] * c12,
                                 p["m2"] * p["r2"] * c12], -1)
        return np.einsum("nij,nj->ni", self.mass_matrix(q), qdd) + coriolis + gravity


def make(robot, gravity_W, parameters):
    """Called by the harness with the robot description (unused here: this model has its own
    numbers), the scenario's gravity and the scenario's extra keys (parameter overrides)."""
    return TwoLinkArm(gravity_W, **parameters)
