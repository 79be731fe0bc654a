"""Exciting trajectories a robot can run: a finite Fourier series per joint, optimised for the
joint-torque regressor, within the robot's limits.

    q_j(t) = q0_j + sum_{l=1..L} a_jl / (l w_f) sin(l w_f t) - b_jl / (l w_f) cos(l w_f t)

(the periodic form usual in robot identification), with q0_j the middle of the joint's range.
At rest at both ends of a period: q'(0) = sum_l a_jl = 0 and q''(0) = w_f sum_l l b_jl = 0, which
the last harmonic's coefficients are solved for, so every series the optimiser tries starts and
ends at rest (and needs two harmonics at least).

Objective (`criterion`): the condition number of the column-scaled base regressor
(harness/identify/torque_id.py; the base set is chosen once, structurally, before optimising), or
D-optimality, -log det of its information matrix per parameter, at samples over one period; plus a
penalty where the trajectory passes `limit_fraction` of a limit. Limits: the joints' position
ranges, their velocity and effort limits (the URDF's <limit velocity effort>) and an acceleration
limit the scenario gives; the torques are the model's inverse dynamics with its friction and rotor
inertia. Powell's method from a seeded random start makes the result the same on every run. After
the optimisation the trajectory is checked on a dense grid (DENSE samples a period) and, should it
pass a limit there, its amplitude is scaled down until it holds every limit; a limit the robot
cannot hold even at rest (an effort below its own weight's torque) is refused.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np

from harness.base.numerics import condition, equilibrated_condition_number, equilibrated_singular_values
from harness.base.tomlio import InputError, Table
from harness.engines.pinocchio import build_model, joint_torques
from harness.identify.torque_id import regressor, structural_base
from harness.sources.motion import Sinusoids

SAMPLES = 60  # regressor samples over one period
DENSE = 400  # samples a period on which the limits are checked
PENALTY = 1e3
CRITERIA = ("condition", "d-optimality")
LIMIT_KINDS = ("position", "velocity", "acceleration", "torque")


@dataclass(frozen=True)
class Excitation:
    """`[excitation]`: a Fourier series of `harmonics` harmonics of `base_frequency` (rad/s) per joint,
    optimised over `evaluations` evaluations of `criterion` from a start drawn with `seed`, every limit
    (with `acceleration_limit`, rad/s^2 or m/s^2, where given) used to at most `limit_fraction`;
    `rate` (Hz) is the sampling of the trajectory `harness excite` writes."""

    base_frequency: float
    harmonics: int = 2
    evaluations: int = 400
    seed: int = 0
    criterion: str = "condition"
    acceleration_limit: float | None = None
    limit_fraction: float = 0.9
    rate: float = 100.0

    @property
    def period(self) -> float:
        return 2 * np.pi / self.base_frequency


def read_excitation(t: Table) -> Excitation:
    """`[excitation]`, validated (one-line errors naming the key)."""
    d = Excitation
    config = Excitation(t.number("base_frequency", positive=True),
                        t.integer("harmonics", default=d.harmonics, minimum=2),
                        t.integer("evaluations", default=d.evaluations, minimum=10),
                        t.integer("seed", default=d.seed, minimum=0),
                        t.string("criterion", default=d.criterion, choices=CRITERIA),
                        t.number("acceleration_limit", positive=True) if t.has("acceleration_limit") else None,
                        t.number("limit_fraction", default=d.limit_fraction, positive=True),
                        t.number("rate", default=d.rate, positive=True))
    if config.limit_fraction > 1.0:
        raise t.error("limit_fraction", f"{config.limit_fraction:g}: a fraction of each limit, at most 1")
    return config


def _series(coef: np.ndarray, q0: np.ndarray, wf: float, t: np.ndarray):
    """q, q', q'' of the Fourier series, coef (n, L, 2), at times t."""
    n, L, _ = coef.shape
    q, qd, qdd = np.tile(q0, (len(t), 1)), np.zeros((len(t), n)), np.zeros((len(t), n))
    for l in range(1, L + 1):
        w = l * wf
        s, c = np.sin(w * t)[:, None], np.cos(w * t)[:, None]
        a, b = coef[:, l - 1, 0], coef[:, l - 1, 1]
        q += a / w * s - b / w * c
        qd += a * c + b * s
        qdd += -a * w * s + b * w * c
    return q, qd, qdd


