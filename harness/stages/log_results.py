"""results.json's `log_identification`: a log run's steps (harness/stages/log_identification.py) as
plain numbers, one function per section."""

from __future__ import annotations

import numpy as np

from harness.base.numerics import SHIFT_GAIN, evenly_spaced, finite_or_null, parameter_scale, relative_error
from harness.identify import consistent, friction_law
from harness.identify.scale import constants_table
from harness.identify.torque_id import describe_base
from harness.model.friction import FAMILIES
from harness.model.inertia import PARAMETER_NAMES
from harness.stages.metrics import torque_errors

FLOOR_DEFINITION = (
    "the least-squares fit's columns (the same base parameters, friction laws and families) fitted on the "
    "validation span itself, its error there: what no fit of this model class can beat on that span, read "
    "for this figure alone. A held-out error near it is the model class's limit, not the fit's")
SERIES_POINTS = 600  # samples per curve kept in results.json for the report's validation plot


CURRENTS_BLIND = ("a torque constant's error: the validation span's torques are its currents times the same constants "
                  "(nominal, or identified on the training span), so a constant 10 % off scales the measured and the "
                  "fitted torques alike and leaves this figure unchanged; a log with a known payload ([data.payload]) "
                  "fixes the constants against known torques (docs/identification.md, 'Motor currents')")


def serialise(li, ctx, config) -> dict:
    """results.json's `log_identification`: the fits, their errors per span, the consistent model and the export."""
    errors = {span: _span_errors(li, span) for span in li.judged.predictions}
    headline = errors.get("validation", errors["training"])
    floor = li.judged.floor
    return {
        "method": "least squares of the structural base parameters with friction and rotor inertia, then all "
                  "parameters under the pseudo-inertia LMI (harness/identify/consistent.py: Clarabel, else SCS, "
                  "else the unconstrained fit moved to the nearest physical one; consistent.fallback says which)",
        "friction_law": _law_section(li),
        "rel_error_definition": ("||tau_predicted - tau_measured||_F / ||tau_measured||_F over every sample and "
                                 "joint of the span; per joint the same over its samples, and the RMS error in "
                                 "N m"),
        "spans": {span: {"samples": len(t), "t_start": float(t[0]), "t_end": float(t[-1])}
                  for span, t in li.judged.t.items()},
        "errors": errors,
        "start": li.start.as_dict(),
        "gravity": li.gravity.describe(),
        "validation_rel_error": {m: e["rel_error"] for m, e in headline.items()},
        **({"validation_cannot_see": CURRENTS_BLIND} if ctx.scenario.data.units["tau"] == "current" else {}),
        "validation_floor": None if floor is None else {"definition": FLOOR_DEFINITION, "rel_error": floor},
        "consistent_costs": {span: e["consistent"]["rel_error"] - e["least squares"]["rel_error"]
                             for span, e in errors.items()},
        "least_squares": _least_squares_section(li),
        **({"truth": _against_truth(li, ctx)} if li.judged.truth else {}),
        "prediction": li.prediction,
        "delays": delay_section(li.delayed.lags, li.delayed.note, ctx.scenario.data.delay, li.model.torque_joints),
        "torque_constants": _constants_section(li.constants.scales, ctx.scenario.data, li.model.torque_joints),
        "repeatability": _repeat_section(li),
        "plausibility": li.plausible,
        "warnings": li.warnings,
        "consistent": _consistent_section(li, ctx),
        "export": sorted(li.exported.files),
        "export_mjcf_friction": {
            "definition": "what robot.xml's frictionloss (MuJoCo's dry friction, a sharp sign) and its missing "
                          "offset change of the identified friction law at the training span's velocities: the "
                          "RMS change over the RMS torque, the largest over the largest torque, per joint",
            **li.exported.mjcf_friction},
        "export_mjcf_not_written": li.exported.refused,
        "joints": len(li.joints),
        "torque_joints": li.model.torque_joints,
        "unmeasured": {"joints": list(ctx.scenario.data.unmeasured), "definition": UNMEASURED,
                       **({"motors": list(ctx.scenario.data.unmeasured_motors)}
                          if ctx.scenario.data.unmeasured_motors else {})},
        "series": _series(li),
    }


