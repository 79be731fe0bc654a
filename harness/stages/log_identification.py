"""Identification from a measured log (harness/sources/log/): the pipeline proven on the bench, on data
whose truth nobody knows, judged on a part of the log the fit never saw.

The source gives the log read, checked, conditioned and split (Context.training, the validation span
in Context.validation). The run is then these steps, each a function with a typed result, the fitting
ones taking the training span alone (a TrainingSpan, harness/sources/log/condition.py: handed another,
they refuse it); what they find on it, a delay or a torque constant, the judging applies to the
validation span (log_judge.as_fitted):
1. delay: each torque channel's lag behind the encoders, estimated and, where asked and found,
   corrected (harness/identify/delay.py);
2. constants: a log of currents made torques by identified torque constants (harness/identify/scale.py);
3. friction law: each joint's law chosen by cross-validation within the training span
   (harness/identify/friction_law.py);
4. fit: least squares of the structural base parameters with each joint's friction and rotor inertia
   (harness/identify/torque_id.py), with standard deviations and weakly identifiable parameters;
5. consistent: the physically consistent fit of all parameters (harness/identify/consistent.py),
   closest to the model's own values where the data cannot tell;
6. judge: both fits, and the model as it was given (its own friction), predict the torques of each
   span: per joint RMS and relative error, and over all joints ||tau_pred - tau||_F / ||tau||_F (the
   figure published identifications quote); against the truth's too, on a bench log;
   The model as given is held against the torques as read (`start`): a factor or a sign between them
   is a reading mistake, said with its likely cause and failing the gate every log scenario has;
7. predict: each model forward-simulated from measured states under the measured torques
   (harness/stages/log_judge.py);
8. export: the consistent model as URDF, MJCF, joints.toml and a model file (harness/model/export.py).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path

import numpy as np

from harness.base.numerics import SideBySide, fit_residual
from harness.base.plugins import Stage
from harness.base.series import TimeSeries
from harness.engines.pinocchio import build_model, joint_torques
from harness.identify import chain_law, consistent, delay, filtered, friction_law, gravity, scale
from harness.identify.friction_law import FrictionLawConfig
from harness.identify.laws import Law, extra_terms
from harness.identify.ls_model import LeastSquaresFit, extra_terms_names
from harness.identify.lstsq import Estimate
from harness.identify.repeat import Repeatability, repeat
from harness.identify.span_rows import RowsOnDemand, rows_by_sample
from harness.identify.torque_id import (
    describe_base,
    fit_base,
    links_weights,
    parameter_names,
    structural_base,
    with_structure,
)
from harness.model.export import (
    LEAST_SQUARES_FILE,
    MJCF_FILE,
    MODEL_FILE,
    README_FILE,
    coulomb_mapping,
    export,
    identified_spec,
    readme,
)
from harness.model.friction import FAMILIES, JointFriction
from harness.model.friction import values as friction_values
from harness.model.mjcf import compiler_message, write_mjcf
from harness.sources.log.condition import TrainingSpan, fits_on
from harness.stages.context import VALIDATION_SPAN
from harness.stages.log_judge import Start, as_fitted, prediction, start
from harness.stages.log_model import LogModel, log_model
from harness.stages.log_results import serialise

LAG_WARNING = 0.001  # s: an estimated delay beyond 1 ms, left uncorrected, is said on the terminal


@dataclass(frozen=True, eq=False)
class Delayed:
    """Step 1: the delays estimated on the training span (None where not asked for, or not
    estimable: `note`), the training span as the fit reads it (corrected where asked: `corrected`),
    and its regressor at the model's own velocities (harness/identify/torque_id.py, with friction)."""

    lags: delay.Delays | None
    note: str | None
    training: TrainingSpan
    W: np.ndarray | RowsOnDemand | None  # (N n, 14 n); None once the delays and the constants have read it (`run`)
    corrected: bool = False  # the found delays corrected (the judging corrects the validation span likewise)


