"""Your code, judged by the harness: a dynamic model and an identification method.

Both are plugins, named in scenario.toml (`python = "my_robot:make_model"`). The harness calls
each factory with the robot description (a harness.model.spec.RobotSpec), the scenario's gravity
`gravity_W` (world components, m/s^2) and `parameters` (the extra keys of the scenario's table).

The model under test below is a placeholder: Pinocchio's RNEA and CRBA on your robot file (URDF or
MJCF, ROBOT_FILE; with the drives your model file states, as the harness reads them), which agree with
the references by construction.
Replace RobotModel with your own model, and LeastSquares with your method (or keep it: it is generic).
"""

from pathlib import Path

import numpy as np

ROBOT_FILE = "robot.urdf"  # your robot: a URDF or an MJCF file (Pinocchio reads either, told by its root)

# ------------------------------------------------------------------------------------------------
# The model under test: an object with `joint_names` and `inverse_dynamics(q, qd, qdd) -> tau`,
# arrays (N, n) in SI units, columns in the order of `joint_names`; optionally `mass_matrix(q)`,
# (N, n, n). Here, until you put yours in its place: Pinocchio on the robot file, sample by sample
# (`robot_model` and `configuration`, with the method below, read the file and turn joint angles into
# Pinocchio's configuration). Pinocchio's RNEA and CRBA include an MJCF joint's armature.


class RobotModel:
    def __init__(self, path, gravity_W, drives=None):
        self.pin = _pinocchio()
        self.model, self.data, self.joint_names = robot_model(path, gravity_W)
        self.drives = drives  # your model file's drives (Drives, below), or None

    def inverse_dynamics(self, q, qd, qdd):
        tau = np.array([self.pin.rnea(self.model, self.data, a, b, c)
                        for a, b, c in zip(configuration(self.model, q), qd, qdd, strict=True)])
        if self.drives is not None:
            return tau + self.drives.torque(qd, qdd, tau)
        # the URDF's <dynamics damping friction>, an MJCF joint's damping and frictionloss
        return tau + self.model.damping * qd + self.model.friction * np.sign(qd)

    def mass_matrix(self, q):
        out = []
        for a in configuration(self.model, q):
            M = self.pin.crba(self.model, self.data, a)
            out.append(np.triu(M) + np.triu(M, 1).T)  # CRBA fills the upper triangle
        return np.array(out) + (0.0 if self.drives is None else self.drives.mass)


def make_model(robot, gravity_W, parameters):
    return RobotModel(Path(__file__).parent / parameters.get("robot_file", ROBOT_FILE), gravity_W, Drives.of(robot))