UNMEASURED = ("joints whose torque the log does not hold ([data] unmeasured): their motion is in every other "
              "joint's row; no row of theirs is fitted or judged; a drive whose torque reaches no measured row (an "
              "open tree's unmeasured joint's own, a motor that moves only unmeasured joints, a closed chain's "
              "unmeasured actuated joint's) keeps the model's friction and rotor inertia in the identified model")


def _expression(li, k: int) -> str:
    """Base parameter k as the combination of parameters it stands for, or a family's coefficient."""
    r = len(li.model.base.independent)
    return describe_base(li.names, li.model.base, k) if k < r else li.extra_names[k - r]


def _least_squares_section(li) -> dict:
    ls, beta_model = li.fitted.ls, li.fitted.beta_model
    rel = relative_error(ls.beta, beta_model, parameter_scale(beta_model))
    return {
        "base_parameters": len(ls.beta), "parameters": len(li.names), "condition_number": ls.condition_number,
        "weakly_identifiable": [_expression(li, k) for k in np.flatnonzero(ls.weak)],
        "base": [{"expression": _expression(li, k), "model": float(beta_model[k]),
                  "identified": float(ls.beta[k]),
                  "std": finite_or_null(ls.std[k]),
                  "rel_std_percent": finite_or_null(100 * ls.std[k] / abs(ls.beta[k])) if ls.beta[k] else None,
                  "ci95": [finite_or_null(ls.beta[k] - ls.ci_half_width[k]),
                           finite_or_null(ls.beta[k] + ls.ci_half_width[k])],
                  "change_from_model": float(rel[k]), "sensitivity": finite_or_null(ls.sensitivity[k]),
                  "weakly_identifiable": bool(ls.weak[k])} for k in range(len(ls.beta))],
    }


def _repeat_section(li) -> dict | None:
    repeated = li.fitted.repeated
    if repeated is None:
        return None
    return {"definition": "the base parameters fitted on each of `segments` consecutive, disjoint parts of the "
                          "training span: per parameter the coefficient of variation over the parts, and whether "
                          "their 95 % intervals share a common point; `moved` lists those whose intervals do not "
                          "(harness/identify/repeat.py)",
            "segments": repeated.segments,
            "max_variation": finite_or_null(float(np.max(repeated.variation))),
            "median_variation": finite_or_null(float(np.median(repeated.variation))),
            "moved_count": int(np.sum(~repeated.overlap)),
            "moved": [_expression(li, k) for k in np.flatnonzero(~repeated.overlap)],
            "per_parameter": [{"expression": _expression(li, k), "mean": float(repeated.mean[k]),
                               "spread": float(repeated.spread[k]),
                               "variation": finite_or_null(float(repeated.variation[k])),
                               "intervals_overlap": bool(repeated.overlap[k])}
                              for k in range(repeated.beta.shape[1])]}


def _consistent_section(li, ctx) -> dict:
    fit = li.fit
    links = {}
    for k, j in enumerate(li.joints):
        links[j] = {"identified": dict(zip(PARAMETER_NAMES, map(float, fit.theta[k]), strict=True)),
                    "model": dict(zip(PARAMETER_NAMES, map(float, li.model.theta[k]), strict=True)),
                    **consistent.consistency(fit.theta[k])}
    return {
        "solver": fit.solver,
        "solver_status": fit.status,
        "fallback": fit.fallback,
        "fallback_definition": "; ".join(f"{k} {text}" for k, text in enumerate(consistent.FALLBACKS)),
        "solver_attempts": list(fit.attempts),
        "training_rel_residual": fit.relative_residual,
        "inconsistent_links": sum(not v["consistent"] for v in links.values()),
        "mass_band": {"definition": f"each link's mass held within {consistent.MASS_BAND[0]:g} to "
                                    f"{consistent.MASS_BAND[1]:g} times its model's: where the fit puts one beyond, "
                                    "it is made again with the band, and the fit free of it kept only where its "
                                    f"training residual is {consistent.DEMAND:g} (relative) lower: the data demand "
                                    "that mass",
                      "band": list(consistent.MASS_BAND), "held_at_band": [li.joints[k] for k in fit.held_at_band],
                      "beyond_band": [li.joints[k] for k in fit.beyond_band],
                      "training_rel_residual_free_of_band": fit.free_residual},
        "masses_beyond_band": len(fit.beyond_band),
        "links": links,
        "friction": {j: {"family": f.family, **f.as_dict()} for j, f in zip(li.drives, li.frictions, strict=True)},
        **({"transmission": ctx.scenario.robot.transmission.describe(ctx.scenario.robot.joint_names)}
           if ctx.scenario.robot.transmission is not None else {}),
    }