def delays(mode: str, model: LogModel, training: TrainingSpan) -> Delayed:
    """Each torque channel's lag (every joint's, or a closed chain's actuated joints': its rows of G^T Y)."""
    joints, training = model.torque_joints, fits_on(training)

    def rows(series: TimeSeries) -> np.ndarray | RowsOnDemand:
        return model.rows(model.pm, *model.data(series)[:3])

    W = rows(training)
    if mode == "none":
        return Delayed(None, None, training, W)
    try:
        filtered = training.full_rate is not None  # a low-passed span keeps its full rate (sources/log/condition.py)
        lags = delay.estimate(training.t, model.data(training)[3], rows_by_sample(W, len(joints)), filtered=filtered)
    except ValueError as exc:
        return Delayed(None, f"delays not estimated: {exc}", training, W)
    if mode != "correct":
        return Delayed(lags, None, training, W)
    # the joints whose delay is found; the others as they are
    training = delay.corrected(training, lags, joints)
    return Delayed(lags, None, training, rows(training), corrected=True)


@dataclass(frozen=True, eq=False)
class Constants:
    """Step 2: the torque constants identified (None: a log of torques, or constants not asked for),
    and the training span in joint torques."""

    scales: scale.TorqueScales | None
    training: TrainingSpan


def constants(data, robot, model: LogModel, d: Delayed, payload: TimeSeries | None) -> Constants:
    """The factors are read from the training span with every found delay corrected, whatever `delay`
    says of the fit (a lag left in moves them by several percent: docs/identification.md, torque constants).
    Each torque channel's: a closed chain's actuated joints', on their rows of G^T Y."""
    if data.units["tau"] != "current" or not data.identify_constants:
        return Constants(None, d.training)
    joints = model.torque_joints
    training, W = fits_on(d.training), d.W
    if d.lags is not None and data.delay == "estimate" and np.any(d.lags.found):
        training = delay.corrected(d.training, d.lags, joints)
        W = model.rows(model.pm, *model.data(training)[:3])
    if isinstance(W, RowsOnDemand):  # the torque constants' fit reads it whole
        W = W.whole()
    tau = model.data(training)[3]
    found = scale.torque_constants(model.pm, model.base, W, tau, model.base.of(model.x_model), robot, data.payload,
                                   payload, None if model.plain else partial(model.rows, model.pm), joints)
    return Constants(found, scale.scaled(d.training, found.factor, joints))


@dataclass(frozen=True, eq=False)
class LawChoice:
    """Step 3: each joint's law (chosen, or the model's), how it was chosen, and why not where not."""

    laws: tuple[Law, ...]
    choice: friction_law.FrictionChoice | None
    note: str | None


def filtered_columns(series: TimeSeries):
    """The span's FilteredColumns where it was low-pass filtered (and it covers the span's rows), else
    None: the friction columns then are filtered as its torques were (harness/identify/filtered.py)."""
    columns = series.full_rate
    return columns if columns is not None and columns.covers(series.t) else None


def friction_laws(config: FrictionLawConfig, robot, model: LogModel, joints: list[str],
                  training: TrainingSpan) -> LawChoice:
    """The search reads the training span's regressor at the model's velocities a chunk of samples at a
    time (its fixed columns do not depend on a law's), never whole."""
    choice, note, training = None, None, fits_on(training)
    if config.choose and model.chain is not None:
        return _chain_laws(config, robot, model, training)
    if config.choose:
        q, qd, qdd, tau = training.joint_data(joints)

        measured = model.measured  # an unmeasured joint's rows and torque zero: they weigh nothing

        def rows_of(samples: np.ndarray) -> np.ndarray:
            return model.joint_rows(model.pm, q[samples], qd[samples], qdd[samples])

        try:
            choice = friction_law.choose(rows_of, model.base.independent, model.link_part, tau * measured, qd,
                                         training.t, unmeasured_plain(robot.frictions, model.drives_reached), config,
                                         training.reach_s, robot.transmission, filtered_columns(training), measured,
                                         q)
        except ValueError as exc:
            note = f"friction law not chosen, the model's kept: {exc}"
    laws = choice.laws if choice is not None else tuple(
        Law.of(f) for f in unmeasured_plain(robot.frictions, model.drives_reached))
    if choice is not None:  # what the data could not tell, said with its range
        undecided = [(j, flat, law) for j, flat, law in zip(joints, choice.undecided, laws, strict=True) if flat]
        note = ("the held-out error of viscous and Coulomb friction is flat in the smoothing velocity (the data "
                "cannot tell it; rad/s or m/s): " + ", ".join(
                    f"{j} from {lo:.3g} to {hi:.3g} (the law chosen: {law.family}, v_c {law.coulomb_velocity:.3g})"
                    for j, (lo, hi), law in undecided)) if undecided else None
    return LawChoice(laws, choice, note)


