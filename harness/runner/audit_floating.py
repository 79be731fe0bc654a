"""The audit's figures for a floating base (harness/runner/audit.py): the robot with its base free
(harness/engines/floating.py) at random states (base poses uniform on SO(3), the joints within their
limits), in the harness's convention (harness/model/floating.py):
- MuJoCo's free joint against Pinocchio's free-flyer, both built from the harness's reading: the
  inverse dynamics (the base's six rows and the joints'), with a wrench on the base and one on the
  outermost body, and the mass matrix (harness/engines/floating.py, engines_agreement);
- Pinocchio's own parser of the file, its free-flyer kept (placed where the file draws the base: its
  configuration is that placement's inverse times the base's pose; its velocities are the base's, in
  base axes), against the harness's Pinocchio model, without wrenches;
- an MJCF file's own model in MuJoCo (its free joint's qpos the base's pose), the same.
Errors are relative to each row's largest |value| over the states (the mass matrix: its largest entry)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from harness.model.spec import RobotSpec


def floating_figures(spec: RobotSpec, described: Path | None, states, seed: int) -> dict:
    """{figure: value} for the robot's floating base; `states` (q, q', q'') of its joints."""
    from harness.base.numerics import largest_relative_difference as largest
    from harness.engines.floating import engines_agreement, inverse_dynamics
    from harness.model.floating import random_base_motion

    q, qd, qdd = states
    base = random_base_motion(len(q), seed)
    g = np.array([0.0, 0.0, -9.81])
    out = {f"floating_{k}": v for k, v in engines_agreement(spec, g, base, q, qd, qdd, seed).items()}
    if described is None:
        return out
    ours = inverse_dynamics(spec, g, base, q, qd, qdd, "pinocchio")
    theirs = _pinocchio_parse(spec, described, g, base, states)
    out["floating_vs_pinocchio_parser"] = max(largest(ours.base, theirs[0]), largest(ours.tau, theirs[1]))
    if described.suffix.lower() == ".xml":
        theirs = _mujoco_file(spec, described, g, base, states)
        out["floating_vs_mujoco_file"] = max(largest(ours.base, theirs[0]), largest(ours.tau, theirs[1]))
    return out


def _pinocchio_parse(spec: RobotSpec, path: Path, g: np.ndarray, base, states) -> tuple[np.ndarray, np.ndarray]:
    """Pinocchio's own parse of the file with its free-flyer: the base rows [F_W, M_W] and joint torques."""
    from harness.engines.pinocchio_file import free_inverse_dynamics

    return free_inverse_dynamics(path, spec.floating.joint, spec.joint_names, g, base, *states)


def _mujoco_file(spec: RobotSpec, path: Path, g: np.ndarray, base, states) -> tuple[np.ndarray, np.ndarray]:
    """MuJoCo's own model of the MJCF file (rigid bodies, as harness/engines/mujoco.py's
    file_inverse_dynamics prepares it) with its free joint: the base rows and joint torques."""
    from harness.engines.floating import mujoco_inverse
    from harness.engines.mujoco_file import rigid_file_model

    out = mujoco_inverse(rigid_file_model(path, g), spec.floating.joint, spec.joint_names, base, *states)
    return out.base, out.tau