def at_rest(free: np.ndarray) -> np.ndarray:
    """(n, L, 2) coefficients from the free ones (n, L - 1, 2): the last harmonic's make
    sum_l a_l = 0 and sum_l l b_l = 0, so q' and q'' vanish at t = 0 and at every period."""
    L = free.shape[1] + 1
    a_last = -free[:, :, 0].sum(axis=1)
    b_last = -(free[:, :, 1] * np.arange(1, L)).sum(axis=1) / L
    return np.concatenate([free, np.stack([a_last, b_last], axis=-1)[:, None, :]], axis=1)


def condition_number(pm, q, qd, qdd, base) -> float:
    """Of the column-scaled regressor of the (structural) base parameters along the trajectory."""
    W1 = regressor(pm, q, qd, qdd, base.with_friction)[:, base.independent]
    return equilibrated_condition_number(W1)


def _criterion(pm, q, qd, qdd, base, criterion: str) -> float:
    W1 = regressor(pm, q, qd, qdd, base.with_friction)[:, base.independent]
    sv = equilibrated_singular_values(W1)
    if criterion == "condition":
        return float(np.log(condition(sv)))
    return float(-np.mean(np.log(sv**2)))  # -log det(W^T W) / p of the scaled regressor


@dataclasses.dataclass(frozen=True)
class Limits:
    """Per joint: position range, velocity, acceleration, effort (inf where there is none)."""

    lower: np.ndarray
    upper: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    effort: np.ndarray

    def describe(self, joints: list[str]) -> dict:
        def f(x: float) -> float | None:
            return float(x) if np.isfinite(x) else None

        return {j: {"position": [f(self.lower[k]), f(self.upper[k])], "velocity": f(self.velocity[k]),
                    "acceleration": f(self.acceleration[k]), "effort": f(self.effort[k])}
                for k, j in enumerate(joints)}


def robot_limits(spec, acceleration: float | None) -> Limits:
    n = len(spec.joints)
    pos = np.array([(spec.limits or {}).get(j.name, (-np.pi, np.pi)) for j in spec.joints], dtype=float)
    pos = np.clip(pos, -np.pi, np.pi)  # a continuous joint: one turn about zero
    drive = spec.drive_limits or {}
    vel = np.array([drive.get(j.name, {}).get("velocity", np.inf) for j in spec.joints])
    eff = np.array([drive.get(j.name, {}).get("effort", np.inf) for j in spec.joints])
    acc = np.full(n, np.inf if acceleration is None else acceleration)
    return Limits(pos[:, 0], pos[:, 1], vel, acc, eff)


def usage(pm, spec, lim: Limits, q, qd, qdd) -> dict[str, float]:
    """The largest fraction of each kind of limit the trajectory uses (0 where there is none)."""
    half = (lim.upper - lim.lower) / 2
    mid = (lim.upper + lim.lower) / 2
    tau = joint_torques(pm, q, qd, qdd)  # with the drives' friction and rotor inertia
    with np.errstate(divide="ignore", invalid="ignore"):
        return {"position": float(np.max(np.abs(q - mid) / half)),
                "velocity": float(np.max(np.nan_to_num(np.abs(qd) / lim.velocity))),
                "acceleration": float(np.max(np.nan_to_num(np.abs(qdd) / lim.acceleration))),
                "torque": float(np.max(np.nan_to_num(np.abs(tau) / lim.effort)))}