def unmeasured_plain(frictions: tuple[JointFriction, ...], measured: np.ndarray) -> tuple[JointFriction, ...]:
    """Each joint's friction as the fit reads it: an unmeasured joint's (no row of its own in an open
    tree) plain viscous and Coulomb friction, no family's term, at its own values: its terms reach no
    measured row, and the identified model keeps its own law (`identified_frictions`)."""
    return tuple(f if m else JointFriction(f.armature, f.viscous, f.coulomb, f.offset, f.coulomb_velocity)
                 for f, m in zip(frictions, measured, strict=True))


def identified_frictions(frictions: tuple[JointFriction, ...], model: tuple[JointFriction, ...],
                         measured: np.ndarray) -> tuple[JointFriction, ...]:
    """The consistent fit's friction of each joint, an unmeasured joint's the model's own (the data hold
    nothing of it)."""
    return tuple(f if m else own for f, own, m in zip(frictions, model, measured, strict=True))


def _chain_laws(config: FrictionLawConfig, robot, model: LogModel, training: TrainingSpan) -> LawChoice:
    """A closed chain's: one smoothing velocity for every joint's viscous and Coulomb law
    (harness/identify/chain_law.py), where the model states no other family."""
    kept = tuple(Law.of(f) for f in robot.frictions)
    other = next((j for j, law in zip(robot.joint_names, kept, strict=True) if law.family != chain_law.FAMILY), None)
    if other is not None:
        return LawChoice(kept, None, f"friction law not chosen, the model's kept: a closed chain's search tries "
                                     f"viscous and Coulomb friction, and the model states {other}'s as "
                                     f"{robot.joint(other).friction.family}")
    q, qd, qdd, tau = model.data(training)
    try:
        choice = chain_law.choose(model.rows(model.pm, q, qd, qdd), model.projection(q), qd, tau,
                                  model.base.independent, model.link_part, training.t, config.folds,
                                  training.reach_s, np.array([law.coulomb_velocity for law in kept]),
                                  filtered_columns(training))
    except ValueError as exc:
        return LawChoice(kept, None, f"friction law not chosen, the model's kept: {exc}")
    return LawChoice(choice.laws, choice, None)


@dataclass(frozen=True, eq=False)
class Fitted:
    """Step 4: the least-squares fit of the base parameters and the families' coefficients (`ls`, an
    Estimate), with the regressor it was made on; the fit repeated on disjoint segments where asked."""

    W: np.ndarray | RowsOnDemand  # (N n, 14 n) the training span's regressor at the laws' velocities
    E: np.ndarray  # (N n, e) the families' columns (extra_terms(laws)) on the training span
    beta_model: np.ndarray  # the model's own base parameters and family coefficients
    extra_model: np.ndarray  # (e,) the model's family coefficients
    ls: Estimate  # harness/identify/lstsq.py
    repeated: Repeatability | None
    note: str | None


