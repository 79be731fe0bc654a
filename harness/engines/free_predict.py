"""How far a floating robot drifts from its log when driven by what the log measured: forward prediction of a
floating base (harness/stages/floating_log.py).

From a measured state (the base's pose and twist, the joints' q and q'), MuJoCo integrates the robot on its free
joint (RK4, PREDICTION_TIMESTEP) under the log's joint torques, less the model's dry friction (its rotor inertia
and viscous friction are MuJoCo's, on the joints or the motors' tendons), and the log's contact wrenches applied
as external forces on their bodies: each contact's force at its point and its moment, moved to the body's centre
of mass for MuJoCo's xfrc_applied (M + (x - c) x F). No contact law is simulated: the ground acts as the log
says it did, so a model's drift is its own (and the noise's). Each measured channel is read by linear
interpolation at the middle of every step (held through the step's stages). At each horizon: the base origin's
distance from the log's, the angle between the two orientations, and each joint's q_sim - q_meas."""

from __future__ import annotations

import mujoco
import numpy as np

from harness.base.numerics import PREDICTION_TIMESTEP, sampled
from harness.engines.mujoco import build_model
from harness.engines.simulation import Simulation
from harness.model import drives, floating
from harness.model.floating import BaseMotion
from harness.model.spec import RobotSpec


def _channels(t: np.ndarray, x: np.ndarray, at: np.ndarray) -> np.ndarray:
    """x (N, ...) at times `at` (M,): numerics.sampled over its channels flattened (held at the ends)."""
    return sampled(t, x.reshape(len(t), -1), at).reshape((len(at),) + x.shape[1:])


def predict(spec: RobotSpec, gravity_W: np.ndarray, t: np.ndarray, base: BaseMotion, q: np.ndarray, qd: np.ndarray,
            tau: np.ndarray, bodies: tuple[str, ...], F_W: np.ndarray, M_W: np.ndarray, x_W: np.ndarray,
            starts: np.ndarray, horizons: tuple[float, ...], timestep: float = PREDICTION_TIMESTEP
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(module docstring) t (N,), `base` (N states), q, qd, tau (N, n) in the spec's joint order, each contact's
    body `bodies` (k,) and its measured force, moment about its point and point F_W, M_W, x_W (N, k, 3). Returns
    the base's position error (starts, horizons) m, its angle (starts, horizons) rad and the joints' errors
    (starts, horizons, n); NaN from where a simulation diverged."""
    model = build_model(spec, gravity_W, Simulation(integrator="RK4", timestep=timestep), floating=True)
    data = mujoco.MjData(model)
    free = model.joint(spec.floating.joint)
    bq, bv = int(free.qposadr[0]), int(free.dofadr[0])
    qadr = np.array([model.joint(j).qposadr[0] for j in spec.joint_names], dtype=int)
    vadr = np.array([model.joint(j).dofadr[0] for j in spec.joint_names], dtype=int)
    act = np.array([model.actuator(f"drive_{j}").id for j in spec.joint_names], dtype=int)
    body_ids = np.array([model.body(b).id for b in bodies], dtype=int)
    dry = drives.Dry(spec.frictions, spec.transmission)
    qpos0, qvel0, _ = floating.to_mujoco(base)
    steps = [round(h / timestep) for h in horizons]
    pos_err, angle, q_err = (np.full((len(starts), len(steps)), np.nan), np.full((len(starts), len(steps)), np.nan),
                             np.full((len(starts), len(steps), len(spec.joints)), np.nan))
    for s, row in enumerate(starts):
        mid = t[row] + (np.arange(steps[-1]) + 0.5) * timestep
        tau_k, F_k, M_k, x_k = (_channels(t, x, mid) for x in (tau, F_W, M_W, x_W))
        mujoco.mj_resetData(model, data)
        data.qpos[bq:bq + 7], data.qvel[bv:bv + 6] = qpos0[row], qvel0[row]
        data.qpos[qadr], data.qvel[vadr] = q[row], qd[row]
        kept = {}
        for k in range(steps[-1]):
            mujoco.mj_kinematics(model, data)  # the bodies' centres of mass now
            # each contact's wrench at its body's centre of mass, summed where a body holds several
            wrench = np.concatenate([F_k[k], M_k[k] + np.cross(x_k[k] - data.xipos[body_ids], F_k[k])], axis=1)
            data.xfrc_applied[:] = 0.0
            np.add.at(data.xfrc_applied, body_ids, wrench)
            data.ctrl[act] = tau_k[k] - dry(data.qvel[vadr], q=data.qpos[qadr])
            mujoco.mj_step(model, data)
            if not (np.all(np.isfinite(data.qpos)) and np.all(np.isfinite(data.qvel))):
                break
            if k + 1 in steps:
                kept[k + 1] = (data.qpos[bq:bq + 7].copy(), data.qpos[qadr].copy())
        at = t[row] + np.array(steps) * timestep
        wanted = _base_at(t, base, at)
        q_meas = _channels(t, q, at)
        for h, n_steps in enumerate(steps):
            if n_steps not in kept:
                continue
            pose, q_sim = kept[n_steps]
            sim = floating.from_mujoco(pose[None], np.zeros((1, 6)), np.zeros((1, 6)))
            p, a = floating.tracking_error(sim, wanted.take(np.array([h])))
            pos_err[s, h], angle[s, h], q_err[s, h] = p[0], a[0], q_sim - q_meas[h]
    return pos_err, angle, q_err


def _base_at(t: np.ndarray, base: BaseMotion, at: np.ndarray) -> BaseMotion:
    """The measured base at times `at`: its position interpolated linearly, its orientation the nearer sample's
    slerped to the next (scipy's Slerp), its twist and rate zero (unused)."""
    from scipy.spatial.transform import Rotation, Slerp

    xyzw = base.quat_wxyz[:, [1, 2, 3, 0]]
    quat = Slerp(t, Rotation.from_quat(xyzw))(np.clip(at, t[0], t[-1])).as_quat()[:, [3, 0, 1, 2]]
    zero = np.zeros((len(at), 3))
    return BaseMotion(_channels(t, base.p_W, at), quat, zero, zero, zero, zero)
