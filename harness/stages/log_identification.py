"""Identification from a measured joint log (harness/sources/log.py): the pipeline proven on the bench,
on data whose truth nobody knows, judged on a part of the log the fit never saw.

1. Least squares of the structural base parameters with each joint's friction and rotor
   inertia (harness/identify/torque_id.py), with standard deviations and weakly identifiable parameters.
2. The physically consistent fit of all parameters (harness/identify/consistent.py), closest to the
   model's own values where the data cannot tell.
3. Both, and the model as it was given (its URDF with its own friction), predict the torques of
   the validation span: per joint RMS and relative error, and over all joints
   ||tau_pred - tau||_F / ||tau||_F (the figure published identifications quote).
4. The consistent model is exported (harness/model/export.py).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from harness.base.numerics import PARAMETER_FLOOR, evenly_spaced, finite_or_null, parameter_scale, relative_error
from harness.base.plugins import Stage
from harness.engines.mujoco import mjcf
from harness.engines.pinocchio import build_model, rnea
from harness.identify import consistent, delay, friction_law
from harness.identify.friction_law import FrictionLawConfig, Law, extra_regressor, extra_terms
from harness.identify.repeat import Repeatability, repeat
from harness.identify.torque_id import (
    BaseFit,
    BaseParameters,
    describe_base,
    fit_base,
    links_torque,
    parameter_names,
    regressor,
    structural_base,
    true_parameters,
    with_structure,
)
from harness.model.export import MJCF_FILE, README_FILE, coulomb_mapping, export, identified_spec, readme
from harness.model.friction import FAMILIES, JointFriction
from harness.model.friction import values as friction_values
from harness.model.inertia import PARAMETER_NAMES, model_kind_scales
from harness.model.mjcf import compiler_message
from harness.sources.log import JointLog, room
from harness.stages.identification import joint_data
from harness.stages.metrics import torque_errors

FLOOR_DEFINITION = (
    "the least-squares fit's columns (the same base parameters, friction laws and families) fitted on the "
    "validation span itself, its error there: what no fit of this model class can beat on that span, read "
    "for this figure alone. A held-out error near it is the model class's limit, not the fit's")


@dataclass(frozen=True, eq=False)
class LogIdentification:
    joints: list[str]
    names: list[str]  # all parameters: 10 per link, then 4 per joint
    base: BaseParameters
    beta_model: np.ndarray  # the model's own base parameters
    ls: BaseFit  # least squares
    fit: consistent.ConsistentFit
    theta_model: np.ndarray  # (n, 10)
    friction_model: np.ndarray  # (n, 4)
    predictions: dict[str, dict[str, np.ndarray]]  # span -> model -> (N, n) torques
    measured: dict[str, np.ndarray]  # span -> (N, n) torques
    t: dict[str, np.ndarray]  # span -> times
    files: dict[str, str]  # the export
    mjcf_friction: dict[str, dict[str, float]]  # per joint, what MuJoCo's dry friction changes (export.coulomb_mapping)
    mjcf_refused: str | None = None  # why robot.xml was not written, if it was not
    plausible: dict = field(default_factory=dict)  # `plausibility`
    warnings: list[str] = field(default_factory=list)  # what the terminal is told
    truth: dict[str, np.ndarray] = field(default_factory=dict)  # span -> the truth's torques, where it is known
    delays: dict = field(default_factory=dict)  # results.json's `delays` (_delay_section)
    torque_constants: dict | None = None  # results.json's `torque_constants` (_constants_section), for currents
    repeated: Repeatability | None = None  # the fit on disjoint segments of the training span
    prediction: dict = field(default_factory=dict)  # results.json's `prediction` (`prediction`)
    frictions: tuple = ()  # each joint's identified friction law (harness/model/friction.py JointFriction)
    choice: friction_law.FrictionChoice | None = None  # how each joint's law was chosen, if it was
    extra_names: list[str] = field(default_factory=list)  # the families' coefficients after the base parameters
    laws: tuple = ()  # each joint's law (harness/identify/friction_law.py Law): family and velocities
    states: dict[str, tuple] = field(default_factory=dict)  # span -> (q, q', q''), as the fit read them
    floor: float | None = None  # the least-squares columns fitted on the validation span itself: its error there

    def _against_truth(self, ctx) -> dict:
        errors = {span: _truth_errors(self, span) for span in self.truth}
        headline = errors.get("validation", errors["training"])
        return {"model": str(ctx.scenario.truth.source),
                "definition": "||tau - tau_truth||_F / ||tau_truth||_F, tau_truth the torques of the model that made "
                              "the log at the conditioned states (its inverse dynamics with its friction): each "
                              "model's error against the robot, and the measured torques' (the sensor's and the "
                              "conditioning's)",
                "validation_rel_error": {m: e["rel_error"] for m, e in headline.items()}, "errors": errors}

    def serialise(self, ctx, config) -> dict:
        """results.json's `log_identification`: the fits, their errors per span, the consistent model and the export."""
        from harness.base.numerics import finite_or_null
        from harness.identify.consistent import consistency

        n = len(self.joints)
        ls = self.ls
        rel = relative_error(ls.beta, self.beta_model, parameter_scale(self.beta_model))

        def expression(k: int) -> str:
            r = len(self.base.independent)
            return describe_base(self.names, self.base, k) if k < r else self.extra_names[k - r]

        errors = {span: _span_errors(self, span) for span in self.predictions}
        headline = errors.get("validation", errors["training"])
        links = {}
        for k, j in enumerate(self.joints):
            links[j] = {"identified": dict(zip(PARAMETER_NAMES, map(float, self.fit.theta[k]), strict=True)),
                        "model": dict(zip(PARAMETER_NAMES, map(float, self.theta_model[k]), strict=True)),
                        **{f"{key}": value for key, value in consistency(self.fit.theta[k]).items()}}
        return {
            "method": "least squares of the structural base parameters with friction and rotor inertia, then all "
                      "parameters under the pseudo-inertia LMI (harness/identify/consistent.py: Clarabel, else SCS, "
                      "else the unconstrained fit moved to the nearest physical one; consistent.fallback says which)",
            "friction_law": _law_section(self),
            "rel_error_definition": ("||tau_predicted - tau_measured||_F / ||tau_measured||_F over every sample and "
                                     "joint of the span; per joint the same over its samples, and the RMS error in "
                                     "N m"),
            "spans": {span: {"samples": len(t), "t_start": float(t[0]), "t_end": float(t[-1])}
                      for span, t in self.t.items()},
            "errors": errors,
            "validation_rel_error": {m: e["rel_error"] for m, e in headline.items()},
            "validation_floor": None if self.floor is None else {
                "definition": FLOOR_DEFINITION, "rel_error": self.floor},
            "consistent_costs": {span: e["consistent"]["rel_error"] - e["least squares"]["rel_error"]
                                 for span, e in errors.items()},
            "least_squares": {
                "base_parameters": len(ls.beta), "parameters": len(self.names), "condition_number": ls.condition_number,
                "weakly_identifiable": [expression(k) for k in np.flatnonzero(ls.weak)],
                "base": [{"expression": expression(k), "model": float(self.beta_model[k]),
                          "identified": float(ls.beta[k]),
                          "std": finite_or_null(ls.std[k]),
                          "rel_std_percent": finite_or_null(100 * ls.std[k] / abs(ls.beta[k])) if ls.beta[k] else None,
                          "ci95": [finite_or_null(ls.beta[k] - ls.ci_half_width[k]),
                                   finite_or_null(ls.beta[k] + ls.ci_half_width[k])],
                          "change_from_model": float(rel[k]), "sensitivity": finite_or_null(ls.sensitivity[k]),
                          "weakly_identifiable": bool(ls.weak[k])} for k in range(len(ls.beta))],
            },
            **({"truth": self._against_truth(ctx)} if self.truth else {}),
            "prediction": self.prediction,
            "delays": self.delays,
            "torque_constants": self.torque_constants,
            "repeatability": None if self.repeated is None else {
                "definition": "the base parameters fitted on each of `segments` consecutive, disjoint parts of the "
                              "training span: per parameter the coefficient of variation over the parts, and whether "
                              "their 95 % intervals share a common point; `moved` lists those whose intervals do not "
                              "(harness/identify/repeat.py)",
                "segments": self.repeated.segments,
                "max_variation": finite_or_null(float(np.max(self.repeated.variation))),
                "median_variation": finite_or_null(float(np.median(self.repeated.variation))),
                "moved_count": int(np.sum(~self.repeated.overlap)),
                "moved": [expression(k) for k in np.flatnonzero(~self.repeated.overlap)],
                "per_parameter": [{"expression": expression(k), "mean": float(self.repeated.mean[k]),
                                   "spread": float(self.repeated.spread[k]),
                                   "variation": finite_or_null(float(self.repeated.variation[k])),
                                   "intervals_overlap": bool(self.repeated.overlap[k])}
                                  for k in range(self.repeated.beta.shape[1])]},
            "plausibility": self.plausible,
            "warnings": self.warnings,
            "consistent": {
                "solver": self.fit.solver,
                "solver_status": self.fit.status,
                "fallback": self.fit.fallback,
                "fallback_definition": "; ".join(f"{k} {text}" for k, text in enumerate(consistent.FALLBACKS)),
                "solver_attempts": list(self.fit.attempts),
                "training_rel_residual": self.fit.relative_residual,
                "inconsistent_links": sum(not v["consistent"] for v in links.values()),
                "links": links,
                "friction": {j: {"family": f.family, **f.as_dict()}
                             for j, f in zip(self.joints, self.frictions, strict=True)},
            },
            "export": sorted(self.files),
            "export_mjcf_friction": {
                "definition": "what robot.xml's frictionloss (MuJoCo's dry friction, a sharp sign) and its missing "
                              "offset change of the identified friction law at the training span's velocities: the "
                              "RMS change over the RMS torque, the largest over the largest torque, per joint",
                **self.mjcf_friction},
            "export_mjcf_not_written": self.mjcf_refused,
            "joints": n,
            "series": _series(self),
        }


