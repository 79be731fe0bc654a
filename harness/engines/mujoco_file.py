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
    hinges `<ball>_x .. _z` (`Coordinates`). ValueError: the file's model lacks a joint."""
    model = rigid_file_model(path, gravity_W)
    at = Coordinates(model, joints, q, qd, qdd, Path(path).name)
    data = mujoco.MjData(model)
    force = np.empty((len(q), model.nv))
    for k in range(len(q)):
        data.qpos[:], data.qvel[:], data.qacc[:] = model.qpos0, 0.0, 0.0
        at.put(data, k)
        mujoco.mj_inverse(model, data)
        force[k] = data.qfrc_inverse
    return at.torques(force)


class Coordinates:
    """The harness's joints' (q, q', q'') (N, n) as a MuJoCo model's coordinates, sample by sample: a hinge or
    slide its own, a ball joint from its three hinges `<ball>_x .. _z` (harness/model/cardano.py: its
    quaternion, its angular velocity D theta' and acceleration D theta'' + D' theta'), and a generalised
    force back on the harness's joints (a ball's torque by D^T). Joints are found by name; an unnamed one
    is '#k' in the harness's reading (harness/model/mjcf.py): MuJoCo's joint k. ValueError: the model
    lacks a joint (`model_name` says whose)."""

    def __init__(self, model: mujoco.MjModel, joints: list[str], q: np.ndarray, qd: np.ndarray, qdd: np.ndarray,
                 model_name: str):
        from harness.model.cardano import ball_state
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
        missing += [f"{model.joint(i).name}_{s}" for i, ks in balls.items()
                    for s, k in zip(BALL_AXES, ks, strict=True) if k is None]
        if missing:
            raise ValueError(f"MuJoCo's model of {model_name} has no joint {missing[0]!r}")
        ids = [i for _, i in hinges]
        self.at, self.pos, self.cols = [k for k, _ in hinges], model.jnt_qposadr[ids], model.jnt_dofadr[ids]
        self.q, self.qd, self.qdd = q, qd, qdd
        self.balls = [(model.jnt_qposadr[i], model.jnt_dofadr[i], ks, ball_state(q[:, ks], qd[:, ks], qdd[:, ks]))
                      for i, ks in balls.items()]

    def put(self, data: mujoco.MjData, k: int) -> None:
        """Sample k's coordinates, velocities and accelerations into `data` (the others left as they are)."""
        data.qpos[self.pos], data.qvel[self.cols], data.qacc[self.cols] = (
            self.q[k, self.at], self.qd[k, self.at], self.qdd[k, self.at])
        for adr, dof, _, (quat, omega, omegadot, _) in self.balls:
            data.qpos[adr:adr + 4], data.qvel[dof:dof + 3], data.qacc[dof:dof + 3] = quat[k], omega[k], omegadot[k]

    def torques(self, force: np.ndarray) -> np.ndarray:
        """The generalised forces `force` (N, nv), one per sample, on the harness's joints, (N, n)."""
        out = np.empty(self.q.shape)
        out[:, self.at] = force[:, self.cols]
        for _, dof, ks, (_, _, _, D) in self.balls:
            out[:, ks] = np.einsum("nij,ni->nj", D, force[:, dof:dof + 3])
        return out