def _against_truth(li, ctx) -> dict:
    errors = {span: _truth_errors(li, span) for span in li.judged.truth}
    headline = errors.get("validation", errors["training"])
    return {"model": str(ctx.scenario.truth.source),
            "definition": "||tau - tau_truth||_F / ||tau_truth||_F, tau_truth the torques of the model that made "
                          "the log at the conditioned states (its inverse dynamics with its friction): each "
                          "model's error against the robot, and the measured torques' (the sensor's and the "
                          "conditioning's)",
            "validation_rel_error": {m: e["rel_error"] for m, e in headline.items()}, "errors": errors}


CHAIN_LAW_DEFINITION = (
    "A closed chain's (harness/identify/chain_law.py): viscous and Coulomb friction at every joint, passive ones "
    "included, with one v_c for all, through G^T Y; v_c estimated with the parameters, the least-squares residual "
    "over the training span as its function (a sharp sign and a logarithmic grid, the best refined between its "
    "neighbours). The held-out errors: the training span cut into {folds} consecutive parts, each predicted by "
    "the base parameters fitted on the others less their rows within guard_s of it (the validation span is never "
    "seen)")


def _law_section(li) -> dict:
    """results.json's `friction_law`: the law, and per joint the family and velocities chosen with
    every family's held-out figure (harness/identify/friction_law.py)."""
    out = {"law": "I_a q'' + f_v q' + f_c s + f_o, s = tanh(q'/v_c) (sign where v_c = 0), and per joint its "
                  "family's terms: asymmetric f_va |q'| + f_ca |s|, Stribeck f_s s exp(-(q'/v_s)^2), load f_l "
                  "|tau_R| s (harness/model/friction.py)",
           "chosen": li.laws.choice is not None,
           "families": {j: law.family for j, law in zip(li.drives, li.laws.laws, strict=True)},
           "coulomb_velocity": {j: f.coulomb_velocity for j, f in zip(li.drives, li.frictions, strict=True)}}
    c = li.laws.choice
    if c is None:
        out["definition"] = "The model's own law per joint ([friction_law] choose = false, or see warnings)"
        return out
    chain = li.model.chain is not None
    out |= {
        "definition": CHAIN_LAW_DEFINITION.format(folds=c.folds) if chain else (
            f"The training span cut into {c.folds} consecutive parts, each predicted by the base "
            "parameters fitted on the others less their rows within guard_s of it (the conditioning's "
            "reach; the validation span is never seen); the held-out error "
            "||tau_pred - tau||_F / ||tau||_F over the training span. Joint by joint (two passes), v_c "
            f"searched for every family ({', '.join(FAMILIES)}) over a logarithmic grid "
            f"{friction_law.VELOCITY_GRID[0]:g} to {friction_law.VELOCITY_GRID[-1]:g} and a sharp "
            "sign, then refined; the simplest family within one standard error (over the parts) of the best "
            "chosen (harness/identify/friction_law.py)"),
        "folds": c.folds,
        "guard_s": c.guard_s,
        "held_out_rel_error": {"model's law": c.model_error, "chosen": c.chosen_error},
        "per_joint": {j: c.scores[k] for k, j in enumerate(li.drives)},
        **({"coulomb_velocity_undecided": {
            "definition": f"the plain law's v_c range over which the held-out errors lie within "
                          f"{friction_law.FLAT:g} of the best, where it spans {friction_law.UNDECIDED} or more of the "
                          "grid's velocities: the data cannot tell them, and the range's middle (log v) is taken",
            **{j: list(r) for j, r in zip(li.drives, c.undecided, strict=True) if r}}}
           if any(getattr(c, "undecided", ()) or ()) else {}),
    }
    return out


