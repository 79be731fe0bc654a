"""A floating base's prescribed motion: a scenario's `[base_motion]` (harness/model/floating.py).

Each of the base's six coordinates is a motion as a joint's is (harness/sources/motion.py, every type,
zero where not given): `x`, `y`, `z` (m) move the base frame's origin from where the file draws it, in
world axes; `roll`, `pitch`, `yaw` (rad) turn the base frame about its own x, then y, then z axis:

    p_WB(t) = p_WF0 + (x, y, z),        R_WB(t) = R_WF0 exp([e_x] roll) exp([e_y] pitch) exp([e_z] yaw)

a product of rotations (never a sum of quaternions; the quaternion is the product's, w >= 0). With
P_i the product of the rotations after the i-th (P_z = 1) and omega_i the angular velocity of that
product in its own axes, the base's angular velocity and acceleration in base axes are exactly

    omega_B = sum_i P_i^T e_i theta_i',    alpha_B = sum_i (P_i^T e_i theta_i'' - omega_i x P_i^T e_i theta_i')

(no singularity: nothing is inverted), and omega_W = R omega_B, alpha_W = R alpha_B.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from harness.base.tomlio import Table
from harness.model import quaternion
from harness.model.floating import BaseMotion, not_free
from harness.model.kinematics import cross
from harness.model.spec import FLOATING_BASE_FIXED, FloatingBase
from harness.sources.motion import Locked, Motion, read_motion

POSITION_AXES = ("x", "y", "z")
ROTATION_AXES = ("roll", "pitch", "yaw")


def _about(axis: int, angle: np.ndarray) -> np.ndarray:
    """(N, 3, 3) rotations by `angle` (N,) about the coordinate axis `axis`: exp([e] angle) = 1 + sin [e]x
    + (1 - cos) [e]x^2 (Rodrigues)."""
    e = np.zeros((3, 3))
    i, j = (axis + 1) % 3, (axis + 2) % 3
    e[j, i], e[i, j] = 1.0, -1.0  # [e_axis]x
    return (np.eye(3) + np.sin(angle)[:, None, None] * e + (1.0 - np.cos(angle))[:, None, None] * (e @ e))


@dataclass(frozen=True, eq=False)
class BaseTrajectory:
    """The six coordinates' motions and the base frame where the file draws it."""

    motions: dict[str, Motion]  # by axis name, POSITION_AXES then ROTATION_AXES
    R_WF0: np.ndarray
    p_WF0: np.ndarray

    def evaluate(self, t: np.ndarray) -> BaseMotion:
        """The base's motion at times t (N,), exactly (the module docstring)."""
        t = np.asarray(t, dtype=float)
        pos = [self.motions[a].evaluate(t) for a in POSITION_AXES]
        p, v, a = (np.stack([c[k] for c in pos], axis=1) for k in range(3))
        angles = [self.motions[a].evaluate(t) for a in ROTATION_AXES]
        rot = [_about(i, th) for i, (th, _, _) in enumerate(angles)]
        after = [np.broadcast_to(np.eye(3), rot[0].shape).copy() for _ in range(3)]  # P_i
        after[1] = rot[2]
        after[0] = rot[1] @ rot[2]
        omega_B, alpha_B = np.zeros((len(t), 3)), np.zeros((len(t), 3))
        omega_after = np.zeros((len(t), 3))  # the angular velocity of P_i in its own axes, from the last axis in
        for i in (2, 1, 0):
            u = np.swapaxes(after[i], 1, 2)[:, :, i]  # P_i^T e_i
            _, rate, acc = angles[i]
            omega_B += u * rate[:, None]
            alpha_B += u * acc[:, None] - cross(omega_after, u * rate[:, None])
            omega_after = omega_B.copy()
        R = self.R_WF0 @ rot[0] @ rot[1] @ rot[2]
        return BaseMotion(self.p_WF0 + p, quaternion.from_matrix(R), v, np.einsum("nij,nj->ni", R, omega_B), a,
                          np.einsum("nij,nj->ni", R, alpha_B))

    def describe(self) -> dict[str, str]:
        return {a: m.describe() for a, m in self.motions.items()}


def read_base_motion(table: Table, floating: FloatingBase) -> BaseTrajectory:
    """`[base_motion]`: a motion table per coordinate given (POSITION_AXES, ROTATION_AXES), the others
    held at zero; a coordinate of another name refused."""
    motions = {a: read_motion(table.table(a)) if table.has(a) else Locked() for a in POSITION_AXES + ROTATION_AXES}
    table.finish()
    return BaseTrajectory(motions, floating.R_WF0, floating.p_WF0)


# the tables of a scenario that read a robot whose base is fixed (a fixed-base regressor, a replay of its
# joints' drive alone): refused beside [base_motion]
FIXED_BASE_TABLES = ("excitation", "identification", "studies", "estimators", "payload")


def refuse_fixed_base_tables(root: Table) -> None:
    """A table of FIXED_BASE_TABLES beside `[base_motion]`: refused, before any is read."""
    for table in FIXED_BASE_TABLES if root.has("base_motion") else ():
        if root.has(table):
            raise root.error(table, "reads a robot whose base is fixed: not beside [base_motion] (the bench "
                                    "moves the base)")


def read_scenario_base_motion(root: Table, robot, models=(), configs=None) -> BaseTrajectory | None:
    """A scenario's `[base_motion]`, None without: the bench moves the base along it
    (harness/engines/free_base.py). Refused for a robot without a floating base, with loops or drives
    (not simulated with the base free), with a model under test that does not answer with the base
    free (no `floating_inverse_dynamics`), and where the joint-torque identification's validation (in
    `configs`) moves the base and this scenario does not, or the other way round."""
    fit = (configs or {}).get("torque_identification")  # its validation must move the base as this one does
    moved = fit is not None and getattr(fit.validation, "base_motion", None) is not None
    if fit is not None and moved != root.has("base_motion"):
        raise root.error("torque_identification", "the scenario and its validation must both move the floating base "
                                                  "([base_motion]) or neither")
    if not root.has("base_motion"):
        if "base_wrench" in root.data.get("measurement", {}).get("noise", {}):
            raise root.error("measurement.noise.base_wrench", "the world's wrench on a floating base is recorded only "
                                                              "where the bench moves it ([base_motion])")
        return None
    why = not_free(robot, "moved")
    if why is not None:
        raise root.error("base_motion", why)
    for m in models:
        if not callable(getattr(m.instance, "floating_inverse_dynamics", None)):
            raise root.error("model_under_test", f"{m.name!r} has no floating_inverse_dynamics(base, q, qd, qdd): "
                                                 "with [base_motion] the recording's torques are the floating "
                                                 "robot's, judged only through it")
    return read_base_motion(root.table("base_motion"), robot.floating)


def model_notes(scenario) -> list[str]:
    """What reading the robot assumed, as a scenario's run says it: a floating base the reading holds
    fixed is moved by the bench where the scenario has a [base_motion], and by the log where its [data]
    has a [data.base]."""
    robot, data = scenario.robot, getattr(scenario, "data", None)
    if getattr(data, "floating", None) is not None:
        moved = "the log moves the floating base ([data.base])"
    elif getattr(scenario, "base_motion", None) is not None:
        moved = "the bench moves the floating base along [base_motion]"
    else:
        return list(robot.notes)
    return [n.removesuffix(FLOATING_BASE_FIXED) + moved if n.endswith(FLOATING_BASE_FIXED) else n
            for n in robot.notes]
