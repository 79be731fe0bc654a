"""Refinement by simulation: what the linear fit cannot adjust, chosen so that the model predicts motion.

The fit of a joint log (torque_id, consistent) is linear in every coefficient once each joint's
smoothing velocity v_c (and Stribeck velocity v_s) is chosen (friction_law chooses them by the
held-out torque error) and once the torques are taken as read at the encoders' instants (delay
estimates a lag in the torque domain). Here these are adjusted by the motion itself: z holds
ln v_c and ln v_s of the joints whose law has them and a delay d_j per torque channel (`adjust`).

For a candidate z:
1. the drive's coefficients of every joint (rotor inertia I_a, viscous f_v, Coulomb f_c, offset f_o
   and its family's terms, harness/model/friction.py) are re-solved by bounded least squares
   (I_a, f_v, f_c and the Stribeck and load terms >= 0) on the training span's torques read d_j later,
   less the consistent fit's rigid-body torque, which stays as fitted: the linear part is the best
   the torques allow for that z (variable projection). An asymmetry is then held within its
   symmetric term, as the consistent fit holds it;
2. that model is forward-simulated in MuJoCo (harness/engines/rollout.py, rollouts: RK4, `timestep`) from K
   measured states of the training span, each over `horizon` seconds under the measured torques read
   d_j later, every start and every finite-difference column of the Jacobian in one batch;
3. the residual is, every `sample` seconds of each rollout and per joint,
   (q_sim - q_meas) / (s_j H) and (q'_sim - q'_meas) / s_j, with s_j the joint's RMS velocity over the
   training span and H the horizon (a diverged rollout's residual is DIVERGED).
z minimises the sum of squares (scipy.optimize.least_squares, trust region reflective within
bounds: a velocity within VELOCITY_RANGE of where the pass starts, a delay within +-delay.LARGEST),
from the model it is given (the consistent fit, its velocities and no delay, in the first pass).
Nothing of the validation span is read. With drives (harness/model/drives.py) each motor's law is
re-solved on its own torque, N^-T (tau - tau_R), at its own rates, and the torque channels' delays are
not adjusted (a channel of a motor-side log is a motor's, mixed into the joints' torques by N).

`refine` is one pass; harness/stages/refinement.py alternates passes with the consistent fit
re-solved at their result, and keeps the candidate that predicts the training span best among those
fitting its torques within TORQUE_SLACK of the consistent fit.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.optimize import least_squares, lsq_linear

from harness.base.numerics import (
    PREDICTION_TIMESTEP,
    evenly_spaced,
    relative_residual,
    relative_residual_of_sums,
    sampled,
)
from harness.base.series import room
from harness.engines.rollout import log_drives, rollouts
from harness.identify import delay as channel_delay
from harness.identify.laws import Law, spring_positions
from harness.model.drives import Transmission, at_drives
from harness.model.friction import (
    BOUNDED_BY,
    EXTRA_KEYS,
    IDENTIFIED_KEYS,
    NONNEGATIVE_KEYS,
    JointFriction,
    columns,
    extra_columns,
)
from harness.model.spec import RobotSpec

ADJUSTABLE = ("coulomb_velocity", "stribeck_velocity", "delay")
VELOCITY_RANGE = 30.0  # a smoothing or Stribeck velocity stays within [v0 / 30, 30 v0]
LOG_STEP = 0.02  # finite-difference step in ln v (2 %)
DELAY_STEP = 2e-4  # s: finite-difference step of a delay
DELAY_SCALE = 5e-3  # s: a delay's typical size, for the trust region's scaling
DIVERGED = 10.0  # the residual of a diverged rollout's samples (10 times the motion's own scale)
TORQUE_SLACK = 0.01  # the refined model may fit the training torques at most 1 % (relative) worse


@dataclass(frozen=True)
class RefineConfig:
    """`[refinement]`: `adjust` what is adjusted (ADJUSTABLE), `horizon` (s) and `starts` the
    rollouts of the objective, `sample` (s) how often a rollout is compared with the log,
    `iterations` the evaluations of the objective least_squares may make in one pass, `passes` how
    many times the adjustment and the linear fit at its result alternate."""

    adjust: tuple[str, ...] = ("coulomb_velocity", "delay")
    horizon: float = 0.1
    starts: int = 20
    sample: float = 0.005
    iterations: int = 10
    passes: int = 2

    @property
    def reach(self) -> float:
        """s: how far from a sample its torque may be read (the delays' bound, when they are adjusted)."""
        return channel_delay.LARGEST if "delay" in self.adjust else 0.0


@dataclass(frozen=True, eq=False)
class Refinement:
    slots: tuple[tuple[int, str], ...]  # what was adjusted: (joint index, "coulomb_velocity" | ... | "delay")
    names: tuple[str, ...]  # the same as "<joint>.<key>"
    initial: np.ndarray  # the values it started from (rad/s or m/s; s)
    refined: np.ndarray
    frictions: tuple[JointFriction, ...]  # the refined law: velocities and re-solved coefficients
    delay: np.ndarray  # (n,) s, each torque channel read this much later
    cost: dict[str, float]  # "start", "refined": RMS of the residual over the training starts
    torque_rel_error: dict[str, float]  # the same two: ||tau_pred - tau||_F / ||tau||_F on the training span
    starts: int
    rollouts: int  # trajectories simulated in all
    steps: int  # steps simulated in all
    evaluations: int  # batches of rollouts (one per residual or Jacobian)
    seconds: float
    message: str  # least_squares' own


@dataclass(frozen=True, eq=False)
class _Problem:
    spec: RobotSpec  # the consistent fit (links and law)
    gravity_W: np.ndarray
    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    tau: np.ndarray
    rigid: np.ndarray  # (N, n) the consistent fit's rigid-body torque
    rows: np.ndarray  # the rows whose torque may be read up to delay.LARGEST either way
    starts: np.ndarray
    steps: int
    every: int  # steps between compared samples
    scale: np.ndarray  # (n,) s_j
    horizon: float
    timestep: float
    slots: tuple[tuple[int, str], ...]  # what each entry of z is: (joint, key)
    laws: tuple[Law, ...]  # each joint's law (its family's terms)
    motor: tuple[np.ndarray, ...]  # (qd, qdd, rigid, tau, q) at each drive: the joints', or the motors' (N^-T)
    fits: dict = field(default_factory=dict)  # (joint, v_c, v_s, lag) -> its drive's fit (`_drive_fit_once`)


def _law(p: _Problem, z: np.ndarray) -> tuple[tuple[JointFriction, ...], np.ndarray]:
    """The joints' laws and the channels' delays of candidate z, the coefficients re-solved."""
    n = p.q.shape[1]
    velocity = {k: {"coulomb_velocity": f.coulomb_velocity, "stribeck_velocity": f.stribeck_velocity}
                for k, f in enumerate(p.spec.frictions)}
    lag = np.zeros(n)
    for (k, key), value in zip(p.slots, z, strict=True):
        if key == "delay":
            lag[k] = value
        else:
            velocity[k][key] = float(np.exp(value))
    return tuple(_drive_fit_once(p, k, velocity[k], lag[k]) for k in range(n)), lag


def _drive_fit_once(p: _Problem, k: int, velocity: dict, lag: float) -> JointFriction:
    """_drive_fit, each joint's at given velocities and lag solved once: a Jacobian's column moves one
    joint's value, and every other joint's fit is the one at the point it is taken at."""
    key = (k, velocity["coulomb_velocity"], velocity["stribeck_velocity"], float(lag))
    if key not in p.fits:
        p.fits[key] = _drive_fit(p, k, velocity, lag)
    return p.fits[key]


def _read(t: np.ndarray, tau_k: np.ndarray, rows: np.ndarray, lag: float) -> np.ndarray:
    """A joint's torque tau_k (N,) read `lag` later, at `rows`."""
    return np.interp(t[rows] + lag, t, tau_k) if lag else tau_k[rows]


def _columns(qd: np.ndarray, qdd: np.ndarray, rigid: np.ndarray, v_c: float, v_s: float,
             terms: tuple[str, ...], q: np.ndarray | None = None) -> tuple[np.ndarray, tuple[str, ...]]:
    """One joint's drive regressor at velocities qd, accelerations qdd, rigid-body torque rigid and
    positions q (each (N,)): [q'', q', s, 1] (harness/model/friction.py, columns), its family's shapes,
    and their keys."""
    law = (Law(coulomb_velocity=v_c, stribeck_velocity=v_s).shapes,)
    drive = columns(law, qd[:, None], qdd[:, None])[:, 0]
    extra = extra_columns(law, qd[:, None], rigid[:, None], None if q is None else q[:, None])[:, 0]
    keys = (*IDENTIFIED_KEYS, *terms)
    return np.column_stack([drive, *(extra[:, EXTRA_KEYS.index(key)] for key in terms)]), keys


def _drive_fit(p: _Problem, k: int, velocity: dict, lag: float) -> JointFriction:
    rows = p.rows
    qd, qdd, rigid, tau, q = p.motor
    A, keys = _columns(qd[rows, k], qdd[rows, k], rigid[rows, k], velocity["coulomb_velocity"],
                       velocity["stribeck_velocity"], p.laws[k].terms, q[rows, k])
    y = _read(p.t, tau[:, k], rows, lag) - rigid[rows, k]
    size = np.sqrt(np.mean(A**2, axis=0))
    size = np.where(size > 0, size, 1.0)
    lower = np.array([0.0 if key in NONNEGATIVE_KEYS else -np.inf for key in keys])
    x = lsq_linear(A / size, y, bounds=(lower, np.inf), method="bvls").x / size
    values = dict(zip(keys, map(float, x), strict=True))
    for key, bound in BOUNDED_BY.items():
        if key in values:
            values[key] = float(np.clip(values[key], -values[bound], values[bound]))
    return replace(p.laws[k], **velocity).friction(**values)


def _inner(t: np.ndarray, largest: float) -> np.ndarray:
    """The rows at least `largest` s from their stretch's ends: where a torque may be read that much
    earlier or later."""
    back, ahead = room(t)
    return np.flatnonzero((back >= largest) & (ahead >= largest))


def torque_rel_error(t: np.ndarray, qd: np.ndarray, qdd: np.ndarray, tau: np.ndarray, rigid: np.ndarray,
                     frictions: tuple[JointFriction, ...], laws: tuple[Law, ...], lag: np.ndarray,
                     largest: float, transmission: Transmission | None = None, q: np.ndarray | None = None) -> float:
    """||tau_pred - tau||_F / ||tau||_F with each joint's torque read lag[j] later and predicted as the
    rigid-body torque `rigid` plus its drive's law; over the rows at least `largest` s from a
    stretch's ends (the same rows whatever the lags). With a transmission the motors' laws reach the
    joints through N (no lags). q (N, n), the positions, a spring's."""
    rows = _inner(t, largest)
    q = spring_positions(q, False, laws)
    if transmission is not None:
        (qd_m, q_m), qdd_m, rigid_m = (at_drives(transmission, qd, q), transmission.motor_rates(qdd),
                                       transmission.motor_torques(rigid))
        drive = np.column_stack([_columns(qd_m[rows, k], qdd_m[rows, k], rigid_m[rows, k], f.coulomb_velocity,
                                          f.stribeck_velocity, law.terms, None if q_m is None else q_m[rows, k])[0]
                                 @ np.array([getattr(f, key) for key in (*IDENTIFIED_KEYS, *law.terms)])
                                 for k, (f, law) in enumerate(zip(frictions, laws, strict=True))])
        return relative_residual(rigid[rows] + transmission.joint_torques(drive) - tau[rows], tau[rows])
    num = den = 0.0
    for k, (f, law) in enumerate(zip(frictions, laws, strict=True)):
        A, keys = _columns(qd[rows, k], qdd[rows, k], rigid[rows, k], f.coulomb_velocity, f.stribeck_velocity,
                           law.terms, None if q is None else q[rows, k])
        y = _read(t, tau[:, k], rows, lag[k])
        num += float(np.sum((y - rigid[rows, k] - A @ np.array([getattr(f, key) for key in keys])) ** 2))
        den += float(np.sum(y**2))
    return relative_residual_of_sums(num, den)


def _residuals(p: _Problem, candidates: list[tuple[tuple[JointFriction, ...], np.ndarray]]) -> np.ndarray:
    """(len(candidates), m): each candidate's residual vector, its rollouts in one batch."""
    K = len(p.starts)
    frictions = [fr for fr, _ in candidates for _ in range(K)]
    lags = np.repeat(np.array([lag for _, lag in candidates]), K, axis=0)
    t0 = np.tile(p.t[p.starts], len(candidates))
    drives = log_drives(p.t, p.tau, t0, p.steps, p.timestep, lags)
    q_sim, qd_sim = rollouts(p.spec, p.gravity_W, frictions, np.tile(p.q[p.starts], (len(candidates), 1)),
                             np.tile(p.qd[p.starts], (len(candidates), 1)), drives, p.timestep)
    compared = np.arange(p.every, p.steps + 1, p.every)
    at = t0[:, None] + compared * p.timestep
    r = np.concatenate([(q_sim[:, compared - 1] - sampled(p.t, p.q, at)) / (p.scale * p.horizon),
                        (qd_sim[:, compared - 1] - sampled(p.t, p.qd, at)) / p.scale], axis=-1)
    r = np.where(np.isfinite(r), r, DIVERGED)
    return r.reshape(len(candidates), -1)


def _problem(spec: RobotSpec, gravity_W: np.ndarray, t: np.ndarray, q: np.ndarray, qd: np.ndarray,
             qdd: np.ndarray, tau: np.ndarray, rigid: np.ndarray, laws: tuple[Law, ...], config: RefineConfig,
             timestep: float, slots: tuple = ()) -> _Problem:
    largest = config.reach
    rows = _inner(t, largest)
    back, ahead = room(t)
    usable = np.flatnonzero((back >= largest) & (ahead >= config.horizon + largest))
    if not len(usable) or len(rows) < 10:
        raise ValueError(f"no stretch of the training span is {config.horizon + 2 * largest:g} s long")
    starts = usable[evenly_spaced(len(usable), config.starts)]
    steps = round(config.horizon / timestep)
    tm = spec.transmission
    motor = ((qd, qdd, rigid, tau, q) if tm is None else
             (tm.motor_rates(qd), tm.motor_rates(qdd), tm.motor_torques(rigid), tm.motor_torques(tau),
              tm.motor_positions(q)))
    return _Problem(spec, np.asarray(gravity_W, dtype=float), t, q, qd, qdd, tau, rigid, rows, starts, steps,
                    max(1, round(config.sample / timestep)), np.maximum(np.sqrt(np.mean(qd**2, axis=0)), 1e-9),
                    config.horizon, timestep, tuple(slots), tuple(laws), motor)


def judge(spec: RobotSpec, gravity_W: np.ndarray, t: np.ndarray, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray,
          tau: np.ndarray, rigid: np.ndarray, laws: tuple[Law, ...], lag: np.ndarray, config: RefineConfig,
          timestep: float = PREDICTION_TIMESTEP) -> tuple[float, float]:
    """A model as it stands (its links and its law, each channel read lag (n,) s later): the RMS of
    the refinement's residual over the span's starts, and its torque error (torque_rel_error)."""
    p = _problem(spec, gravity_W, t, q, qd, qdd, tau, rigid, laws, config, timestep)
    r = _residuals(p, [(tuple(spec.frictions), lag)])[0]
    return (float(np.sqrt(np.mean(r**2))),
            torque_rel_error(t, qd, qdd, tau, rigid, tuple(spec.frictions), laws, lag, config.reach,
                             spec.transmission, q))


def refine(spec: RobotSpec, gravity_W: np.ndarray, t: np.ndarray, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray,
           tau: np.ndarray, rigid: np.ndarray, laws: tuple[Law, ...], config: RefineConfig,
           delay: np.ndarray | None = None, timestep: float = PREDICTION_TIMESTEP) -> Refinement:
    """One pass of the refinement (module docstring) from the model `spec` (its links, fixed, and each
    joint's law, whose family is laws[j]) with its channels read `delay` (n,) s later (default none),
    on the training span t (N,), q, q', q'', tau (N, n) as the fit read them; rigid (N, n) the
    model's rigid-body torque there. Raises ValueError when the span has no room for a rollout or
    nothing is left to adjust."""
    started = time.perf_counter()
    largest = config.reach
    lag0 = np.zeros(q.shape[1]) if delay is None else np.asarray(delay, dtype=float)
    slots, x0, lower, upper, x_scale, steps_fd = [], [], [], [], [], []
    for k, f in enumerate(spec.frictions):
        for key in config.adjust:
            v = getattr(f, key) if key != "delay" else 0.0
            if key == "stribeck_velocity" and "stribeck" not in laws[k].terms:
                continue
            if key == "delay" and spec.transmission is not None:
                continue  # a motor-side channel is mixed into the joints' torques: not adjusted
            if key == "delay":
                slots.append((k, key))
                x0.append(float(np.clip(lag0[k], -largest, largest))), lower.append(-largest), upper.append(largest)
                x_scale.append(DELAY_SCALE), steps_fd.append(DELAY_STEP)
            elif v > 0:  # a joint with a sharp sign (v_c = 0) or no Stribeck term has nothing to adjust
                slots.append((k, key))
                x0.append(np.log(v)), lower.append(np.log(v / VELOCITY_RANGE)), upper.append(np.log(v * VELOCITY_RANGE))
                x_scale.append(1.0), steps_fd.append(LOG_STEP)
    if not slots:
        raise ValueError(f"nothing to adjust: no joint's law has {' or '.join(config.adjust)}")
    p = _problem(spec, gravity_W, t, q, qd, qdd, tau, rigid, laws, config, timestep, tuple(slots))
    starts, steps = p.starts, p.steps
    counts = {"rollouts": 0, "evaluations": 0}
    cache: dict[bytes, np.ndarray] = {}

    def rolled(candidates: list) -> np.ndarray:
        """_residuals, counted."""
        counts["rollouts"] += len(candidates) * len(starts)
        counts["evaluations"] += 1
        return _residuals(p, candidates)

    def batch(zs: list[np.ndarray]) -> np.ndarray:
        return rolled([_law(p, z) for z in zs])

    def fun(z: np.ndarray) -> np.ndarray:
        key = z.tobytes()
        if key not in cache:
            cache.clear()
            cache[key] = batch([z])[0]
        return cache[key]

    upper_a, lower_a = np.array(upper), np.array(lower)
    h_a = np.array(steps_fd)

    def jac(z: np.ndarray) -> np.ndarray:
        h = np.where(z + h_a <= upper_a, h_a, -h_a)  # a step that stays within the bounds
        columns = batch([z + h[i] * np.eye(len(z))[i] for i in range(len(z))])
        return ((columns - fun(z)) / h[:, None]).T

    x0_a = np.array(x0)
    consistent_law = tuple(spec.frictions)
    r0 = rolled([(consistent_law, lag0)])[0]  # the model as it stands: its own coefficients, not re-solved
    result = least_squares(fun, x0_a, jac=jac, bounds=(lower_a, upper_a), method="trf", x_scale=np.array(x_scale),
                           max_nfev=config.iterations)
    frictions, lag = _law(p, result.x)
    cost = {"start": float(np.sqrt(np.mean(r0**2))), "refined": float(np.sqrt(np.mean(fun(result.x) ** 2)))}
    torque = {name: torque_rel_error(t, qd, qdd, tau, rigid, fr, p.laws, lg, largest, spec.transmission, q)
              for name, fr, lg in (("start", consistent_law, lag0), ("refined", frictions, lag))}

    def natural(z: np.ndarray) -> np.ndarray:
        return np.array([v if key == "delay" else np.exp(v) for (_, key), v in zip(slots, z, strict=True)])

    joints = spec.drive_names
    return Refinement(tuple(slots), tuple(f"{joints[k]}.{key}" for k, key in slots), natural(x0_a),
                      natural(result.x), frictions, lag, cost, torque, len(starts), counts["rollouts"],
                      counts["rollouts"] * steps, counts["evaluations"], time.perf_counter() - started,
                      str(result.message))