def delay_section(lags, note: str | None, mode: str, joints: list[str]) -> dict:
    """results.json's `delays`: each torque channel's (harness/identify/delay.py Delays, or None with why)."""
    if lags is None:
        return {"mode": mode, "estimated": False, "note": note}
    return {"mode": mode, "estimated": True, "corrected": mode == "correct",
            "definition": "per joint, d such that the torque measured d later fits the joint's regressor rows best "
                          "(least squares, every parameter); positive: the torque channel lags the encoders "
                          "(harness/identify/delay.py)",
            "found_definition": f"inside the search, and the residual at the delay at most {SHIFT_GAIN:g} x the "
                                "residual at zero delay; only a found delay is corrected",
            "search_s": [float(lags.candidates[0]), float(lags.candidates[-1])],
            "per_joint": {j: {"delay_s": float(lags.delay[k]), "found": bool(lags.found[k]),
                              "residual": float(lags.residual[k]), "residual_at_zero": float(lags.residual_at_zero[k]),
                              "at_edge_of_search": bool(lags.at_edge[k])} for k, j in enumerate(joints)}}


def _constants_section(constants, source, joints: list[str]) -> dict | None:
    if constants is None:
        return None
    c = constants
    scale = ({"fixed_by": "the known payload's torques ([data.payload])"} if c.fixed_by == "payload" else {
        "fixed_by": "the model's own base parameters: the median ratio of the model's to the fit's (the currents fix "
                    "the constants only up to one common scale; every constant is as right as the model's parameters "
                    "are on the median, which a log of currents alone cannot check: a log with a known payload, "
                    "[data.payload], can)",
        "value": c.scale, "rel_std": c.scale_std})
    return {"definition": "per joint, the torque it carries over the torque its currents give with the nominal "
                          "constant (harness/identify/scale.py); identified = factor x nominal; ci95 its 95 % interval "
                          "(a wild bootstrap over `blocks` contiguous blocks of each log, the fit linearised at its "
                          "solution, the common scale recomputed on each of `resamples` draws), for this log's motion "
                          "and its noise; read from the training span with every found delay corrected (delays), and "
                          "as right as the scale's source",
            "fixed_by": c.fixed_by, "common_scale": scale, "relative_residual": c.relative_residual,
            "resamples": c.resamples, "blocks": c.blocks,
            "per_joint": constants_table(joints, source.torque_constant[:len(joints)], c.factor, c.std, c.ci95)}


def _truth_errors(li, span: str) -> dict:
    """Each model's torques, and the measured ones, against the truth's at the span's states."""
    ref, joints = li.judged.truth[span], li.model.torque_joints
    return {**{model: torque_errors(pred, ref, joints) for model, pred in li.judged.predictions[span].items()},
            "measured": torque_errors(li.judged.measured[span], ref, joints)}


def _span_errors(li, span: str) -> dict:
    return {model: torque_errors(pred, li.judged.measured[span], li.model.torque_joints)
            for model, pred in li.judged.predictions[span].items()}


def _series(li) -> dict:
    """The validation span's measured and predicted torques, thinned to SERIES_POINTS, for the plot."""
    j, joints = li.judged, li.model.torque_joints
    span = "validation" if "validation" in j.t else "training"
    rows = evenly_spaced(len(j.t[span]), SERIES_POINTS)
    return {"span": span, "t": [float(x) for x in j.t[span][rows]],
            "measured": {name: [float(x) for x in j.measured[span][rows, k]] for k, name in enumerate(joints)},
            **{model: {name: [float(x) for x in pred[rows, k]] for k, name in enumerate(joints)}
               for model, pred in j.predictions[span].items()}}