def _law_section(li: LogIdentification) -> dict:
    """results.json's `friction_law`: the law, and per joint the family and velocities chosen with
    every family's held-out figure (harness/identify/friction_law.py)."""
    out = {"law": "I_a q'' + f_v q' + f_c s + f_o, s = tanh(q'/v_c) (sign where v_c = 0), and per joint its "
                  "family's terms: asymmetric f_va |q'| + f_ca |s|, Stribeck f_s s exp(-(q'/v_s)^2), load f_l "
                  "|tau_R| s (harness/model/friction.py)",
           "chosen": li.choice is not None,
           "families": {j: law.family for j, law in zip(li.joints, li.laws, strict=True)},
           "coulomb_velocity": {j: f.coulomb_velocity for j, f in zip(li.joints, li.frictions, strict=True)}}
    c = li.choice
    if c is None:
        out["definition"] = "The model's own law per joint ([friction_law] choose = false, or see warnings)"
        return out
    out |= {
        "definition": (f"The training span cut into {c.folds} consecutive parts, each predicted by the base "
                       "parameters fitted on the others (the validation span is never seen); the held-out error "
                       "||tau_pred - tau||_F / ||tau||_F over the training span. Joint by joint (two passes), v_c "
                       f"searched for every family ({', '.join(FAMILIES)}) over a logarithmic grid "
                       f"{friction_law.VELOCITY_GRID[0]:g} to {friction_law.VELOCITY_GRID[-1]:g} and a sharp "
                       "sign, then refined; the simplest family within one standard error (over the parts) of the best "
                       "chosen (harness/identify/friction_law.py)"),
        "folds": c.folds,
        "held_out_rel_error": {"model's law": c.model_error, "chosen": c.chosen_error},
        "per_joint": {j: c.scores[k] for k, j in enumerate(li.joints)},
    }
    return out


