"""Rollouts: a model forward-simulated in MuJoCo under given joint torques, many starts advanced
together. What a log's prediction (`predict`: the drift of a model from measured states under the
measured torques) and the refinement by simulation (harness/identify/refine.py) run.

The scheme is MuJoCo's RK4 (the classical Runge-Kutta tableau, positions and velocities advanced from
the four stages' velocities and accelerations), the drive and its dry friction evaluated at every
stage. A drive's law is smooth and nonlinear in q' (tanh, Stribeck), which MuJoCo has no element
for, so it would be a Python callback at each stage of each rollout (8 to 20 us a call). Here the
stages are taken for the whole batch at once: MuJoCo evaluates the accelerations of all B states in
one call of `mujoco.rollout` on a pool of threads (`acceleration_model`: forward dynamics without a
callback), and numpy the stage's drive torque and dry friction of all B rows (friction.Dry.rows).
Against MuJoCo's own RK4 with the callback the trajectories agree to round-off (tests/test_refine.py)."""

from __future__ import annotations

import copy
import os
from collections.abc import Sequence

import mujoco
import numpy as np
from mujoco import rollout as mujoco_rollout

from harness.base.numerics import PREDICTION_TIMESTEP, RK4_A, RK4_B, sampled
from harness.engines.mujoco import ACCELERATION_STEP, acceleration_model, controlled
from harness.model import drives as drive_law
from harness.model import friction
from harness.model.spec import RobotSpec

ROWS_PER_THREAD = 64  # states a thread of the pool is given at least
_CLOCK = 1.0  # s: the time of every state sent; MuJoCo's reset of a non-finite one sets it to 0


def stage_times(steps: int, timestep: float) -> np.ndarray:
    """(2 steps + 1,): the times, from a rollout's start, at which RK4 evaluates the dynamics (each
    step's start, middle (twice) and end): where `rollouts` reads a drive."""
    return np.arange(2 * steps + 1) * (timestep / 2)