def least_squares(robot, gravity_W: np.ndarray, model: LogModel, joints: list[str], training: TrainingSpan,
                  laws: LawChoice, segments: int | None) -> Fitted:
    """On the training span's regressor at the laws' velocities (the chosen ones, or the model's own),
    made here, its Coulomb columns the filtered ones on a filtered log; a long span's made where it is
    read, never whole (harness/identify/span_rows.py)."""
    q, qd, qdd, tau = model.data(fits_on(training))
    columns = filtered_columns(training)
    # the Coulomb columns filtered as the torques were, on a filtered log
    coulomb = None if columns is None else filtered.coulomb(columns, training.t, laws.laws, robot.transmission)
    pm = model.pm if laws.choice is None else build_model(  # the chosen smoothing velocities
        robot.with_frictions(laws.choice.frictions(robot.frictions)), gravity_W)
    W = model.rows(pm, q, qd, qdd, coulomb)
    if laws.choice is None:
        rigid = links_torque(W, model.theta, tau.shape)
    else:  # the search's is every joint's, a closed chain's its actuated joints'
        rigid = laws.choice.tau_rigid if model.chain is not None else laws.choice.tau_rigid[:, model.measured]
    extra_model = np.array([getattr(robot.frictions[k], key) for k, key in extra_terms(laws.laws)])
    beta_model = np.concatenate([model.base.of(model.x_model), extra_model])
    E = model.families(laws.laws, q, qd, rigid, robot.transmission, columns, training.t)
    W_ls = SideBySide(((W, model.base.independent), E))  # never joined: a long log's regressor is large
    ls = with_structure(fit_base(W_ls, tau, beta_model), model.base)
    repeated, note = None, None
    if segments:
        try:
            repeated = repeat(W_ls, tau, beta_model, segments)
        except ValueError as exc:
            note = f"repeatability not measured: {exc}"
    return Fitted(W, E, beta_model, extra_model, ls, repeated, note)


def links_torque(W: np.ndarray | RowsOnDemand, theta: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """(N, n) the links' torque of the parameters theta (n, 10) on a span's regressor W: its first 10 n
    columns, never copied out."""
    return (SideBySide(((W, np.arange(theta.size)),)) @ theta.ravel()).reshape(shape)


@dataclass(frozen=True, eq=False)
class Judged:
    """Step 6: per span (training, validation) the states the fits read, the measured torques, each
    model's predicted torques, the truth's where known; the model class's floor on the validation span."""

    states: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]  # span -> (q, q', q'')
    measured: dict[str, np.ndarray]  # span -> (N, n)
    t: dict[str, np.ndarray]
    predictions: dict[str, dict[str, np.ndarray]]  # span -> model -> (N, n)
    truth: dict[str, np.ndarray]  # span -> the truth's torques (a bench log)
    floor: float | None  # the least-squares columns fitted on the validation span itself: its error there


def judge(sc, model: LogModel, spans: dict[str, TimeSeries], fitted: Fitted, laws: tuple[Law, ...],
          identified, given_training: np.ndarray, tilt: gravity.Tilt) -> Judged:
    """Each span predicted by the least-squares fit, the consistent fit (`identified`, a RobotSpec)
    and the model as given (on the training span `given_training`, as the start check computed it)."""
    r = len(model.base.independent)
    pm_truth = build_model(sc.truth, tilt.declared_W) if sc.truth is not None else None
    pm_identified = build_model(identified, tilt.gravity_W)
    pm_given = build_model(sc.robot, tilt.declared_W)  # the model and the gravity the scenario states
    out = Judged({}, {}, {}, {}, {}, None)
    for name, series in spans.items():
        q, qd, qdd, tau = model.data(series)
        W = fitted.W if name == "training" else model.rows(pm_identified, q, qd, qdd)
        base = (W, model.base.independent)  # the base parameters' columns, never copied out
        rigid_ls = (SideBySide((base,)) @ links_weights(fitted.ls.beta[:r], model.link_part)).reshape(tau.shape)
        columns = filtered_columns(series) if name == "training" else None  # as the fit read it
        W_span = SideBySide((base, model.families(laws, q, qd, rigid_ls, sc.robot.transmission, columns, series.t)))
        out.states[name], out.measured[name], out.t[name] = (q, qd, qdd), tau, series.t
        out.predictions[name] = {"least squares": (W_span @ fitted.ls.beta).reshape(tau.shape),
                                 "consistent": model.torques(pm_identified, q, qd, qdd),
                                 "model as given": given_training if name == "training" else
                                 model.torques(pm_given, q, qd, qdd)}
        if name == "validation":  # the model class's floor there: its least squares on that span itself
            floor = fit_residual(W_span, tau.ravel())  # its residual, from its rows' QR
            out = _with_floor(out, floor / float(np.linalg.norm(tau)))
        if pm_truth is not None:  # what the robot that made the log needs at these states
            out.truth[name] = model.torques(pm_truth, q, qd, qdd)
    return out