PLAUSIBLE = 3.0  # a link's identified mass or inertia more than 3 times, or under a third of, the model's: warned
ON_MARGIN = 1.01  # a link whose smallest pseudo-inertia eigenvalue is within 1 % of the fit's margin sits on it


def plausibility(theta: np.ndarray, theta_model: np.ndarray, joints: list[str], margin: float) -> dict:
    """Beside consistency, plausibility: per link (by its joint) the identified mass and the trace of
    the inertia about the centre of mass as ratios to the model's own; the links outside
    [1/PLAUSIBLE, PLAUSIBLE] on either; and the links on the fit's positive-definiteness margin
    (their smallest pseudo-inertia eigenvalue within ON_MARGIN of it), which the data pushed there."""
    from harness.model.inertia import about_centre_of_mass, pseudo_inertia

    ratios, outside, on_margin = {}, [], []
    for k, j in enumerate(joints):
        m, m0 = float(theta[k][0]), float(theta_model[k][0])
        tr = float(np.trace(about_centre_of_mass(theta[k])[2])) if m > 0 else float("nan")
        tr0 = float(np.trace(about_centre_of_mass(theta_model[k])[2])) if m0 > 0 else float("nan")
        with np.errstate(divide="ignore", invalid="ignore"):
            r = {"mass": m / m0 if m0 > 0 else float("nan"), "inertia_trace": tr / tr0 if tr0 > 0 else float("nan")}
        ratios[j] = r
        if any(np.isfinite(v) and not 1 / PLAUSIBLE <= v <= PLAUSIBLE for v in r.values()):
            outside.append(j)
        if np.linalg.eigvalsh(pseudo_inertia(theta[k]))[0] <= ON_MARGIN * margin:
            on_margin.append(j)
    return {"definition": f"per link, identified / model: its mass and the trace of its inertia about the centre "
                          f"of mass; implausible outside [1/{PLAUSIBLE:g}, {PLAUSIBLE:g}]; on_margin: links whose "
                          f"smallest pseudo-inertia eigenvalue is within {ON_MARGIN:g} x the fit's margin",
            "band": [1 / PLAUSIBLE, PLAUSIBLE], "ratios": ratios, "implausible": outside,
            "implausible_links": len(outside), "on_margin": on_margin, "links_on_margin": len(on_margin)}


