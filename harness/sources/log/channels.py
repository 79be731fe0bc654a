"""Which joints a log's torque channels measure: `[data] unmeasured` names the joints without one (no
column, or a channel that reads nothing, as a mobile manipulator's wrist channels do; of a closed chain,
actuated joints). Their motion stays in the model: their torque row is left out of every fit and
judgement (harness/stages/log_model.py, as a closed chain's passive joints' are), so the links they
carry are identified from the other joints' rows; their own friction and rotor inertia reach no
measured channel of an open tree and stay the model's (a closed chain's reach the measured actuated
channels through G^T, as a passive joint's do)."""

from __future__ import annotations

import numpy as np

from harness.base.tomlio import Table
from harness.model.spec import RobotSpec
from harness.sources.log.closed import closed_chain_source, logged
from harness.sources.log.schema import DataSource, with_unmeasured_motors

__all__ = ["every_joint", "logged", "supported"]  # logged: the robot as its log is read


def every_joint(source: DataSource, robot: RobotSpec, tau: np.ndarray, names: list[str]
                ) -> tuple[np.ndarray, list[str]]:
    """The torque columns read (the measured joints', in the model's order; of a motor-side log, the
    measured motors', in the motors' order) as one column per joint (motor), an unmeasured one's zero
    (never read: harness/stages/log_model.py); and each column's name."""
    channels = list(robot.transmission.motors) if source.unmeasured_motors else robot.joint_names
    without = source.unmeasured_motors or source.unmeasured
    if not without:
        return tau, names
    measured = [k for k, j in enumerate(channels) if j not in without]
    out = np.zeros((len(tau), len(channels)))
    out[:, measured] = tau
    every = [f"(unmeasured: {j})" for j in channels]
    for k, name in zip(measured, names, strict=True):
        every[k] = name
    return out, every


def supported(root: Table, dt: Table, robot: RobotSpec, source: DataSource) -> DataSource:
    """The `[data]` table `dt` of a scenario `root` on `robot`, read as `source`: what a closed chain's log
    does not support (harness/sources/log/closed.py, and counterbalanced channels) and what reads every
    joint's torque beside `unmeasured` joints refused in one line naming the key; a motor-side log's
    unmeasured motors as the joints they turn (schema.with_unmeasured_motors)."""
    source = with_unmeasured_motors(source, dt, robot.transmission, robot.joint_names)  # a motor-side log's
    if robot.loops:
        source = closed_chain_source(root, dt, robot, source)
        if source.counterbalanced:
            raise dt.error("counterbalanced", f"model {robot.name!r} is a closed chain: its fit reads every "
                                              "actuated channel with gravity (a counterbalanced channel is read "
                                              "without it on an open tree)")
    if not source.unmeasured:
        return source
    for table in ("identification", "refinement"):
        if root.has(table):
            raise root.error(table, "reads every joint's torque, and [data] unmeasured names joints without one")
    return source
