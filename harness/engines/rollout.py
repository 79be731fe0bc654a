"""Rollouts: a model forward-simulated in MuJoCo under given joint torques, many starts in one batch
of `mujoco.rollout` (RK4), its dry friction applied at every stage. What a log's prediction
(`predict`: the drift of a model from measured states under the measured torques) and the refinement
by simulation (harness/identify/refine.py) run."""

from __future__ import annotations

import copy
from collections.abc import Sequence

import mujoco
import numpy as np
from mujoco import rollout as mujoco_rollout

from harness.base.numerics import sampled
from harness.engines.mujoco import build_spec, controlled
from harness.model import drives as drive_law
from harness.model import friction
from harness.model.spec import RobotSpec


def _as_slice(index: np.ndarray) -> slice | np.ndarray:
    """index as a slice where its entries are consecutive."""
    if len(index) and np.array_equal(index, np.arange(index[0], index[0] + len(index))):
        return slice(int(index[0]), int(index[0]) + len(index))
    return index



PREDICTION_TIMESTEP = 0.001  # s: RK4 steps of a prediction (the log's torques read at every stage)
_BLOCK = 1024.0  # s: rollout b runs on the clock from b * _BLOCK, which tells the callback whose drive it is


def stage_times(steps: int, timestep: float) -> np.ndarray:
    """(2 steps + 1,): the times, from a rollout's start, at which RK4 evaluates the dynamics (each
    step's start, middle (twice) and end): where `rollouts` reads a drive."""
    return np.arange(2 * steps + 1) * (timestep / 2)