LAG_WARNING = 0.001  # s: an estimated delay beyond 1 ms, left uncorrected, is said on the terminal...
LAG_GAIN = 0.9  # ... where reading the torque that much later leaves at most 90 % of the residual at zero delay


def _found(lags) -> np.ndarray:
    """Per joint, whether the delay is found: inside the search, and the fit clearly better for it."""
    return ~lags.at_edge & (lags.residual <= LAG_GAIN * lags.residual_at_zero)


def _read_later(log: JointLog, lag: np.ndarray, joints: list[str]) -> JointLog:
    """The log with each joint's torque read `lag` later (harness/identify/delay.py), the rows where
    that falls across a gap or beyond an end dropped."""
    cols = [log.joint_index(j) for j in joints]
    step = float(np.median(np.diff(log.t)))
    tau, keep = delay.shifted(log.t, log.tau[:, cols], lag, step)
    out = log.tau.copy()
    out[:, cols] = tau
    return dataclasses.replace(log, tau=out).span(keep)


def _delay_section(lags, note: str | None, mode: str, joints: list[str]) -> dict:
    if lags is None:
        return {"mode": mode, "estimated": False, "note": note}
    return {"mode": mode, "estimated": True, "corrected": mode == "correct",
            "definition": "per joint, d such that the torque measured d later fits the joint's regressor rows best "
                          "(least squares, every parameter); positive: the torque channel lags the encoders "
                          "(harness/identify/delay.py)",
            "found_definition": f"inside the search, and the residual at the delay at most {LAG_GAIN:g} x the "
                                "residual at zero delay; only a found delay is corrected",
            "search_s": [float(lags.candidates[0]), float(lags.candidates[-1])],
            "per_joint": {j: {"delay_s": float(lags.delay[k]), "found": bool(_found(lags)[k]),
                              "residual": float(lags.residual[k]), "residual_at_zero": float(lags.residual_at_zero[k]),
                              "at_edge_of_search": bool(lags.at_edge[k])} for k, j in enumerate(joints)}}


def _torque_constants(sc, pm, base, W, tau, beta_model, joints):
    """Each joint's factor on its nominal torque constant (harness/identify/scale.py), fixed by the
    payload log where the scenario gives one, else by the model's own parameters."""
    from harness.identify.scale import payload_parameters, torque_scales
    from harness.sources.log import condition, read_raw

    if sc.data.payload is None:
        return torque_scales(W[:, base.independent], tau, beta_model)
    p = sc.data.payload
    loaded = condition(read_raw(sc.data, sc.robot, p.file), sc.data, sc.robot)
    q2, qd2, qdd2, tau2 = joint_data(loaded, joints)
    W2 = regressor(pm, q2, qd2, qdd2, with_friction=True)
    k = joints.index(sc.robot.inner_joint(p.body).name)
    theta_p = payload_parameters(p.mass, p.com_W, p.inertia, sc.robot.joints[k].p_W0)
    known = (W2[:, 10 * k: 10 * k + 10] @ theta_p).reshape(tau2.shape)
    return torque_scales(W[:, base.independent], tau, beta_model, W2[:, base.independent], tau2, known)


def _scaled(log: JointLog, factor: np.ndarray, joints: list[str]) -> JointLog:
    cols = [log.joint_index(j) for j in joints]
    tau = log.tau.copy()
    tau[:, cols] *= factor
    return dataclasses.replace(log, tau=tau)


