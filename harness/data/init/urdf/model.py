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
    def __init__(self, path, gravity_W, drives=None, free_joint=None, springs=None):
        self.pin = _pinocchio()
        self.model, self.data, self.joint_names = robot_model(path, gravity_W)
        self.drives = drives  # your model file's drives (Drives, below), or None
        self.path, self.gravity_W, self.free_joint = path, gravity_W, free_joint  # a floating base's joint
        # an MJCF joint's spring, k (q - springref), which Pinocchio's parser does not read (spring_terms, below)
        self.stiffness, self.spring_rest = spring_terms(springs, self.joint_names)

    def inverse_dynamics(self, q, qd, qdd):
        tau = np.array([self.pin.rnea(self.model, self.data, a, b, c)
                        for a, b, c in zip(configuration(self.model, q), qd, qdd, strict=True)])
        if self.drives is not None:
            return tau + self.drives.torque(qd, qdd, tau, q)
        # the URDF's <dynamics damping friction>, an MJCF joint's damping, frictionloss and spring
        return (tau + self.model.damping * qd + self.model.friction * np.sign(qd)
                + self.stiffness * q - self.spring_rest)

    def mass_matrix(self, q):
        out = []
        for a in configuration(self.model, q):
            M = self.pin.crba(self.model, self.data, a)
            out.append(np.triu(M) + np.triu(M, 1).T)  # CRBA fills the upper triangle
        return np.array(out) + (0.0 if self.drives is None else self.drives.mass)


    def floating_inverse_dynamics(self, base, q, qd, qdd):
        """A robot with a floating base, its base free (floating.toml, where the bench moves it): the world's
        wrench on the base [F_W, M_W] about its frame's origin (N, 6), then the joints' torques (N, n), rigid
        bodies (the harness adds the drives' friction and rotor inertia); `base` a
        harness.model.floating.BaseMotion (the base's pose, twist and their rates, world axes). Here,
        Pinocchio's own parse of the robot file with its free-flyer."""
        from harness.engines.pinocchio_file import free_inverse_dynamics

        rows, tau = free_inverse_dynamics(self.path, self.free_joint, self.joint_names, self.gravity_W, base,
                                          q, qd, qdd)
        return np.concatenate([rows, tau], axis=1)


def make_model(robot, gravity_W, parameters):
    return RobotModel(Path(__file__).parent / parameters.get("robot_file", ROBOT_FILE), gravity_W, Drives.of(robot),
                      None if robot.floating is None else robot.floating.joint, springs(robot))