def _with_floor(judged: Judged, floor: float) -> Judged:
    return Judged(judged.states, judged.measured, judged.t, judged.predictions, judged.truth, floor)


@dataclass(frozen=True, eq=False)
class Exported:
    """Step 8: the files of `identified/`, what robot.xml's dry friction changes, and why robot.xml
    was not written, where it was not."""

    files: dict[str, str]
    mjcf_friction: dict[str, dict[str, float]]  # per joint (harness/model/export.py, coulomb_mapping)
    refused: str | None


def export_model(sc, gravity_W: np.ndarray, robot, identified, frictions: tuple[JointFriction, ...], theta: np.ndarray,
                 training: TrainingSpan, W: np.ndarray | RowsOnDemand, ls: LeastSquaresFit) -> Exported:
    """A closed chain's friction mapping is judged against each joint's torque in the identified tree
    (rnea at the training span's states: what each joint carries, the loops' forces included, its
    drive's or its bearing's), a passive joint having no measured torque of its own."""
    q, qd, qdd, tau = training.joint_data(robot.joint_names)
    g = ", ".join(f"{x:.17g}" for x in gravity_W)
    description = (f"{robot.name} identified from {sc.data.file.name} by harness (scenario {sc.name}): "
                   f"physically consistent inertial parameters, friction and rotor inertia, at gravity [{g}] m/s^2 "
                   "in the base's axes")
    files = export(robot, theta, frictions, description, gravity_W)
    files[f"identified/{LEAST_SQUARES_FILE}"] = ls.to_toml(
        f"{robot.name}: the least-squares fit of its base parameters from {sc.data.file.name} by harness (scenario "
        f"{sc.name}).\nFormat: docs/reference.md, 'The least-squares fit'; harness.identified_model(folder, "
        "fit=\"least squares\") evaluates it.")
    if robot.loops or sc.data.unmeasured:  # every joint's torque in the identified model
        mapping = coulomb_mapping(identified, qd, joint_torques(build_model(identified, gravity_W), q, qd, qdd))
    else:
        mapping = coulomb_mapping(identified, qd, tau, links_torque(W, theta, tau.shape))
    worst = max(mapping, key=lambda j: mapping[j]["rms"])
    refused = None
    try:  # MuJoCo's compiler has checks of its own: what it refuses is said, not a crash
        files[f"identified/{MJCF_FILE}"] = write_mjcf(
            identified, gravity_W,
            f"{description}.\nCoulomb friction as MuJoCo's frictionloss (dry friction, a sharp sign) instead of "
            f"f_c tanh(q'/v_c), and no torque offset: at the training span's velocities, up to "
            f"{mapping[worst]['rms']:.3g} of the RMS torque (joint {worst}; per joint in README.md). Rotor inertia, "
            "viscous friction and inertials are the identified model's.")
    except ValueError as exc:
        refused = f"MuJoCo's compiler refuses the identified model ({compiler_message(exc)})"
    files[f"identified/{README_FILE}"] = readme(identified, [Path(f).name for f in files] + [README_FILE], mapping,
                                                description, refused)
    return Exported(files, mapping, refused)


def least_squares_fit(model: LogModel, fitted: Fitted, names: list[str], laws: tuple[Law, ...],
                      drives: list[str], gravity_W: np.ndarray) -> LeastSquaresFit:
    """Step 8's least-squares file: the fit, its columns and what each parameter stands for."""
    base, r = model.base, len(model.base.independent)
    families = extra_terms_names(laws, drives)
    link, share = model.link_part
    return LeastSquaresFit(MODEL_FILE, base.independent, [describe_base(names, base, k) for k in range(r)] + families,
                           fitted.ls.beta, np.asarray(fitted.ls.std, dtype=float), link, share, families,
                           np.asarray(gravity_W, dtype=float))