def _constants_section(constants, source, joints: list[str]) -> dict | None:
    if constants is None:
        return None
    return {"definition": "per joint, the torque it carries over the torque its currents give with the nominal "
                          "constant (harness/identify/scale.py); identified = factor x nominal",
            "fixed_by": constants.fixed_by, "relative_residual": constants.relative_residual,
            "per_joint": {j: {"nominal": source.torque_constant[k], "factor": float(constants.factor[k]),
                              "identified": float(constants.factor[k] * source.torque_constant[k]),
                              "factor_std": None if constants.std is None else float(constants.std[k])}
                          for k, j in enumerate(joints)}}


HORIZONS = (0.02, 0.05, 0.1, 0.2)  # s: how far ahead a model is judged by forward simulation
PREDICTION_STARTS = 20  # starts spread evenly over the span


def _starts(t: np.ndarray, reach: float, count: int) -> np.ndarray:
    """Rows from which `reach` seconds lie within the same stretch of the span (no gap crossed)."""
    usable = np.flatnonzero(room(t)[1] >= reach)
    if not len(usable):
        return usable
    return usable[evenly_spaced(len(usable), count)]


def prediction(sc, models: dict, t: np.ndarray, q: np.ndarray, qd: np.ndarray, tau: np.ndarray, span: str,
               joints: list[str], delays: dict | None = None) -> dict:
    """Each model forward-simulated in MuJoCo from measured states of a span (t (N,), q, q', tau (N, n))
    under the measured torques (harness/engines/mujoco.py, predict), each channel read delays[model]
    (n,) s later where given: per horizon the RMS and largest position and velocity error."""
    from harness.engines.mujoco import PREDICTION_TIMESTEP, predict

    starts = _starts(t, HORIZONS[-1], PREDICTION_STARTS)
    out = {"definition": f"from {len(starts)} measured states along the {span} span, each model forward-simulated "
                         "in MuJoCo (RK4, 1 ms) under the measured joint torques less its dry friction (Coulomb, "
                         "offset and its family's terms); at each horizon q_sim - q_meas [rad or m] and "
                         "q'_sim - q'_meas: RMS over the starts and joints, the largest joint's RMS, per joint RMS. "
                         "The least-squares fit is not "
                         "simulated: its base parameters are not a full set of physical parameters",
           "span": span, "starts": len(starts), "timestep_s": PREDICTION_TIMESTEP,
           "horizons_s": list(HORIZONS), "models": {}}
    if not len(starts):
        out["note"] = f"no stretch of the {span} span is {HORIZONS[-1]:g} s long"
        return out
    for name, spec in models.items():
        q_err, qd_err = predict(spec, sc.gravity_W, t, q, qd, tau, starts, HORIZONS,
                                delay=(delays or {}).get(name))
        per = {}
        for h, horizon in enumerate(HORIZONS):
            e, ed = q_err[:, h], qd_err[:, h]
            diverged = int(np.sum(~np.all(np.isfinite(e), axis=1)))
            per[f"h{round(horizon * 1e3)}ms"] = {
                "q_rms": finite_or_null(float(np.sqrt(np.mean(e**2)))),
                "q_rms_largest_joint": finite_or_null(float(np.max(np.sqrt(np.mean(e**2, axis=0))))),
                "qd_rms": finite_or_null(float(np.sqrt(np.mean(ed**2)))),
                "q_rms_per_joint": {j: finite_or_null(float(np.sqrt(np.mean(e[:, k] ** 2))))
                                    for k, j in enumerate(joints)},
                "diverged": diverged}
        out["models"][name] = per
    return out


