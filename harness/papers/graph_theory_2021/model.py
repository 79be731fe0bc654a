"""The graph-theory model as a model under test (harness/base/plugins.py, ModelUnderTest): joint
torques and joint wrenches from (q, q', q'') by the paper's Newton-Euler equations (Eqs. 17-23)
solved with the incidence matrix (harness/papers/graph_theory_2021/inverse.py), the body motion
from the tree's forward kinematics; of a closed chain, with the loops' forces as further unknowns
(closed.py), answering for its actuated joints."""

from __future__ import annotations

import numpy as np

from harness.model import friction
from harness.model.spec import RobotSpec
from harness.papers.graph_theory_2021.closed import closed_chain_inverse
from harness.papers.graph_theory_2021.dynamics import build_graph_model
from harness.papers.graph_theory_2021.inverse import GraphInverse, inverse_dynamics_of_motion

STANDARD_GRAVITY_W = np.array([0.0, 0.0, -9.80665])


class GraphTheoryModel:
    """m_i and the principal J_i of every body come from the robot description it is built from."""

    def __init__(self, spec: RobotSpec, gravity_W: np.ndarray):
        self.spec = spec
        self.graph = build_graph_model(spec, gravity_W)
        self.joint_names = list(spec.joint_names)
        if spec.loops:  # a closed chain: its actuated joints' drives (closed.py)
            self.actuated_joints = list(spec.actuated)

    def solve(self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> GraphInverse:
        if self.spec.loops:
            out = closed_chain_inverse(self.spec, self.graph, q, qd, qdd)
            return GraphInverse(out.tau, out.F_W, out.M_W)
        return inverse_dynamics_of_motion(self.spec, self.graph, q, qd, qdd)

    def inverse_dynamics(self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
        """The drive torques: the joint wrenches' components along the axes, plus the drives' own
        rotor inertia and friction (harness/model/friction.py); of a closed chain, the actuated
        joints' (harness/papers/graph_theory_2021/closed.py: every joint's law in its equations)."""
        tau = self.solve(q, qd, qdd).tau
        if self.spec.loops:
            return tau[:, [self.joint_names.index(a) for a in self.actuated_joints]]
        return tau + friction.torque(self.spec.frictions, qd, qdd, tau, q)

    def joint_wrenches(self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        out = self.solve(q, qd, qdd)
        return out.F_W, out.M_W

    def floating_inverse_dynamics(self, base, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
        """With the robot's floating base free (harness/model/floating.py, BaseMotion `base`): the base's six
        rows [F_W, M_W] (the world's wrench on it about its frame's origin) and the joints' torques, (N,
        6 + n), rigid bodies (harness/papers/graph_theory_2021/floating.py: the base a six-degree-of-freedom
        joint to the ground)."""
        from harness.papers.graph_theory_2021.floating import floating_inverse_dynamics

        rows, tau = floating_inverse_dynamics(self.spec, self.graph, base, q, qd, qdd)
        return np.concatenate([rows, tau], axis=1)

    def mass_matrix(self, q: np.ndarray) -> np.ndarray:
        """M(q) column by column from the same equations: with no velocity, M e_k is the torque of a
        unit acceleration of joint k less that of none (gravity cancels)."""
        q = np.atleast_2d(q)
        zero = np.zeros_like(q)
        at_rest = self.inverse_dynamics(q, zero, zero)
        eye = np.eye(q.shape[1])
        cols = [self.inverse_dynamics(q, zero, np.broadcast_to(eye[k], q.shape)) - at_rest for k in range(q.shape[1])]
        return np.stack(cols, axis=-1)


def make(robot: RobotSpec, gravity_W: np.ndarray = STANDARD_GRAVITY_W) -> GraphTheoryModel:
    return GraphTheoryModel(robot, np.asarray(gravity_W, dtype=float))