@dataclass(frozen=True, eq=False)
class LogIdentification:
    """A log run's steps' results, in the order they ran (results.json's `log_identification`:
    harness/stages/log_results.py)."""

    joints: list[str]
    drives: list[str]  # who each drive law belongs to: the joints, or the transmission's motors
    names: list[str]  # all parameters: 10 per link, then 4 per drive
    model: LogModel
    delayed: Delayed
    constants: Constants
    laws: LawChoice
    fitted: Fitted
    fit: consistent.ConsistentFit
    frictions: tuple[JointFriction, ...]  # each joint's identified friction law
    plausible: dict  # consistent.plausibility
    judged: Judged
    prediction: dict  # results.json's `prediction` (log_judge.prediction)
    exported: Exported
    start: Start  # the model as given against the log as read (log_judge.start)
    gravity: gravity.Tilt  # the gravity the fits, the judging and the exports use
    warnings: list[str] = field(default_factory=list)  # what the terminal is told

    @property
    def extra_names(self) -> list[str]:
        """The families' coefficients after the base parameters."""
        return extra_terms_names(self.laws.laws, self.drives)

    @property
    def files(self) -> dict[str, str]:
        return self.exported.files

    serialise = serialise


def run(ctx, config: FrictionLawConfig | None) -> LogIdentification | None:
    sc = ctx.scenario
    if sc.data.floating is not None:  # a floating base's log: harness/stages/floating_log.py
        return None
    robot, joints = sc.robot, sc.robot.joint_names
    ctx.progress("structural base parameters (with friction and rotor inertia)", None)
    model = log_model(robot, sc.gravity_W, sc.data.unmeasured, sc.data.counterbalanced)
    if sc.data.delay != "none":
        ctx.progress("the torque channels' delays behind the encoders", None)
    delayed = delays(sc.data.delay, model, ctx.training)
    if sc.data.units["tau"] == "current" and sc.data.identify_constants:
        ctx.progress("torque constants (motor currents)", None)
    scaled = constants(sc.data, robot, model, delayed, ctx.payload)
    # the start check first, before any fit: the model as given against the torques as read (its
    # findings head the terminal and the report)
    q, qd, qdd, _ = model.data(scaled.training)
    given = model.torques(model.pm, q, qd, qdd)  # the model as given on the training span, judged again below
    def weightless() -> np.ndarray:  # a counterbalanced joint's reading: made only where the start check reads it
        return model.torques(build_model(robot, np.zeros(3)), q, qd, qdd)

    started = start(given, model.data(delayed.training)[3], model.torque_joints, weightless,
                    sc.data.counterbalanced)
    if sc.data.tilt != "declared":
        ctx.progress("gravity's direction in the base's axes (cross-validated within the training span)", None)
    tilt = gravity_of(sc.data.tilt, robot, sc.gravity_W, model, *model.data(fits_on(scaled.training)))
    if tilt.chosen:  # every fit and the exports at the torques' gravity, with its base parameters
        model = log_model(robot, tilt.gravity_W, sc.data.unmeasured, sc.data.counterbalanced)
    config = config or FrictionLawConfig()
    if config.choose:
        ctx.progress("the friction law of every joint (cross-validated within the training span)", None)
    # the model's regressor served the delays and the constants: let go of, the search and the fit
    # make theirs (one training regressor is held at a time)
    delayed = dataclasses.replace(delayed, W=None)
    laws = friction_laws(config, robot, model, joints, scaled.training)
    fitted = least_squares(robot, tilt.gravity_W, model, joints, scaled.training, laws, sc.data.repeat)
    ctx.progress("physically consistent parameters (semidefinite program)", None)
    tau = model.data(scaled.training)[3]
    fit, frictions = consistent.fit_with_laws(fitted.W, fitted.E, tau, laws.laws, model.theta,
                                              friction_values(robot.frictions), fitted.extra_model,
                                              robot.transmission, model.reach)
    frictions = identified_frictions(frictions, robot.frictions, model.drives_reached)
    identified = identified_spec(robot, fit.theta, frictions)
    # the validation span as the fit's findings make it, by the judging (the fit never reads it)
    validation = as_fitted(ctx.validation.get(VALIDATION_SPAN), delayed.lags if delayed.corrected else None,
                           None if scaled.scales is None else scaled.scales.factor, model.torque_joints)
    spans = {"training": scaled.training, **({"validation": validation} if validation is not None else {})}
    judged = judge(sc, model, spans, fitted, laws.laws, identified, given, tilt)
    ctx.progress("the models forward-simulated under the measured torques", None)
    span = "validation" if "validation" in spans else "training"
    q, qd, _ = judged.states[span]
    models = {"consistent": identified, "model as given": robot, **({"truth": sc.truth} if sc.truth else {})}
    gravities = {name: tilt.gravity_W if name == "consistent" else tilt.declared_W for name in models}
    predicted = prediction(gravities, models, judged.t[span], q, qd, judged.measured[span], span, joints,
                           not_made=_not_driven(sc.data, model), plan=sc.data.prediction)
    names = parameter_names(joints, True, robot.drive_names)
    exported = export_model(sc, tilt.gravity_W, robot, identified, frictions, fit.theta, scaled.training, fitted.W,
                            least_squares_fit(model, fitted, names, laws.laws, robot.drive_names, tilt.gravity_W))
    plausible = consistent.plausibility(fit.theta, model.theta, joints, fit.margin)
    li = LogIdentification(joints, robot.drive_names, names, model,
                           delayed, scaled, laws, fitted, fit,
                           frictions, plausible, judged, predicted, exported, started, tilt)
    li.warnings.extend(warnings(li, sc.data.delay))
    return li


