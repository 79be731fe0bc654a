"""MuJoCo's own model of an MJCF file, compiled from the file (not the bench's model of the harness's reading
of it): what `harness audit` compares the harness's reading with (harness/runner/audit.py)."""

from __future__ import annotations

import re
from pathlib import Path

import mujoco
import numpy as np


def rigid_file_model(path: Path, gravity_W: np.ndarray) -> mujoco.MjModel:
    """MuJoCo's own model of the MJCF file at `path`, rigid bodies alone (`file_inverse_dynamics`)."""
    model = mujoco.MjModel.from_xml_path(str(path))
    model.opt.gravity[:] = gravity_W
    model.opt.density = model.opt.viscosity = 0.0
    flag = mujoco.mjtDisableBit
    model.opt.disableflags |= (flag.mjDSBL_EQUALITY | flag.mjDSBL_CONTACT | flag.mjDSBL_LIMIT
                               | flag.mjDSBL_FRICTIONLOSS)
    model.dof_armature[:] = model.dof_damping[:] = model.jnt_stiffness[:] = model.body_gravcomp[:] = 0.0
    model.tendon_armature[:] = model.tendon_damping[:] = model.tendon_stiffness[:] = 0.0
    return model


def file_inverse_dynamics(path: Path, joints: list[str], gravity_W: np.ndarray, q: np.ndarray, qd: np.ndarray,
                          qdd: np.ndarray) -> np.ndarray:
    """MuJoCo's inverse dynamics (mj_inverse, (N, n) in the order of `joints`, named as in the file) of its
    own model of the MJCF file at `path`, compiled from the file, rigid bodies alone: the joints' armature,
    damping, stiffness and the bodies' gravity compensation zeroed, the equality constraints (a closed
    chain's loops), contacts, joint limits and friction loss off, no fluid; a free joint held at the
    file's pose (qpos0) at rest, as the harness holds it. A ball joint of the file is the harness's three
    hinges `<ball>_x .. _z` (harness/model/cardano.py): its quaternion, angular velocity and acceleration
    made from theirs, its torque taken to theirs by D^T. ValueError: the file's model lacks a joint."""
    from harness.model.cardano import ball_state

    model = rigid_file_model(path, gravity_W)
    hinges, balls = _file_joints(model, path, joints)
    cols, pos = model.jnt_dofadr[[i for _, i in hinges]], model.jnt_qposadr[[i for _, i in hinges]]
    at = [k for k, _ in hinges]
    states = [(model.jnt_qposadr[i], model.jnt_dofadr[i], ks, ball_state(q[:, ks], qd[:, ks], qdd[:, ks]))
              for i, ks in balls]
    data = mujoco.MjData(model)
    tau = np.empty_like(q)
    for k in range(len(q)):
        data.qpos[:], data.qvel[:], data.qacc[:] = model.qpos0, 0.0, 0.0
        data.qpos[pos], data.qvel[cols], data.qacc[cols] = q[k, at], qd[k, at], qdd[k, at]
        for adr, dof, _, (quat, omega, omegadot, _) in states:
            data.qpos[adr:adr + 4], data.qvel[dof:dof + 3], data.qacc[dof:dof + 3] = quat[k], omega[k], omegadot[k]
        mujoco.mj_inverse(model, data)
        tau[k, at] = data.qfrc_inverse[cols]
        for _, dof, ks, (_, _, _, D) in states:
            tau[k, ks] = D[k].T @ data.qfrc_inverse[dof:dof + 3]
    return tau


def _file_joints(model: mujoco.MjModel, path: Path, joints: list[str]) -> tuple[list, list]:
    """Where each of `joints` (the harness's names) is in MuJoCo's model of the file: (k, joint id) of the
    hinges and slides, and (ball joint id, [k of <ball>_x, _y, _z]) of the balls. An unnamed joint is '#k'
    in the harness's reading (harness/model/mjcf.py): MuJoCo's joint k."""
    from harness.model.mjcf import BALL_AXES

    ball_of = {f"{model.joint(i).name}_{s}": (i, c) for i in range(model.njnt)
               if int(model.jnt_type[i]) == int(mujoco.mjtJoint.mjJNT_BALL) for c, s in enumerate(BALL_AXES)}
    hinges, balls, missing = [], {}, []
    for k, j in enumerate(joints):
        i = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, j)
        if i < 0 and re.fullmatch(r"#\d+", j):
            i = int(j[1:])
        if 0 <= i < model.njnt and int(model.jnt_type[i]) in (int(mujoco.mjtJoint.mjJNT_HINGE),
                                                               int(mujoco.mjtJoint.mjJNT_SLIDE)):
            hinges.append((k, i))
        elif j in ball_of:
            balls.setdefault(ball_of[j][0], [None] * 3)[ball_of[j][1]] = k
        else:
            missing.append(j)
    missing += [f"{model.joint(i).name}_{s}" for i, ks in balls.items() for s, k in zip(BALL_AXES, ks, strict=True)
                if k is None]
    if missing:
        raise ValueError(f"MuJoCo's model of {Path(path).name} has no joint {missing[0]!r}")
    return hinges, list(balls.items())