def consistent_fit(W: np.ndarray, E: np.ndarray, tau: np.ndarray, laws: tuple[Law, ...], theta_model: np.ndarray,
                   friction_model: np.ndarray, extra_model: np.ndarray) -> tuple[consistent.ConsistentFit,
                                                                                 tuple[JointFriction, ...]]:
    """The physically consistent fit (harness/identify/consistent.py) of the torques tau (N, n) on the
    regressor W (N n, 14 n: every link's ten parameters, every joint's four drive terms at its law's
    velocities) and the families' columns E (N n, e, extra_terms(laws)), pulled towards the model's
    own values (theta_model (n, 10), friction_model (n, 4), extra_model (e,)) where the data cannot
    tell; and each joint's identified friction law."""
    N, n = tau.shape
    terms = extra_terms(laws)
    W_all = np.hstack([W, E])
    # magnitudes for the pull towards the model: the inertial parameters' kinds in the model; a
    # friction term's, the value that alone would carry its joint's whole torque (rms over rms)
    rms_cols = np.sqrt(np.mean(W[:, 10 * n:].reshape(N, n, -1) ** 2, axis=0)).reshape(n, n, 4)
    cols = rms_cols[np.arange(n), np.arange(n)]  # joint j's own four columns, on its own rows
    rms_tau = np.sqrt(np.mean(tau**2, axis=0))
    carry = rms_tau[:, None] / np.where(cols > 0, cols, 1.0)
    friction_scale = np.maximum(np.abs(friction_model), carry)
    friction_scale = np.maximum(friction_scale, PARAMETER_FLOOR * friction_scale.max(axis=0, initial=0.0))  # a joint
    # that carries nothing has no size of its own
    extra_rms = np.sqrt(np.mean(E.reshape(N, n, -1) ** 2, axis=0))  # (n, e): each column's RMS on each joint's rows
    extra_scale = np.array([max(abs(extra_model[c]), rms_tau[k] / max(float(extra_rms[k, c]), 1e-300))
                            for c, (k, _) in enumerate(terms)])
    scale = np.concatenate([model_kind_scales(theta_model).ravel(), friction_scale.ravel(), extra_scale])
    fit = consistent.fit(W_all, tau.reshape(-1), theta_model, friction_model, scale, tuple(terms), extra_model)
    frictions = tuple(
        JointFriction(*map(float, fit.friction[k]), coulomb_velocity=law.coulomb_velocity,
                      stribeck_velocity=law.stribeck_velocity,
                      **{key: float(fit.extra[c]) for c, (kk, key) in enumerate(terms) if kk == k})
        for k, law in enumerate(laws))
    return fit, frictions