def gravity_of(mode: str, robot, gravity_W: np.ndarray, model: LogModel, q: np.ndarray, qd: np.ndarray,
               qdd: np.ndarray, tau: np.ndarray) -> gravity.Tilt:
    """The gravity the fits use (harness/identify/gravity.py) from the training span's states and torques: its
    regressor at gravity 0 and along each axis, a chunk of samples at a time, on the base parameters' columns
    of gravity in no special direction (gravity.GENERIC_TURN): a turned gravity reaches parameters the declared
    one does not (a first link's first moment about a vertical first axis)."""
    if mode == "declared":
        return gravity.declared(gravity_W)
    generic = structural_base(build_model(robot, gravity.turned(gravity_W, gravity.GENERIC_TURN)), robot.limits,
                              with_friction=True, chain=model.chain, channels=model.channels,
                              weightless=model.weightless)
    pms = {None: build_model(robot, np.zeros(3)), **{i: build_model(robot, np.eye(3)[i]) for i in range(3)}}

    def rows(i: int | None, sl: slice) -> np.ndarray:
        W = model.rows(pms[i], q[sl], qd[sl], qdd[sl])
        return W.whole() if isinstance(W, RowsOnDemand) else W

    try:
        return gravity.tilt(mode, gravity_W, rows, tau, generic.independent, len(robot.joints))
    except (np.linalg.LinAlgError, ValueError) as exc:  # a search that fails is no verdict: the declared one kept
        return gravity.declared(gravity_W, mode, f"declared kept: the search failed ({exc})")


def _not_driven(data, model: LogModel) -> str | None:
    """Why the models are not forward-simulated under the measured torques, where they are not: joints
    without a torque to drive them, or a channel that lacks the counterweight's torque the model lacks."""
    if data.unmeasured:
        return f"not made: {', '.join(data.unmeasured)} without a measured torque to drive them ([data] unmeasured)"
    if model.weightless:
        return (f"not made: {', '.join(model.joints[k] for k in model.weightless)} held by a counterweight or spring "
                "the model does not have ([data] counterbalanced)")
    return None


