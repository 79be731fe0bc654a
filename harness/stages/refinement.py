"""Refinement by simulation of a log's consistent fit (harness/identify/refine.py), asked for by a
`[refinement]` table in a `[data]` scenario:

    [refinement]
    adjust = ["coulomb_velocity", "delay"]   # and/or "stribeck_velocity"
    horizon = 0.1                            # s: each rollout of the objective
    starts = 20                              # rollouts from measured states of the training span
    sample = 0.005                           # s: how often a rollout is compared with the log
    iterations = 10                          # evaluations of the objective in one pass
    passes = 2                               # the adjustment and the linear fit at its result, alternated

It runs after the identification methods, so that its rollouts and seconds stand beside those of
any method that reports its own (MuJoCo's sysid, harness/adapters/mujoco_sysid.py). The refined
model is judged on the validation span as the consistent fit is: held-out torque error, and
forward simulation from the same measured states over the same horizons.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from harness.base.numerics import sample_step
from harness.base.plugins import Stage
from harness.engines.pinocchio import build_model, joint_torques
from harness.identify import delay as channel_delay
from harness.identify.consistent import fit_with_laws
from harness.identify.laws import Law, extra_regressor, extra_terms
from harness.identify.refine import (
    ADJUSTABLE,
    TORQUE_SLACK,
    RefineConfig,
    Refinement,
    judge,
    refine,
    torque_rel_error,
)
from harness.identify.torque_id import regressor
from harness.model.export import identified_spec
from harness.model.friction import NO_FRICTION, JointFriction
from harness.model.friction import values as friction_values
from harness.stages.log_judge import prediction


@dataclass(frozen=True, eq=False)
class Candidate:
    """A model the refinement made: its links (n, 10), its law and its channels' delays, and how it
    does on the training span (the RMS of the refinement's residual; its torque error)."""

    label: str
    theta: np.ndarray
    frictions: tuple[JointFriction, ...]
    laws: tuple[Law, ...]
    delay: np.ndarray
    cost: float
    torque_rel_error: float


@dataclass(frozen=True, eq=False)
class RefinementResult:
    passes: tuple[Refinement, ...]
    candidates: tuple[Candidate, ...]  # the consistent fit first
    chosen: int  # index into candidates: the refined model (0: the consistent fit stands)
    reason: str
    note: str | None  # why nothing was refined
    validation: dict  # the refined model and the consistent fit on the validation span
    beside: dict  # method -> its rollouts and seconds, for the methods that report rollouts
    seconds: float

    def serialise(self, ctx, config: RefineConfig) -> dict:
        """results.json's `refinement`."""
        out = {"definition": "the consistent fit's smoothing and Stribeck velocities and its torque channels' "
                             "delays adjusted so that MuJoCo, driven by the measured torques from measured states "
                             "of the training span, best reproduces the measured motion, the links held and the "
                             "drive's coefficients re-solved by bounded least squares for each candidate; then the "
                             "consistent fit re-solved at the adjusted velocities and delays"
                             + (f", the two alternating {config.passes} times" if config.passes > 1 else "")
                             + " (harness/identify/refine.py). The model kept is the candidate "
                             "that predicts the training span best among those that fit its torques within "
                             f"{TORQUE_SLACK:.0%} of the consistent fit",
               "adjust": list(config.adjust), "horizon_s": config.horizon, "sample_s": config.sample,
               "starts": config.starts, "iterations": config.iterations, "passes_asked": config.passes}
        if not self.passes:
            return {**out, "note": self.note}
        chosen, first = self.candidates[self.chosen], self.passes[0]
        return {**out, "accepted": self.chosen > 0, "kept": chosen.label, "reason": self.reason,
                "parameters": {name: {"consistent": float(a), "refined": b} for name, a, b in
                               zip(first.names, first.initial, values(first.slots, chosen), strict=True)},
                "candidates": {c.label: {"prediction_cost": c.cost, "torque_rel_error": c.torque_rel_error}
                               for c in self.candidates},
                "training": {"prediction_cost": {"consistent": self.candidates[0].cost, "refined": chosen.cost},
                             "torque_rel_error": {"consistent": self.candidates[0].torque_rel_error,
                                                  "refined": chosen.torque_rel_error}},
                "validation": self.validation,
                "passes": [{"rollouts": r.rollouts, "steps": r.steps, "evaluations": r.evaluations,
                            "seconds": r.seconds, "optimiser": r.message} for r in self.passes],
                "rollouts": sum(r.rollouts for r in self.passes), "steps": sum(r.steps for r in self.passes),
                "seconds": self.seconds, "beside": self.beside}


def choose(candidates: list[Candidate]) -> tuple[int, str]:
    """The candidate kept: the one that predicts the training span best (lowest cost) among those whose
    training torque error is within TORQUE_SLACK of the first's (the consistent fit's), and why."""
    bound = candidates[0].torque_rel_error * (1 + TORQUE_SLACK)
    fits = [i for i, c in enumerate(candidates) if c.torque_rel_error <= bound]
    chosen = min(fits, key=lambda i: (candidates[i].cost, i))
    if chosen == 0:
        return 0, ("no candidate predicts the training span better than the consistent fit and fits its torques "
                   f"within {TORQUE_SLACK:.0%} as well")
    return chosen, (f"'{candidates[chosen].label}' predicts the training span best among the candidates that fit its "
                    f"torques within {TORQUE_SLACK:.0%} of the consistent fit")


def values(slots: tuple[tuple[int, str], ...], c: Candidate) -> list[float]:
    """The adjusted quantities' values in a candidate, slot by slot (joint index, key)."""
    return [float(c.delay[k]) if key == "delay" else float(getattr(c.frictions[k], key)) for k, key in slots]


def _beside(ctx) -> dict:
    methods = ctx.done.get("identification_methods")
    return {} if methods is None else {
        m.name: {"plugin": m.plugin, "rollouts": m.rollouts, "seconds": m.seconds}
        for m in methods.methods if getattr(m, "rollouts", None) is not None}


def _rigid(spec, gravity_W, q, qd, qdd) -> np.ndarray:
    """(N, n): the rigid-body torque of a model's links (its drives left out)."""
    return joint_torques(build_model(spec.with_frictions((NO_FRICTION,) * len(spec.joints)), gravity_W), q, qd, qdd)


def _refit(ctx, li, r: Refinement, laws: tuple[Law, ...], rigid: np.ndarray, q, qd, qdd, tau, t):
    """The consistent fit (harness/identify/consistent.py, fit_with_laws) again, at the velocities and delays of
    pass r: the laws with its velocities, the torques read its delays later (rows whose reading would
    cross an end or a gap left out)."""
    sc = ctx.scenario
    robot = sc.robot
    laws = tuple(law.at_velocities_of(f) for law, f in zip(laws, r.frictions, strict=True))
    shaped = robot.with_frictions(tuple(law.shaping(f) for f, law in zip(robot.frictions, laws, strict=True)))
    later, keep = channel_delay.shifted(t, tau, r.delay, sample_step(t))
    W = regressor(build_model(shaped, li.gravity.gravity_W), q[keep], qd[keep], qdd[keep], with_friction=True)
    E = extra_regressor(laws, qd[keep], rigid[keep], robot.transmission, q=q[keep])
    extra_model = np.array([getattr(robot.frictions[k], key) for k, key in extra_terms(laws)])
    fit, frictions = fit_with_laws(W, E, later[keep], laws, li.model.theta, friction_values(robot.frictions),
                                   extra_model, robot.transmission)
    return fit.theta, frictions, laws


def _judged(ctx, li, chosen: Candidate, identified, refined, largest: float) -> dict:
    """The refined model against the consistent fit on the validation span (the training span when
    the log has none): torque error on the same rows, and forward simulation."""
    sc, joints = ctx.scenario, li.joints
    judged = li.judged
    span = "validation" if "validation" in judged.states else "training"
    q, qd, qdd = judged.states[span]
    tau, t = judged.measured[span], judged.t[span]
    torque = {name: torque_rel_error(t, qd, qdd, tau, _rigid(spec, li.gravity.gravity_W, q, qd, qdd), spec.frictions,
                                     laws, lag, largest, spec.transmission, q)
              for name, spec, laws, lag in (("consistent", identified, li.laws.laws, np.zeros(len(joints))),
                                            ("refined", refined, chosen.laws, chosen.delay))}
    simulated = prediction(li.gravity.gravity_W, {"consistent": identified, "refined": refined}, t, q, qd, tau, span,
                           joints, {"refined": chosen.delay}, plan=sc.data.prediction)
    return {"span": span, "torque_rel_error": torque,
            "torque_rel_error_change": torque["refined"] - torque["consistent"], "prediction": simulated}


def run(ctx, config: RefineConfig | None) -> RefinementResult | None:
    li = ctx.done.get("log_identification")
    if config is None or li is None:
        return None
    started = time.perf_counter()
    sc = ctx.scenario
    robot, n = sc.robot, len(li.joints)
    t, (q, qd, qdd), tau = li.judged.t["training"], li.judged.states["training"], li.judged.measured["training"]
    identified = identified_spec(robot, li.fit.theta, li.frictions)
    rigid = _rigid(identified, li.gravity.gravity_W, q, qd, qdd)
    spec, theta, frictions, laws, lag = identified, li.fit.theta, li.frictions, li.laws.laws, np.zeros(n)
    passes, candidates = [], []
    for k in range(config.passes):
        ctx.progress(f"refinement by forward simulation, pass {k + 1} of {config.passes} (MuJoCo rollouts)", None)
        try:
            r = refine(spec, li.gravity.gravity_W, t, q, qd, qdd, tau, rigid, laws, config, lag)
        except ValueError as exc:
            if not passes:
                return RefinementResult((), (), 0, "", f"nothing refined: {exc}", {}, _beside(ctx),
                                        time.perf_counter() - started)
            break
        passes.append(r)
        if not candidates:
            candidates.append(Candidate("consistent", theta, frictions, laws, lag, r.cost["start"],
                                        r.torque_rel_error["start"]))
        candidates.append(Candidate(f"pass {k + 1}: links held", theta, r.frictions, laws, r.delay, r.cost["refined"],
                                    r.torque_rel_error["refined"]))
        theta, frictions, laws = _refit(ctx, li, r, laws, rigid, q, qd, qdd, tau, t)
        lag = r.delay
        spec = identified_spec(robot, theta, frictions)
        rigid = _rigid(spec, li.gravity.gravity_W, q, qd, qdd)
        cost, torque = judge(spec, li.gravity.gravity_W, t, q, qd, qdd, tau, rigid, laws, lag, config)
        candidates.append(Candidate(f"pass {k + 1}: refitted", theta, frictions, laws, lag, cost, torque))
    chosen, reason = choose(candidates)
    c = candidates[chosen]
    refined = identified_spec(robot, c.theta, c.frictions)
    return RefinementResult(tuple(passes), tuple(candidates), chosen, reason, None,
                            _judged(ctx, li, c, identified, refined, config.reach), _beside(ctx),
                            time.perf_counter() - started)


def configure(t, scenario) -> RefineConfig:
    """`[refinement]`, validated (one-line errors naming the key). Only a `[data]` scenario reads it
    (runner/scenario.py refuses the table elsewhere, stages.LOG_TABLES)."""
    d = RefineConfig()
    config = RefineConfig(tuple(t.strings("adjust", choices=ADJUSTABLE, default=list(d.adjust))),
                          t.number("horizon", default=d.horizon, positive=True),
                          t.integer("starts", default=d.starts, minimum=1),
                          t.number("sample", default=d.sample, positive=True),
                          t.integer("iterations", default=d.iterations, minimum=1),
                          t.integer("passes", default=d.passes, minimum=1))
    if config.sample > config.horizon:
        raise t.error("sample", f"{config.sample:g} s is longer than the horizon ({config.horizon:g} s)")
    if config.horizon > 2.0:
        raise t.error("horizon", f"{config.horizon:g} s: a torque-driven rollout drifts away from a log within a "
                                 "second; at most 2 s")
    return config


STAGE = Stage("refinement", "refinement by forward simulation", run, RefinementResult.serialise,
              "Refinement by simulation", table="refinement", configure=configure)