def run(ctx, config) -> LogIdentification | None:
    sc = ctx.scenario
    robot = sc.robot
    joints = robot.joint_names
    train: JointLog = ctx.measured
    validation: JointLog | None = ctx.validation
    pm = build_model(robot, sc.gravity_W)
    ctx.progress("structural base parameters (with friction and rotor inertia)", None)
    base = structural_base(pm, robot.limits, with_friction=True)
    q, qd, qdd, tau = joint_data(train, joints)
    W = regressor(pm, q, qd, qdd, with_friction=True)
    n = len(joints)
    lags, lag_note = None, None
    if sc.data.delay != "none":
        ctx.progress("the torque channels' delays behind the encoders", None)
        try:
            lags = delay.estimate(train.t, tau, W.reshape(len(q), n, -1))
        except ValueError as exc:
            lag_note = f"delays not estimated: {exc}"
    if lags is not None and sc.data.delay == "correct":  # the joints whose delay is found; the others as they are
        train, validation = (None if log is None else _read_later(log, np.where(_found(lags), lags.delay, 0.0), joints)
                             for log in (train, validation))
        q, qd, qdd, tau = joint_data(train, joints)
        W = regressor(pm, q, qd, qdd, with_friction=True)
    x_model = true_parameters(pm, with_friction=True)
    beta_model = base.of(x_model)
    # the base parameters that hold a link's inertia, and the drive's share in each (the model's own, where a
    # rotor inertia is regrouped with a link's): what a load-dependent law's rigid-body torque reads
    link_part = base.link_part(x_model, 10 * n)
    constants = None
    if sc.data.units["tau"] == "current" and sc.data.identify_constants:
        ctx.progress("torque constants (motor currents)", None)
        constants = _torque_constants(sc, pm, base, W, tau, beta_model, joints)
        train, validation = (None if log is None else _scaled(log, constants.factor, joints)
                             for log in (train, validation))
        q, qd, qdd, tau = joint_data(train, joints)
    law_config = config or FrictionLawConfig()
    theta_model = x_model[: 10 * n].reshape(n, 10)
    choice, law_note = None, None
    if law_config.choose:
        ctx.progress("the friction law of every joint (cross-validated within the training span)", None)
        try:
            choice = friction_law.choose(W, base.independent, link_part, tau, qd, train.t, robot.frictions,
                                         law_config)
        except ValueError as exc:
            law_note = f"friction law not chosen, the model's kept: {exc}"
    laws = choice.laws if choice is not None else tuple(Law.of(f) for f in robot.frictions)
    terms = extra_terms(laws)
    if choice is not None:  # the regressor with the chosen smoothing velocities
        W = regressor(build_model(robot.with_frictions(choice.frictions(robot.frictions)), sc.gravity_W),
                      q, qd, qdd, with_friction=True)
        rigid_train = choice.tau_rigid
    else:
        rigid_train = (W[:, : 10 * n] @ theta_model.ravel()).reshape(tau.shape)
    extra_model = np.array([getattr(robot.frictions[k], key) for k, key in terms])
    beta_model = np.concatenate([beta_model, extra_model])
    r = len(base.independent)
    W_ls = np.hstack([W[:, base.independent], extra_regressor(laws, qd, rigid_train)])
    ls = with_structure(fit_base(W_ls, tau, beta_model), base)
    repeated, repeat_note = None, None
    if sc.data.repeat:
        try:
            repeated = repeat(W_ls, tau, beta_model, sc.data.repeat)
        except ValueError as exc:
            repeat_note = f"repeatability not measured: {exc}"
    friction_model = friction_values(robot.frictions)
    ctx.progress("physically consistent parameters (semidefinite program)", None)
    fit, identified_frictions = consistent_fit(W, W_ls[:, len(base.independent):], tau, laws, theta_model,
                                               friction_model, extra_model)
    plausible = plausibility(fit.theta, theta_model, joints, fit.margin)
    warnings = []
    if plausible["implausible"]:
        warnings.append(f"identified links far from the model's (mass or inertia beyond {PLAUSIBLE:g} times, or under "
                        f"1/{PLAUSIBLE:g} of, its own): " + ", ".join(
                            f"{j} (mass x{plausible['ratios'][j]['mass']:.3g}, inertia "
                            f"x{plausible['ratios'][j]['inertia_trace']:.3g})" for j in plausible["implausible"]))
    if plausible["on_margin"]:
        warnings.append(f"{len(plausible['on_margin'])} link(s) on the fit's positive-definiteness margin (the data "
                        f"push them past physical): {', '.join(plausible['on_margin'])}")
    lagging = [] if lags is None else [k for k in np.flatnonzero(_found(lags)) if abs(lags.delay[k]) > LAG_WARNING]
    if lagging and sc.data.delay == "estimate":
        warnings.append("torque channels behind the encoders (estimated, not corrected; [data] delay = \"correct\" "
                        "shifts them): " + ", ".join(f"{joints[k]} {lags.delay[k] * 1e3:.2g} ms" for k in lagging))
    if lag_note:
        warnings.append(lag_note)
    if law_note:
        warnings.append(law_note)
    if repeat_note:
        warnings.append(repeat_note)
    moved = [] if repeated is None else list(np.flatnonzero(~repeated.overlap))
    if moved:
        warnings.append(f"{len(moved)} base parameter(s) moved between the {repeated.segments} segments of the "
                        "training span more than their 95 % intervals allow (log_identification.repeatability)")
    if constants is not None and constants.fixed_by == "model":
        warnings.append("torque constants identified up to one common scale, fixed by the model's own parameters "
                        "(a log with a known payload, [data.payload], fixes it)")
    if fit.fallback:
        warnings.append(f"the consistent fit fell back ({consistent.FALLBACKS[fit.fallback]}): "
                        + "; ".join(fit.attempts))
    spans = {"training": (q, qd, qdd, tau, train.t)}
    if validation is not None:
        spans["validation"] = (*joint_data(validation, joints), validation.t)
    predictions, measured, times, truth_tau = {}, {}, {}, {}
    floor = None
    pm_truth = build_model(sc.truth, sc.gravity_W) if sc.truth is not None else None
    identified = identified_spec(robot, fit.theta, identified_frictions)
    pm_identified = build_model(identified, sc.gravity_W)
    for span, (qs, qds, qdds, taus, ts) in spans.items():
        Ws = W if span == "training" else regressor(pm_identified, qs, qds, qdds, with_friction=True)
        W_base = Ws[:, base.independent]
        rigid_ls = links_torque(W_base, ls.beta[:r], link_part).reshape(taus.shape)
        W_span = np.hstack([W_base, extra_regressor(laws, qds, rigid_ls)])
        predictions[span] = {
            "least squares": (W_span @ ls.beta).reshape(taus.shape),
            "consistent": rnea(pm_identified, qs, qds, qdds).tau,
            "model as given": rnea(pm, qs, qds, qdds).tau,
        }
        measured[span], times[span] = taus, ts
        if span == "validation":  # the model class's floor there: its least squares on that span itself
            fitted = W_span @ np.linalg.lstsq(W_span, taus.ravel(), rcond=None)[0]
            floor = torque_errors(fitted.reshape(taus.shape), taus, joints)["rel_error"]
        if pm_truth is not None:  # what the robot that made the log needs at these states
            truth_tau[span] = rnea(pm_truth, qs, qds, qdds).tau
    refused = None  # why robot.xml was not written
    description = (f"{robot.name} identified from {sc.data.file.name} by harness (scenario {sc.name}): "
                   "physically consistent inertial parameters, friction and rotor inertia")
    files = export(robot, fit.theta, identified_frictions, description)
    ctx.progress("the models forward-simulated under the measured torques", None)
    simulated = {"consistent": identified, "model as given": robot, **({"truth": sc.truth} if sc.truth else {})}
    span = "validation" if validation is not None else "training"
    predicted = prediction(sc, simulated, spans[span][4], *spans[span][:2], spans[span][3], span, joints)
    mapping = coulomb_mapping(identified, qd, tau, (W[:, : 10 * n] @ fit.theta.ravel()).reshape(tau.shape))
    worst = max(mapping, key=lambda j: mapping[j]["rms"])
    try:  # MuJoCo's compiler has checks of its own: what it refuses is said, not a crash
        files[f"identified/{MJCF_FILE}"] = mjcf(
            identified, sc.gravity_W,
            f"{description}.\nCoulomb friction as MuJoCo's frictionloss (dry friction, a sharp sign) instead of "
            f"f_c tanh(q'/v_c), and no torque offset: at the training span's velocities, up to "
            f"{mapping[worst]['rms']:.3g} of the RMS torque (joint {worst}; per joint in README.md). Rotor inertia, "
            "viscous friction and inertials are the identified model's.")
    except ValueError as exc:
        refused = f"MuJoCo's compiler refuses the identified model ({compiler_message(exc)})"
    files[f"identified/{README_FILE}"] = readme(identified, [Path(f).name for f in files] + [README_FILE], mapping,
                                                description, refused)
    return LogIdentification(joints, parameter_names(joints, True), base, beta_model, ls, fit, theta_model,
                             friction_model, predictions, measured, times, files, mapping, refused, plausible, warnings,
                             truth_tau, _delay_section(lags, lag_note, sc.data.delay, joints),
                             _constants_section(constants, sc.data, joints), repeated, predicted,
                             identified_frictions, choice, [f"{joints[k]}.{key}" for k, key in terms], laws,
                             {span: v[:3] for span, v in spans.items()}, floor)