def optimise(scenario: Any, excitation: Excitation, with_friction: bool) -> tuple[Any, dict]:
    """The scenario (a harness.runner.scenario.Scenario: its robot and gravity are read) with its
    motion replaced by the optimised excitation, and the optimisation's report. `with_friction`: the
    regressor has each joint's friction and rotor-inertia columns, as the fit it prepares will."""
    harmonics, base_frequency, evaluations = excitation.harmonics, excitation.base_frequency, excitation.evaluations
    criterion, limit_fraction = excitation.criterion, excitation.limit_fraction
    spec = scenario.robot
    pm = build_model(spec, scenario.gravity_W)
    base = structural_base(pm, spec.limits, with_friction=with_friction)  # chosen once
    n = len(spec.joints)
    lim = robot_limits(spec, excitation.acceleration_limit)
    q0, half = (lim.lower + lim.upper) / 2, (lim.upper - lim.lower) / 2
    period = 2 * np.pi / base_frequency
    t = np.linspace(0.0, period, SAMPLES, endpoint=False)
    dense = np.linspace(0.0, period, DENSE + 1)
    scale = 0.3 * half[:, None, None] * base_frequency  # amplitude of each coefficient's start

    def coefficients(x: np.ndarray) -> np.ndarray:
        return at_rest(x.reshape(n, harmonics - 1, 2))

    def cost(x):
        q, qd, qdd = _series(coefficients(x), q0, base_frequency, t)
        used = usage(pm, spec, lim, q, qd, qdd)
        excess = sum(max(0.0, u - limit_fraction) ** 2 for u in used.values())
        return _criterion(pm, q, qd, qdd, base, criterion) + PENALTY * excess

    rng = np.random.default_rng(excitation.seed)
    x0 = (rng.uniform(-1, 1, (n, harmonics - 1, 2)) * scale).ravel()
    start = float(np.exp(_criterion(pm, *_series(coefficients(x0), q0, base_frequency, t), base, "condition")))
    from scipy.optimize import minimize

    res = minimize(cost, x0, method="Powell", options={"maxfev": evaluations, "xtol": 1e-4, "ftol": 1e-6})
    coef = coefficients(res.x)
    # the limits hold on the dense grid, or the amplitude shrinks until they do
    shrink = 1.0
    used = usage(pm, spec, lim, *_series(coef, q0, base_frequency, dense))
    if max(used.values()) > 1.0:
        lo, hi = 0.0, 1.0
        for _ in range(40):
            mid = (lo + hi) / 2
            ok = max(usage(pm, spec, lim, *_series(coef * mid, q0, base_frequency, dense)).values()) <= 1.0
            lo, hi = (mid, hi) if ok else (lo, mid)
        if lo == 0.0:
            raise InputError(scenario.source, "excitation", "no trajectory holds the limits: even at rest the "
                                                            "torques exceed an effort limit")
        shrink, coef = lo, coef * lo
        used = usage(pm, spec, lim, *_series(coef, q0, base_frequency, dense))
    q, qd, qdd = _series(coef, q0, base_frequency, t)
    final = condition_number(pm, q, qd, qdd, base)
    motion = {}
    for k, joint in enumerate(spec.joints):
        sin = tuple((float(coef[k, l, 0] / ((l + 1) * base_frequency)), (l + 1) * base_frequency)
                    for l in range(harmonics))
        cos = tuple((float(-coef[k, l, 1] / ((l + 1) * base_frequency)), (l + 1) * base_frequency)
                    for l in range(harmonics))
        motion[joint.name] = Sinusoids(float(q0[k]), sin, cos)
    report = {"harmonics": harmonics, "base_frequency": base_frequency, "period": period,
              "evaluations": int(res.nfev), "criterion": criterion,
              "initial_condition_number": start, "optimised_condition_number": final,
              "condition_number_ratio": final / start,
              "objective": f"{criterion} of the column-scaled base regressor over one period ({SAMPLES} samples), "
                           f"every limit within {limit_fraction:g} of itself; at rest at both ends",
              "limits": lim.describe(spec.joint_names), "limit_fraction": limit_fraction,
              "largest_fraction_of_limits": used, "dense_samples": DENSE, "amplitude_shrunk_by": shrink,
              "rate": excitation.rate}
    return dataclasses.replace(scenario, motion=motion), report


def trajectory(scenario: Any, excitation: Excitation) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """t, q, q', q'' of the scenario's (optimised) motion over one period of the excitation's base
    frequency, sampled at its `rate`, both ends included: what a robot's controller plays."""
    period, rate = excitation.period, excitation.rate
    t = np.arange(int(np.floor(period * rate + 1e-9)) + 1) / rate
    t = np.append(t, period) if t[-1] < period - 1e-12 else t
    out = [m.evaluate(t) for m in scenario.motion.values()]
    return t, *(np.column_stack([o[k] for o in out]) for k in range(3))