def threads(batch: int) -> int:
    """The threads MuJoCo evaluates a batch of `batch` states on: the cores this process may run on, each
    with at least ROWS_PER_THREAD rows (waking a thread costs about as much as 20 states); 0, the calling
    thread, for a smaller batch."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    count = min(cores, batch // ROWS_PER_THREAD)
    return count if count > 1 else 0


class _Stage:
    """A stage's rates of the rollouts still running (`rows`): the generalised force on each, the drive
    less its own law's dry friction (one numpy evaluation for all), and their accelerations in one
    `mujoco.rollout` call of one step of `acceleration_model`, row b in models[b] (its rotor inertia
    and viscous friction), on the pool's threads."""

    def __init__(self, models: list, laws: list, viscous: np.ndarray, index: np.ndarray, transmission,
                 qadr: np.ndarray, vadr: np.ndarray, pool, rows: np.ndarray):
        """models[k], laws[k] and viscous[k]: the k-th distinct law's; row b of the batch is under law index[b]."""
        model = models[index[rows[0]]]
        self.models = [models[k] for k in index[rows]]
        self.dry = drive_law.Dry(friction.Dry.rows(laws, index[rows]), transmission)
        self.viscous = viscous[index[rows]]  # (B, n), or (B, n, n) through a transmission: N^T diag(f_v) N
        self.pool, self.qadr, self.vadr, self.dofs = pool, 1 + qadr, 1 + model.nq + vadr, vadr
        self.data = [mujoco.MjData(model) for _ in range(max(pool.nthread, 1))]
        full = mujoco.mjtState.mjSTATE_FULLPHYSICS
        state = np.empty(mujoco.mj_stateSize(model, full))
        mujoco.mj_getState(model, self.data[0], state, full)  # the layout: time, qpos, qvel, ...
        state[0] = _CLOCK
        B = len(rows)
        self.state, self.next = np.tile(state, (B, 1)), np.empty((B, 1, len(state)))
        self.force = np.zeros((B, 1, model.nv))
        self.chunk = -(-B // max(pool.nthread, 1))  # one chunk per thread

    def applied(self, q: np.ndarray, qd: np.ndarray, drive: np.ndarray) -> np.ndarray:
        """The drive less its dry friction (a spring's part read at q). A load-dependent law reads the
        rigid-body torque as the drive less the rest of its friction (the rotor inertia's part, I_a q'', is
        not known before the stage)."""
        dry = self.dry
        if not dry.any:
            return drive
        if dry.needs_load:
            viscous = (self.viscous * qd if self.viscous.ndim == 2 else np.einsum("bij,bj->bi", self.viscous, qd))
            return drive - dry(qd, drive - dry(qd, load=False, q=q) - viscous, q=q)
        return drive - dry(qd, q=q)

    def __call__(self, q: np.ndarray, qd: np.ndarray, drive: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(B, n) q'' and (B,) whether MuJoCo took the state as it was (not reset on a bad one)."""
        self.state[:, self.qadr], self.state[:, self.vadr] = q, qd
        self.force[:, 0, self.dofs] = self.applied(q, qd, drive)
        self.pool.rollout(self.models, self.data, self.state, self.force, control_spec=_APPLIED, skip_checks=True,
                          nstep=1, state=self.next, chunk_size=self.chunk)
        return ((self.next[:, 0, self.vadr] - qd) / ACCELERATION_STEP,
                self.next[:, 0, 0] == _CLOCK + ACCELERATION_STEP)


_APPLIED = int(mujoco.mjtState.mjSTATE_QFRC_APPLIED)


def rollouts(spec: RobotSpec, gravity_W: np.ndarray, frictions: Sequence[tuple[friction.JointFriction, ...]],
             q0: np.ndarray, qd0: np.ndarray, drives: np.ndarray,
             timestep: float = PREDICTION_TIMESTEP) -> tuple[np.ndarray, np.ndarray]:
    """B forward simulations of the robot, advanced together by RK4 (`timestep`; the module's
    docstring): rollout b starts at (q0[b], qd0[b]) (B, n) and is driven by the joint torques drives[b]
    (B, 2 steps + 1, n), given at `stage_times(steps, timestep)`, less the dry friction of its own law
    frictions[b] (friction.Dry: Coulomb, offset and the families' terms); its rotor inertia and viscous
    friction are MuJoCo's armature and damping (with a transmission, its tendons'), so laws that differ
    only in friction share the robot's inertials. Returns q and q' after each step, (B, steps, n) in
    the spec's joint order, NaN from the step at which a rollout diverged (a non-finite state, or
    MuJoCo's reset on one at any stage), which is simulated no further."""
    model = acceleration_model(spec, gravity_W)
    joint_ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, j) for j in spec.joint_names]
    qadr, vadr = model.jnt_qposadr[joint_ids], model.jnt_dofadr[joint_ids]
    B, n = q0.shape
    steps = (drives.shape[1] - 1) // 2
    t = spec.transmission  # with one, each motor's inertia and damping are its tendon's (harness/model/mjspec.py)
    tendons = None if t is None else [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_TENDON, m) for m in t.motors]
    seen, index, models, laws, viscous = {}, np.empty(B, dtype=int), [], [], []  # each distinct law once
    for b, fr in enumerate(frictions):
        if id(fr) not in seen:
            k = friction.values(fr)
            m = model
            if fr != tuple(spec.frictions):
                m = copy.copy(model)
                if t is None:
                    m.dof_armature[vadr], m.dof_damping[vadr] = k[:, 0], k[:, 1]
                else:
                    m.tendon_armature[tendons], m.tendon_damping[tendons] = k[:, 0], k[:, 1]
            seen[id(fr)] = len(models)
            models.append(m), laws.append(fr), viscous.append(k[:, 1] if t is None else t.N.T @ np.diag(k[:, 1]) @ t.N)
        index[b] = seen[id(fr)]
    viscous = np.asarray(viscous)
    q_out, qd_out = np.full((B, steps, n), np.nan), np.full((B, steps, n), np.nan)
    rows = np.arange(B)  # the rollouts still running
    q, qd = np.array(q0, dtype=float), np.array(qd0, dtype=float)
    h = timestep
    with mujoco_rollout.Rollout(nthread=threads(B)) as pool, controlled(None, keep_warnings=False):
        stage = _Stage(models, laws, viscous, index, t, qadr, vadr, pool, rows)
        for s in range(steps):
            rates, ok = [], np.ones(len(rows), dtype=bool)
            q_i, qd_i = q, qd
            for i, at in enumerate((2 * s, 2 * s + 1, 2 * s + 1, 2 * s + 2)):
                if i:
                    q_i, qd_i = q + (RK4_A[i - 1] * h) * rates[-1][0], qd + (RK4_A[i - 1] * h) * rates[-1][1]
                qdd_i, took = stage(q_i, qd_i, drives[rows, at])
                rates.append((qd_i, qdd_i))
                ok &= took
            q = q + h * sum(w * r[0] for w, r in zip(RK4_B, rates, strict=True))
            qd = qd + h * sum(w * r[1] for w, r in zip(RK4_B, rates, strict=True))
            ok &= np.isfinite(q).all(axis=1) & np.isfinite(qd).all(axis=1)
            q_out[rows[ok], s], qd_out[rows[ok], s] = q[ok], qd[ok]
            if not ok.all():  # the diverged are simulated no further
                rows, q, qd = rows[ok], q[ok], qd[ok]
                if not len(rows):
                    break
                stage = _Stage(models, laws, viscous, index, t, qadr, vadr, pool, rows)
    return q_out, qd_out


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