def _truth_errors(li: LogIdentification, span: str) -> dict:
    """Each model's torques, and the measured ones, against the truth's at the span's states."""
    ref = li.truth[span]
    return {**{model: torque_errors(pred, ref, li.joints) for model, pred in li.predictions[span].items()},
            "measured": torque_errors(li.measured[span], ref, li.joints)}


def _span_errors(li: LogIdentification, span: str) -> dict:
    return {model: torque_errors(pred, li.measured[span], li.joints) for model, pred in li.predictions[span].items()}


SERIES_POINTS = 600  # samples per curve kept in results.json for the report's validation plot


def _series(li: LogIdentification) -> dict:
    """The validation span's measured and predicted torques, thinned to SERIES_POINTS, for the plot."""
    span = "validation" if "validation" in li.t else "training"
    rows = evenly_spaced(len(li.t[span]), SERIES_POINTS)
    return {"span": span, "t": [float(x) for x in li.t[span][rows]],
            "measured": {j: [float(x) for x in li.measured[span][rows, k]] for k, j in enumerate(li.joints)},
            **{model: {j: [float(x) for x in pred[rows, k]] for k, j in enumerate(li.joints)}
               for model, pred in li.predictions[span].items()}}


def configure(t, scenario) -> FrictionLawConfig:
    """`[friction_law] choose = true, folds = 5, families = [...]`, validated (one-line errors
    naming the key). Only a `[data]` scenario reads it (runner/scenario.py refuses the table
    elsewhere, stages.LOG_TABLES)."""
    return FrictionLawConfig(
        t.boolean("choose", default=FrictionLawConfig.choose),
        t.integer("folds", default=FrictionLawConfig.folds, minimum=2),
        tuple(t.strings("families", choices=tuple(FAMILIES), default=list(FrictionLawConfig.families))))


STAGE = Stage("log_identification", "identification from the measured log", run, LogIdentification.serialise,
              "Identification from the log", files=lambda li: li.files, table="friction_law", configure=configure)
