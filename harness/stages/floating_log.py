"""A floating base's log (`[data.base]`, `[[data.contacts]]`: harness/sources/log/floating.py) identified and
judged: the floating-base identification (harness/identify/floating_id.py) on the training span, from the
contacts' wrenches alone (`rows = "base"`, no joint torque read) or with the joints' torques (`"all"`), its
physically consistent fit, and both judged on the validation span the fits never read: the world's whole
wrench on the base (the contacts' sum) and the joints' torques predicted against the log's, and, on a bench
log whose robot is known (`[data] truth`), against the truth's (docs/floating_base.md).

The rows are the robot's M q'' + h: the base's six (world axes, about its frame's origin) are the contacts'
wrench on it, and each joint's its motor's torque plus the contacts' J^T [F; M] (harness/model/contacts.py).
The start check runs first: the model as given against the log's base rows on the training span; a row
whose difference is over START_LIMIT of its size is a finding (a contact wrench in other axes than declared,
a force in other units, a quaternion in another order), and the start gate fails."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from harness.base.numerics import PREDICTION_TIMESTEP, finite_or_null
from harness.base.plugins import Stage
from harness.engines.pinocchio import build_model
from harness.identify import consistent as sdp
from harness.identify import delay, floating_id
from harness.identify.scale import constants_table, scaled
from harness.stages.context import VALIDATION_SPAN
from harness.stages.floating_fit import UNSEEN, seen, whole_rows
from harness.stages.log_results import delay_section

ROWS = ("base", "all")
START_LIMIT = 0.25  # the model as given may differ from the log's base rows by a quarter of their size
# (a model's error is a few per cent; a wrench in the wrong axes or unit is of the order of the wrench)


ESTIMATORS = ("wls", "ols")


@dataclass(frozen=True)
class FloatingLogConfig:
    """`[floating_log] rows = "base", consistent = true, friction = ..., estimator = "wls"`: `friction` (the
    joints' drive columns, rotor inertia, viscous and Coulomb friction and offset, on their own rows) by default
    where the model declares any and the joints' rows are read; never from the base rows alone (no drive reaches
    them). `estimator`: "wls", both fits weight each row (the base's force and moment components, each joint's
    torque) by the inverse of its residual variance, found again after each weighted fit until it settles
    (floating_id.row_weights); "ols", every row alike."""

    rows: str = "base"
    consistent: bool = True
    friction: bool = False
    estimator: str = "wls"


def configure(t, scenario) -> FloatingLogConfig:
    rows = t.string("rows", default="base", choices=ROWS)
    declared = not all(f.none for f in scenario.robot.frictions)
    friction = t.boolean("friction", default=declared and rows == "all")
    if friction and rows == "base":
        raise t.error("friction", "a drive's friction never reaches the base's rows: rows = \"all\" reads it")
    return FloatingLogConfig(rows, t.boolean("consistent", default=True), friction,
                             t.string("estimator", default="wls", choices=ESTIMATORS))


@dataclass(frozen=True, eq=False)
class FloatingLogFit:
    results: dict
    files: dict

    def serialise(self, ctx, config) -> dict:
        return self.results


def _data(robot, contacts, span, rows) -> tuple:
    """(base, q, q', q'', the rows read: floating_id.read_rows) of a span, and its whole rows (N, 6 + n)."""
    return _read(whole_rows(robot, contacts, span), rows)


def _read(whole: tuple, rows) -> tuple:
    """`_data` of a span's `whole_rows`."""
    base, q, qd, qdd, wrench, tau = whole
    return (base, q, qd, qdd, floating_id.measured(wrench, tau, rows)), np.concatenate([wrench, tau], axis=1)


def _errors(predicted: np.ndarray, reference: np.ndarray, scale: np.ndarray, names: list[str]) -> dict:
    """Each row's |predicted - reference| over its scale: the largest, where, and the RMS, of every row and of the
    base's six and the joints' apart (`names` the base's six first)."""
    rel = np.abs(predicted - reference) / scale
    worst = int(np.argmax(np.max(rel, axis=0)))
    rms = lambda x: float(np.sqrt(np.mean(x**2))) if x.size else float("nan")  # noqa: E731
    return {"max_rel_error": float(rel.max()), "max_rel_row": names[worst], "rms_rel_error": rms(rel),
            "rms_rel_error_base": rms(rel[:, :6]), "rms_rel_error_joints": rms(rel[:, 6:])}


def scales(whole: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """(6 + n,) each row's scale on a span: the base's force rows the largest |F| of the contacts' wrench on the
    base (`whole`'s first three columns), its moment rows the largest |M|, and each joint's the largest |value|
    of its motor's torque `tau` (N, n), not of its whole row: what a stance leg's motor gives is nearly all the
    foot's force, and the leg's own dynamics, the whole row, a small remainder. A channel that reads 0 throughout
    (a dead one) is judged on the largest of the joints' scales."""
    F, M = (float(np.max(np.linalg.norm(whole[:, s], axis=1))) for s in (slice(0, 3), slice(3, 6)))
    motor = np.max(np.abs(tau), axis=0)
    motor = np.where(motor > 0, motor, motor.max(initial=0.0))
    return np.maximum(np.concatenate([[F, F, F, M, M, M], motor]), 1e-300)


def _delays(mode: str, pm, robot, training, whole: tuple, Y: np.ndarray, friction: bool,
            joints: list[str]) -> tuple[dict, object, delay.Delays | None]:
    """Each joint's torque channel's lag behind the encoders (`[data] delay`, as for an arm: estimated on the
    training span, and with "correct" each one found corrected there and, by the judging, on the validation
    span): the motor's torque read d later, plus the contacts' J^T F on the encoders' clock, fitted by the
    joint's rows of the floating robot's regressor (harness/identify/delay.py). `whole` is the span's
    `whole_rows`, Y its regressor with the drives' columns. The results' section, the training span (corrected
    or as it was) and the delays the judging corrects (None: none). `joints`: those whose torque the log
    measures."""
    if mode == "none":
        return delay_section(None, None, mode, joints), training, None
    at = [robot.joint_names.index(j) for j in joints]
    tau = training.joint_data(joints)[3]
    W = (Y if friction else Y[..., :floating_id.rigid_columns(pm)])[:, 6:, :][:, at]
    try:
        lags = delay.estimate(training.t, tau, W, filtered=training.full_rate is not None,
                              offset=whole[5][:, at] - tau)
    except ValueError as exc:
        return delay_section(None, f"delays not estimated: {exc}", mode, joints), training, None
    if mode != "correct":
        return delay_section(lags, None, mode, joints), training, None
    return delay_section(lags, None, mode, joints), delay.corrected(training, lags, joints), lags


def _start(model_rows: np.ndarray, measured: np.ndarray) -> dict:
    """The start check (module docstring) on the base's force and moment rows."""
    findings = []
    for part, cols in (("force", slice(0, 3)), ("moment", slice(3, 6))):
        size = float(np.sqrt(np.mean(np.sum(measured[:, cols] ** 2, axis=1))))
        off = float(np.sqrt(np.mean(np.sum((model_rows[:, cols] - measured[:, cols]) ** 2, axis=1)))) / max(size,
                                                                                                            1e-300)
        if off > START_LIMIT:
            findings.append(f"the model as given and the log's contact wrenches differ in the base's {part} by "
                            f"{off:.3g} of its RMS: a contact wrench in other axes than declared, a force or moment "
                            "in other units, or a quaternion in another order?")
    return {"findings": len(findings), "said": findings, "limit": START_LIMIT,
            "definition": "the RMS of the model's base rows less the log's (the contacts' wrench on the base), "
                          "force and moment each over the RMS of the log's, on the training span"}


def _judged(ctx, lags: delay.Delays | None, factor: np.ndarray | None, measured: list[str]) -> tuple:
    """The span judged (the validation span, else the training span) and its series, read as the training span was
    read for the fits: its torque channels' delays corrected and its torques at the constants found there."""
    span = ctx.validation.get(VALIDATION_SPAN)
    name, judged = ("validation", span) if span is not None else ("training", ctx.training)
    if lags is not None:
        judged = delay.corrected(judged, lags, measured)
    if factor is not None:
        judged = scaled(judged, factor, measured)
    return name, judged


def _truth_rows(sc, data: tuple) -> np.ndarray | None:
    """(N, 6 + n): the rows the robot that made a bench log (`[data] truth`) gives at the states of `data`; None
    without one."""
    if sc.truth is None:
        return None
    truth_pm = build_model(sc.truth, sc.gravity_W, floating=True)
    own = not all(f.none for f in sc.truth.frictions)
    return floating_id.regressor(truth_pm, *data[:4], own) @ floating_id.true_parameters(truth_pm, own)


def _torque_constants(ctx, pm, structure, rows, span, training: tuple, Y: np.ndarray, measured: list[str],
                      weighted: bool) -> tuple:
    """Where a log of motor currents asks for its constants (`identify_torque_constants`): each measured joint's
    factor identified with the base parameters from the base's rows and the joints' (floating_id.torque_factors:
    the contacts' wrench fixes the scale), and the training span `span` (`training` its rows read, `_read`, Y its
    regressor) with every torque times its factor; the factors (None where not asked) and results.json's section, as an
    arm's (harness/stages/log_results.py)."""
    data = ctx.scenario.data
    if not data.identify_constants:
        return span, None, None
    ctx.progress("torque constants (motor currents), their scale the contacts' wrenches'", None)
    motor = span.joint_data(measured)[3]
    est = floating_id.torque_factors(pm, structure, rows, training, Y, motor, weighted)
    m = len(measured)
    factor, std, half = est.beta[-m:], est.std[-m:], est.ci_half_width[-m:]
    nominal = [data.torque_constant[ctx.scenario.robot.joint_names.index(j)] for j in measured]
    section = {
        "definition": "per joint, the torque it carries over the torque its currents give with the nominal constant, "
                      "identified with the base parameters from the base's rows and the joints' (harness/identify/"
                      "floating_id.py, torque_factors); identified = factor x nominal; ci95 its 95 % interval (the "
                      "least squares' CR3 interval, clustered by sample), for this log's motion and its noise; read "
                      "from the training span, and applied to the span judged as found there",
        "fixed_by": "contacts",
        "common_scale": {"fixed_by": "the contacts' wrenches on the base, read in newtons by no motor constant"},
        "per_joint": constants_table(measured, nominal, factor, std, np.stack([factor - half, factor + half], axis=1))}
    return scaled(span, factor, measured), factor, section


def _estimator(name: str, read: list[str], noise: np.ndarray, weights: np.ndarray | None) -> dict:
    """results.json's `estimator`: which, and each read row's residual on the training span after the weighted
    fits (floating_id.row_weights: its noise as the data show it) and its weight (1 throughout with "ols")."""
    weights = np.ones(len(read)) if weights is None else weights
    return {"name": name, "rows": {r: {"residual_std": float(s), "weight": float(w)}
                                   for r, s, w in zip(read, noise, weights, strict=True)},
            "definition": "wls weights each row by the inverse of its residual variance on the training span (a "
                          "force, a moment and a motor's torque each read with its own noise), found from the "
                          "ordinary least squares and again after each weighted fit until it settles, the largest "
                          "weight 1; ols weighs every row alike"}


def run(ctx, config: FloatingLogConfig | None) -> FloatingLogFit | None:
    sc = ctx.scenario
    fl = sc.data.floating
    if fl is None:
        return None
    config = config or FloatingLogConfig()
    rows, robot, friction = config.rows, sc.robot, config.friction
    names = list(floating_id.BASE_ROWS) + robot.joint_names
    # the joints whose torque the log measures ([data] unmeasured): only their rows are read and judged
    measured = [j for j in robot.joint_names if j not in sc.data.unmeasured]
    judged_rows = np.r_[0:6, [6 + robot.joint_names.index(j) for j in measured]].astype(int)
    if len(measured) < len(robot.joint_names) and rows == "all":
        rows = judged_rows
    pm = build_model(robot, sc.gravity_W, floating=True)
    if sc.data.delay != "none":
        ctx.progress("the torque channels' delays behind the encoders", None)
    # the training span's rows and regressor, once: the delays', the start check's and both fits'
    whole = whole_rows(robot, fl.contacts, ctx.training)
    Y_t = floating_id.regressor(pm, *whole[:4], with_friction=True)
    delays, training_span, lags = _delays(sc.data.delay, pm, robot, ctx.training, whole, Y_t, friction, measured)
    if lags is not None:  # corrected: the torques read later, the rows where that falls beyond an end dropped
        whole = whole_rows(robot, fl.contacts, training_span)
        Y_t = floating_id.regressor(pm, *whole[:4], with_friction=True)
    training, whole_t = _read(whole, rows)
    model_t = Y_t[..., :floating_id.rigid_columns(pm)] @ floating_id.true_parameters(pm)
    start = _start(model_t[:, :6], whole_t[:, :6])
    ctx.progress("floating-base structural base parameters", None)
    structure = ctx.once(("floating-base structural base parameters", rows if isinstance(rows, str) else tuple(rows),
                          friction),
                         lambda: floating_id.structural_base(pm, robot.limits, rows, with_friction=friction))
    training_span, factor, constants = _torque_constants(ctx, pm, structure, rows, training_span, training, Y_t,
                                                         measured, config.estimator == "wls")
    if factor is not None:  # the torques at the constants found: the training span's rows read again
        training, whole_t = _data(robot, fl.contacts, training_span, rows)
    judged_span, judged = _judged(ctx, lags, factor, measured)
    validation, whole_v = _data(robot, fl.contacts, judged, rows)
    weights, noise = floating_id.row_weights(pm, structure, rows, training, Y_t)
    if config.estimator == "ols":
        weights = None
    fit, _, _ = floating_id.identify(pm, structure, rows, training, validation, Y_t, weights)
    parameters = floating_id.parameter_names(robot, pm, friction)
    holding, unseen = seen(structure, parameters, robot)
    declared = not all(f.none for f in robot.frictions)  # the model's drives judged with their laws
    Y_v = floating_id.regressor(pm, *validation[:4], declared)  # (N, 6 + n, p [+ 4 n])
    rigid = Y_v.shape[-1] - (4 * len(robot.joints) if declared else 0)
    scale = scales(whole_v, judged.joint_data(robot.joint_names)[3])
    # every row predicted, the joints' too where the fit read the base rows alone: a floating base's rows see
    # every base parameter its whole regressor does (Ayusawa, Venture and Nakamura 2014; structural_base gives
    # the same count either way), and friction, which only the joints' rows see, is refused with rows = "base"
    lsq = floating_id.selected(Y_v if friction else Y_v[..., :rigid], "all")[:, structure.independent] @ fit.beta
    predictions = {"least_squares": lsq.reshape(len(whole_v), -1),
                   "model_as_given": Y_v @ floating_id.true_parameters(pm, declared)}
    truth_rows = _truth_rows(sc, validation)
    if truth_rows is not None:
        predictions["truth"] = truth_rows
    out, files, identified = {}, {}, None
    if config.consistent:
        ctx.progress("physically consistent parameters (semidefinite program)", None)
        physical, links = floating_id.consistent(pm, robot, rows, training, friction, Y_t, weights)
        # its joints' rows with the drives' laws identified, or the model's where they were not
        predictions["consistent"] = floating_id.consistent_rows(pm, physical, "all", validation, friction)
        model = floating_id.link_parameters(pm)
        frictions = tuple(dataclasses.replace(f, armature=a, viscous=v, coulomb=c, offset=o) if friction else f
                          for f, (a, v, c, o) in zip(robot.frictions, physical.friction[1:], strict=True))
        files, identified = _exported(sc, physical.theta, frictions)
        out["consistent"] = {
            "exported": sorted(files),
            "status": physical.status, "solver": physical.solver,
            "training_relative_residual": physical.relative_residual,
            "inconsistent_links": [b for k, b in enumerate(links)
                                   if not sdp.consistency(physical.theta[k])["consistent"]],
            "masses": {b: {"identified": float(physical.theta[k, 0]), "model": float(model[k, 0])}
                       for k, b in enumerate(links)}}
    judged_out = {}
    c, named = judged_rows, [names[i] for i in judged_rows]
    for name, pred in predictions.items():
        entry = {"measured": _errors(pred[:, c], whole_v[:, c], scale[c], named)}
        if truth_rows is not None and name != "truth":
            entry["truth"] = _errors(pred[:, c], truth_rows[:, c], scale[c], named)
        judged_out[name] = entry
    results = {
        "rows": config.rows, "unmeasured": [j for j in robot.joint_names if j not in measured], "friction": friction,
        "span": judged_span, "base_body_in": holding, "unseen": unseen,
        "unseen_definition": UNSEEN, "contacts": [c.name for c in fl.contacts],
        "start": start, "parameters": len(parameters), "base_parameters": len(structure.independent),
        "condition_number": float(fit.condition_number), "judged": judged_out, **out,
        "estimator": _estimator(config.estimator, [names[i] for i in floating_id.read_rows(rows, len(robot.joints))],
                                noise, weights),
        "definition": "each row's |predicted - reference| over its scale on the judged span: the base's force rows "
                      "over the largest |F| of the contacts' wrench on the base, its moment rows over the largest "
                      "|M|; each joint's motor torque (its row less the contacts' J^T F as the log reads them) over "
                      "its largest |value| in the log; `measured` against the log's, `truth` against what the robot "
                      "that made it gives at the same states and contact forces",
        "delays": delays, "torque_constants": constants,
        "prediction": _prediction(ctx, judged, judged_span, identified)}
    return FloatingLogFit(results, files)


FLOATING_PREDICTION = (
    "from {starts} measured states along the {span} span (the base's pose and twist, the joints' q and q'), each "
    "model forward-simulated on its free joint in MuJoCo (RK4, 1 ms) under the measured joint torques less its dry "
    "friction and the measured contact wrenches applied to their bodies (no contact law: the ground acts as the log "
    "says it did; harness/engines/free_predict.py); at each horizon the base origin's distance from the log's [m] and "
    "the angle between the two orientations [rad] (RMS and largest over the starts), and q_sim - q_meas [rad or m] "
    "(RMS over the starts and joints, and the largest joint's RMS). The least-squares fit is not simulated: its base "
    "parameters are not a full set of physical parameters")


def _prediction(ctx, judged, span: str, identified) -> dict:
    """results.json's `prediction` of a floating base's log (FLOATING_PREDICTION): the model as given, the consistent
    fit's robot (`identified`, where made) and the truth (a bench log's) simulated from `[data] prediction`'s starts
    of the span judged (`judged`, a TimeSeries with the base's and the contacts' columns)."""
    from harness.engines.free_predict import predict
    from harness.model.floating import BaseMotion
    from harness.stages.log_judge import joint_drift, not_predicted, prediction_starts

    sc = ctx.scenario
    plan = sc.data.prediction
    starts = prediction_starts(judged.t, plan.horizons[-1], plan.starts)
    out = {"definition": FLOATING_PREDICTION.format(starts=len(starts), span=span), "span": span,
           "starts": len(starts), "timestep_s": PREDICTION_TIMESTEP, "horizons_s": list(plan.horizons), "models": {}}
    note = not_predicted(plan, starts, span, "not made: joints without a torque channel ([data] unmeasured) have "
                                             "nothing to drive them" if sc.data.unmeasured else None)
    if note is not None:
        out["note"] = note
        return out
    ctx.progress("forward simulation under the measured torques and contact wrenches", None)
    base = BaseMotion.from_rows(judged.base_pose, judged.base_twist_W, judged.base_rate_W)
    bodies = tuple(c.body for c in sc.data.floating.contacts)
    models = {"model_as_given": sc.robot, "consistent": identified, "truth": sc.truth}
    for name, spec in models.items():
        if spec is None:
            continue
        position, angle, q_err = predict(spec, sc.gravity_W, judged.t, base, judged.q, judged.qd, judged.tau, bodies,
                                         judged.contact_F_W, judged.contact_M_W, judged.contact_x_W, starts,
                                         plan.horizons)
        out["models"][name] = {f"h{round(h * 1e3)}ms": {
            "base_position_rms_m": finite_or_null(float(np.sqrt(np.mean(position[:, k] ** 2)))),
            "base_position_max_m": finite_or_null(float(np.max(position[:, k]))),
            "base_angle_rms_rad": finite_or_null(float(np.sqrt(np.mean(angle[:, k] ** 2)))),
            "base_angle_max_rad": finite_or_null(float(np.max(angle[:, k]))),
            **joint_drift(q_err[:, k], sc.robot.joint_names),
            "diverged": int(np.sum(~np.isfinite(position[:, k])))} for k, h in enumerate(plan.horizons)}
    return out


def _exported(sc, theta: np.ndarray, frictions: tuple) -> tuple[dict[str, str], object]:
    """The consistent fit as files, and its robot (a RobotSpec): an MJCF file of the robot on its free joint with
    the identified bodies, and where the robot comes from a URDF, that URDF with them and a floating joint
    (harness/model/export.py)."""
    from harness.model.export import MJCF_FILE, URDF_FILE, identified_floating_spec, write_urdf
    from harness.model.mjcf import write_mjcf

    robot = sc.robot
    spec = identified_floating_spec(robot, theta, frictions)
    files = {f"identified/{MJCF_FILE}": write_mjcf(spec, sc.gravity_W, f"{robot.name}: identified by the harness from "
                                                                       "a floating base's log (its physically "
                                                                       "consistent fit)", floating=True)}
    if robot.urdf is not None:
        files[f"identified/{URDF_FILE}"] = write_urdf(robot, theta[1:], frictions, theta[0])
    return files, spec


STAGE = Stage("floating_log", "a floating base's log: identification and judging", run,
              FloatingLogFit.serialise, "A floating base's log", files=lambda f: f.files, table="floating_log",
              configure=configure)
