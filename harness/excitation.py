"""Exciting trajectories: a finite Fourier series per joint, optimised for the joint-torque
regressor's condition number.

    q_j(t) = q0_j + sum_{l=1..L} a_jl / (l w_f) sin(l w_f t) - b_jl / (l w_f) cos(l w_f t)

(the periodic form usual in robot identification), with q0_j the middle of the joint's range.
The objective is the condition number of the column-scaled base regressor (harness/torque_id.py)
at samples over one period, plus a penalty where a joint leaves its limits. Powell's method from a
seeded random start makes the result the same on every run. The optimised series becomes the
scenario's motion; the report gives the condition number before and after.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.optimize import minimize

from harness.engines.pinocchio import build_model
from harness.motion import Sinusoids
from harness.scenario import Scenario
from harness.torque_id import regressor, structural_base

SAMPLES = 60  # regressor samples over one period


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


def condition_number(pm, q, qd, qdd, base) -> float:
    """Of the column-scaled regressor of the (structural) base parameters along the trajectory."""
    W1 = regressor(pm, q, qd, qdd)[:, base.independent]
    sv = np.linalg.svd(W1 / np.linalg.norm(W1, axis=0), compute_uv=False)
    return float(sv[0] / sv[-1])


def optimise(scenario: Scenario, harmonics: int, base_frequency: float, evaluations: int, seed: int
             ) -> tuple[Scenario, dict]:
    spec = scenario.robot
    pm = build_model(spec, scenario.gravity_W)
    base = structural_base(pm, spec.limits)  # chosen once, not at every evaluation
    n = len(spec.joints)
    limits = np.array([(spec.limits or {}).get(j.name, (-np.pi, np.pi)) for j in spec.joints], dtype=float)
    limits = np.clip(limits, -np.pi, np.pi)
    q0, half = limits.mean(axis=1), (limits[:, 1] - limits[:, 0]) / 2
    t = np.linspace(0.0, 2 * np.pi / base_frequency, SAMPLES, endpoint=False)
    scale = 0.3 * half[:, None, None] * base_frequency  # amplitude of each coefficient's start

    def cost(x):
        coef = x.reshape(n, harmonics, 2)
        q, qd, qdd = _series(coef, q0, base_frequency, t)
        excess = np.maximum(0, np.abs(q - q0) - 0.9 * half)
        return np.log(condition_number(pm, q, qd, qdd, base)) + 1e3 * np.sum(excess**2)

    rng = np.random.default_rng(seed)
    x0 = (rng.uniform(-1, 1, (n, harmonics, 2)) * scale).ravel()
    start = float(np.exp(cost(x0)))
    res = minimize(cost, x0, method="Powell", options={"maxfev": evaluations, "xtol": 1e-4, "ftol": 1e-6})
    coef = res.x.reshape(n, harmonics, 2)
    final = float(np.exp(cost(res.x)))
    motion = {}
    for k, joint in enumerate(spec.joints):
        sin = tuple((float(coef[k, l, 0] / ((l + 1) * base_frequency)), (l + 1) * base_frequency)
                    for l in range(harmonics))
        cos = tuple((float(-coef[k, l, 1] / ((l + 1) * base_frequency)), (l + 1) * base_frequency)
                    for l in range(harmonics))
        motion[joint.name] = Sinusoids(float(q0[k]), sin, cos)
    report = {"harmonics": harmonics, "base_frequency": base_frequency, "evaluations": int(res.nfev),
              "initial_condition_number": start, "optimised_condition_number": final,
              "condition_number_ratio": final / start,
              "objective": "condition number of the column-scaled base regressor over one period "
                           f"({SAMPLES} samples), joints within 90 % of their half range"}
    return dataclasses.replace(scenario, motion=motion), report
