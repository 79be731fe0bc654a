"""The MuJoCo test bench as a source of data: a scenario's robot moved along its motion and
recorded (the truth every stage is judged against)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Protocol

import numpy as np

from harness.base.series import TimeSeries
from harness.base.tomlio import InputError
from harness.engines.mujoco import Diverged, simulate
from harness.engines.simulation import Simulation
from harness.model.spec import RobotSpec


class Setup(Protocol):
    """What the bench reads of a scenario (a harness.runner.scenario.Scenario is one)."""

    source: Path  # the scenario file, named in an error
    robot: RobotSpec
    gravity_W: np.ndarray  # (3,) m/s^2
    output_steps: int
    output_dt: float  # s
    simulation: Simulation
    prescribed: Callable  # t -> (q, q', q''), each (len(t), n) in the robot's joint order
    base_motion: object  # a floating base's [base_motion] (harness/sources/base_motion.py), or None: held fixed
    contacts: tuple  # the points it stands on (harness/model/contacts.py), or ()


def record(scenario: Setup) -> TimeSeries:
    """The scenario simulated in MuJoCo: `output_steps + 1` rows from t = 0; a floating base with a
    `[base_motion]` moves along it (the world's wrench on it recorded), else it is held where the file
    draws it. A motion that drives the simulation to non-finite values is bad input, named by its joint
    and time."""
    base = scenario.base_motion
    _simulable_drives(scenario)
    try:
        return simulate(scenario.robot, scenario.gravity_W, scenario.prescribed, scenario.output_steps,
                        scenario.output_dt, scenario.simulation, None if base is None else base.evaluate,
                        scenario.contacts)
    except Diverged as exc:
        moved = base is not None and exc.joint == scenario.robot.floating.joint  # the base's free joint
        raise InputError(scenario.source, "base_motion" if moved else f"motion.{exc.joint}",
                         f"drives the simulation to non-finite values at t = {exc.t:.6g} s (MuJoCo: "
                         f"{exc.engine_message.split('. ')[0]}); a motion this fast or this far cannot be "
                         "simulated") from None


def _simulable_drives(scenario: Setup) -> None:
    """Drives the bench can simulate, else bad input naming the motor (harness/model/drives.py, across_branches)."""
    from harness.model.drives import across_branches
    from harness.model.loops import carried

    spec = scenario.robot
    if spec.transmission is None:
        return
    inner = np.stack([carried(spec, j.child) for j in spec.joints], axis=1) > 0  # [j, k]: j carries k's body
    found = across_branches(spec.frictions, spec.transmission, inner)
    if found is not None:
        motor, a, b = found
        raise InputError(scenario.source, "model", f"[drives.{motor}] of model {spec.name!r} turns "
                                                   f"{spec.joint_names[a]!r} and {spec.joint_names[b]!r}, on separate "
                                                   "branches of the tree, with a rotor inertia MuJoCo cannot couple "
                                                   "them by: the bench does not simulate it (a rotor inertia of 0 "
                                                   "there is simulated)")


def write_log(rec: TimeSeries, joints: list[str], path: Path) -> None:
    """A recording written as a lab's joint log would be: a CSV of t, then q{k}, qd{k}, tau{k} for
    k = 1..n in the order of `joints` (what `[data] columns = { q = "q{j}", ... }` reads), every number
    to the last bit. A floating base's recording adds what its state estimator and foot sensors would log,
    as published (harness/sources/log/floating.py reads it): the base's position `px py pz`, its quaternion
    in ROS's order `qx qy qz qw`, its twist in base axes `vx vy vz wx wy wz`, and each contact's force on its
    body, world axes, `<contact>_fx <contact>_fy <contact>_fz`, then, for a contact whose moment is not zero
    throughout (a sole's), its moment about its point `<contact>_mx <contact>_my <contact>_mz`."""
    from harness.base.csvtext import csv_text

    cols = {"t": rec.t}
    for k, j in enumerate(joints):
        c = rec.joint_index(j)
        cols[f"q{k + 1}"], cols[f"qd{k + 1}"], cols[f"tau{k + 1}"] = rec.q[:, c], rec.qd[:, c], rec.tau[:, c]
    if rec.base_pose is not None:
        from harness.model.quaternion import to_matrix

        R_T = np.swapaxes(to_matrix(rec.base_pose[:, 3:]), 1, 2)
        twist_B = np.concatenate([(R_T @ rec.base_twist_W[:, s, None])[..., 0] for s in (slice(0, 3), slice(3, 6))],
                                 axis=1)
        cols.update(zip(("px", "py", "pz"), rec.base_pose[:, :3].T, strict=True))
        cols.update(zip(("qx", "qy", "qz", "qw"), rec.base_pose[:, [4, 5, 6, 3]].T, strict=True))
        cols.update(zip(("vx", "vy", "vz", "wx", "wy", "wz"), twist_B.T, strict=True))
        for k, name in enumerate(rec.contacts):
            cols.update(zip((f"{name}_fx", f"{name}_fy", f"{name}_fz"), rec.contact_F_W[:, k].T, strict=True))
            if np.any(rec.contact_M_W[:, k] != 0.0):
                cols.update(zip((f"{name}_mx", f"{name}_my", f"{name}_mz"), rec.contact_M_W[:, k].T, strict=True))
    Path(path).write_text(csv_text(cols, missing=""), newline="")