def rollouts(spec: RobotSpec, gravity_W: np.ndarray, frictions: Sequence[tuple[friction.JointFriction, ...]],
             q0: np.ndarray, qd0: np.ndarray, drives: np.ndarray,
             timestep: float = PREDICTION_TIMESTEP) -> tuple[np.ndarray, np.ndarray]:
    """B forward simulations of the robot in one batch of `mujoco.rollout` (RK4, `timestep`): rollout
    b starts at (q0[b], qd0[b]) (B, n) and is driven by the joint torques drives[b] (B, 2 steps + 1, n),
    given at `stage_times(steps, timestep)`, less the dry friction of its own law frictions[b]
    (friction.Dry: Coulomb, offset and the families' terms); its rotor inertia and viscous friction are
    MuJoCo's armature and damping, so laws that differ only in friction share the robot's inertials.
    Returns q and q' after each step, (B, steps, n) in the spec's joint order, NaN from the step at
    which a rollout diverged (a non-finite state, or MuJoCo's reset on one)."""
    model = build_spec(spec, gravity_W, "RK4", timestep).compile()
    data = mujoco.MjData(model)
    joint_ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, j) for j in spec.joint_names]
    qadr, vadr = model.jnt_qposadr[joint_ids], model.jnt_dofadr[joint_ids]
    B = len(q0)
    steps = (drives.shape[1] - 1) // 2
    t = spec.transmission  # with one, each motor's inertia and damping are its tendon's (harness/model/mjspec.py)
    tendons = None if t is None else [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_TENDON, m) for m in t.motors]
    laws, models, forcing = {}, {}, []  # each distinct law once: its model (armature, damping) and dry friction
    for fr in frictions:
        if id(fr) not in laws:
            k = friction.values(fr)
            m = model
            if fr != tuple(spec.frictions):
                m = copy.copy(model)
                if t is None:
                    m.dof_armature[vadr], m.dof_damping[vadr] = k[:, 0], k[:, 1]
                else:
                    m.tendon_armature[tendons], m.tendon_damping[tendons] = k[:, 0], k[:, 1]
            dry = friction.Dry.of(fr) if t is None else drive_law.Dry(fr, t)
            laws[id(fr)], models[id(fr)] = (dry, k[:, 1] if t is None else t.N.T @ np.diag(k[:, 1]) @ t.N), m
        forcing.append(laws[id(fr)])
    half, last = timestep / 2, 2 * steps
    v_at = _as_slice(vadr)
    qvel, qfrc_applied = data.qvel, data.qfrc_applied  # views of the one MjData the rollouts run in

    def applied(m: mujoco.MjModel, d: mujoco.MjData) -> None:
        now = d.time
        b = min(int(now // _BLOCK), B - 1)  # (a rollout MuJoCo reset restarts at time 0: its NaN is set below)
        drive = drives[b, min(round((now - b * _BLOCK) / half), last)]
        dry, viscous = forcing[b]
        v = qvel[v_at]
        # load-dependent friction: the drive's torque less the rest of its friction stands for the
        # rigid-body torque (the rotor inertia's part, I_a q'', is not known before the step); with a
        # transmission the viscous part is N^T diag(f_v) N q' (`viscous` that matrix)
        if dry.needs_load:
            rest = drive - dry(v, load=False) - (viscous * v if viscous.ndim == 1 else viscous @ v)
            qfrc_applied[v_at] = drive - dry(v, rest)
        else:
            qfrc_applied[v_at] = drive - dry(v)

    full = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state0 = np.empty(mujoco.mj_stateSize(model, full))
    mujoco.mj_getState(model, data, state0, full)  # the layout: time, qpos, qvel, ...
    state0 = np.tile(state0, (B, 1))
    clock = np.arange(B) * _BLOCK
    state0[:, 0] = clock
    state0[:, 1 + qadr], state0[:, 1 + model.nq + vadr] = q0, qd0
    with controlled(applied, keep_warnings=False):  # a diverged rollout is its NaN, not a warning line
        state, _ = mujoco_rollout.rollout([models[id(fr)] for fr in frictions], data, state0,
                                          np.zeros((1, 1, model.nu)), nstep=steps)
    q, qd = state[:, :, 1 + qadr], state[:, :, 1 + model.nq + vadr]
    expected = clock[:, None] + np.arange(1, steps + 1) * timestep
    bad = ~(np.isfinite(q).all(axis=2) & np.isfinite(qd).all(axis=2)) | (np.abs(state[:, :, 0] - expected) > half)
    bad = np.logical_or.accumulate(bad, axis=1)
    return np.where(bad[..., None], np.nan, q), np.where(bad[..., None], np.nan, qd)


def log_drives(t: np.ndarray, tau: np.ndarray, start_times: np.ndarray, steps: int, timestep: float,
               delay: np.ndarray | None = None) -> np.ndarray:
    """(B, 2 steps + 1, n): a log's torques tau (N, n) at times t (N,) read at the stage times of rollouts
    starting at `start_times` (B,), by linear interpolation; with `delay` (n,) or (B, n), each joint's
    channel read that much later (a channel behind its encoder)."""
    at = start_times[:, None] + stage_times(steps, timestep)  # (B, S)
    shift = np.zeros((len(start_times), tau.shape[1])) if delay is None else np.broadcast_to(
        delay, (len(start_times), tau.shape[1]))
    return np.stack([np.interp(at + shift[:, j:j + 1], t, tau[:, j]) for j in range(tau.shape[1])], axis=-1)


def predict(spec: RobotSpec, gravity_W: np.ndarray, t: np.ndarray, q: np.ndarray, qd: np.ndarray, tau: np.ndarray,
            starts: np.ndarray, horizons: tuple[float, ...], timestep: float = PREDICTION_TIMESTEP,
            delay: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """How far a model drifts from a measured motion under its measured torques. From each start row
    s, MuJoCo starts at the measured (q, q') and integrates (`rollouts`: RK4, `timestep`) with the
    joint torques read from the log (linear interpolation in time, at every stage of every step; each
    channel `delay` (n,) s later where given), less the model's dry friction; at each horizon the error
    q_sim - q_meas and q'_sim - q'_meas. t (N,),
    q, qd, tau (N, n) in the spec's joint order; returns two (starts, horizons, n) arrays, NaN where
    the simulation diverged."""
    steps = [round(h / timestep) for h in horizons]
    drives = log_drives(t, tau, t[starts], steps[-1], timestep, delay)
    q_sim, qd_sim = rollouts(spec, gravity_W, [tuple(spec.frictions)] * len(starts), q[starts], qd[starts], drives,
                             timestep)
    at = t[starts][:, None] + np.array(steps) * timestep  # (starts, horizons)
    rows = np.array(steps) - 1
    return q_sim[:, rows] - sampled(t, q, at), qd_sim[:, rows] - sampled(t, qd, at)