def warnings(li: LogIdentification, mode: str) -> list[str]:
    """What the terminal is told of a log run, once."""
    out, lags = [], li.delayed.lags  # the start check's findings are its own (log_judge.Start.said), said first
    unmeasured = [j for j, m in zip(li.joints, li.model.measured, strict=True) if not m]
    if unmeasured:
        kept = [d for d, reached in zip(li.drives, li.model.drives_reached, strict=True) if not reached]
        out.append(f"torque channels unmeasured ([data] unmeasured): {', '.join(unmeasured)}: fitted and judged on the "
                   f"other {len(li.model.torque_joints)} channels, their joints' motion in the model; "
                   + (f"the friction and rotor inertia of {', '.join(kept)} (reaching no measured channel) the model's"
                      if kept else "every drive's friction and rotor inertia identified through the measured channels")
                   + "; no forward prediction (nothing drives them)")
    if li.model.weightless:
        out.append("counterbalanced channels ([data] counterbalanced) fitted without their joints' gravity: "
                   f"{', '.join(li.joints[k] for k in li.model.weightless)}; the exported model has no counterweight "
                   "or spring (a simulation of it needs one at those joints); no forward prediction")
    if li.gravity.chosen:
        g = li.gravity.gravity_W
        out.append(f"gravity as the torques give it, {li.gravity.reason}: [{g[0]:.4g}, {g[1]:.4g}, {g[2]:.4g}] "
                   "m/s^2 in the base's axes (the base mounted off level?); the fits, the consistent model's "
                   "prediction and the exports use it (identified/robot.xml's <option gravity>, robot.toml's [model] "
                   "gravity), [data] tilt = \"declared\" keeps the declared one (log_identification.gravity)")
    out += consistent.plausibility_warnings(li.plausible)
    out += consistent.band_warnings(li.fit, li.joints, li.model.theta)
    out += delay_warnings(lags, li.model.torque_joints, mode)
    out += [note for note in (li.delayed.note, li.laws.note, li.fitted.note) if note]
    repeated = li.fitted.repeated
    moved = [] if repeated is None else list(np.flatnonzero(~repeated.overlap))
    if moved:
        out.append(f"{len(moved)} base parameter(s) moved between the {repeated.segments} segments of the "
                   "training span more than their 95 % intervals allow (log_identification.repeatability)")
    c = li.constants.scales
    if c is not None and c.fixed_by == "model":
        out.append(f"torque constants identified up to one common scale, fixed by the model's own parameters (their "
                   f"median ratio to the fit's, {c.scale:.4g}, +-{100 * c.scale_std:.2g} %): every constant is as "
                   "right as the model's parameters are; a log with a known payload, [data.payload], fixes the scale")
    if li.fit.fallback:
        out.append(f"the consistent fit fell back ({consistent.FALLBACKS[li.fit.fallback]}): "
                   + "; ".join(li.fit.attempts))
    return out


def delay_warnings(lags: delay.Delays | None, joints: list[str], mode: str) -> list[str]:
    """What the terminal is told of the delays: those found beyond LAG_WARNING and left uncorrected, and
    those estimated but not found (at the search's edge, or beyond LAG_WARNING without the fit being
    clearly better for them), each with its estimate."""
    if lags is None:
        return []
    out = []
    lagging = [k for k in np.flatnonzero(lags.found) if abs(lags.delay[k]) > LAG_WARNING]
    if lagging and mode == "estimate":
        out.append("torque channels behind the encoders (estimated, not corrected; [data] delay = \"correct\" "
                   "shifts them): " + ", ".join(f"{joints[k]} {lags.delay[k] * 1e3:.2g} ms" for k in lagging))
    unsure = [k for k in np.flatnonzero(~lags.found) if lags.at_edge[k] or abs(lags.delay[k]) > LAG_WARNING]
    if unsure:
        out.append("torque channels' delays estimated but not found (at the search's edge, or the fit not clearly "
                   "better for them), not corrected: " + ", ".join(
                       f"{joints[k]} {lags.delay[k] * 1e3:.3g} ms{' (at the edge)' if lags.at_edge[k] else ''}"
                       for k in unsure))
    return out


def configure(t, scenario) -> FrictionLawConfig:
    """`[friction_law] choose = true, folds = 5, families = [...]`, validated (one-line errors
    naming the key). Only a `[data]` scenario reads it (runner/scenario.py refuses the table
    elsewhere, stages.LOG_TABLES). A closed chain's search has no families to choose from."""
    if scenario.robot.loops and t.has("families"):
        raise t.error("families", f"model {scenario.robot.name!r} is a closed chain: its search tries viscous and "
                                  "Coulomb friction alone (harness/identify/chain_law.py)")
    return FrictionLawConfig(
        t.boolean("choose", default=FrictionLawConfig.choose),
        t.integer("folds", default=FrictionLawConfig.folds, minimum=2),
        tuple(t.strings("families", choices=tuple(FAMILIES), default=list(FrictionLawConfig.families))))


STAGE = Stage("log_identification", "identification from the measured log", run, LogIdentification.serialise,
              "Identification from the log", files=lambda li: li.files, table="friction_law", configure=configure)
