"""Identification from joint torques: the built-in method (harness/identify/torque_id.py) and every
identification method the scenario plugs in, on the same measured data and judged the same way.

Judged twice: the base parameters (the combinations of the 10 inertial parameters per body that
the torques determine, found from the Pinocchio regressor of the training data) against the
truth's, where the method reports parameters; and the torques the identified model predicts on a
validation trajectory it never saw, against the recorded ones, relative to each joint's load L_J.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from harness.base.numerics import NORMAL_975, PARAMETER_FLOOR, finite_or_null, parameter_scale, relative_error
from harness.base.plugins import PluginError, Stage, inverse_dynamics
from harness.engines.pinocchio import build_model
from harness.identify.floating_id import ROWS
from harness.identify.lstsq import WEAK_RATIO
from harness.identify.torque_fit import identify_from_torques
from harness.identify.torque_id import (
    COEFFICIENT_FLOOR,
    STRUCTURAL_STATES,
    WEAK_STRUCTURE,
    TorqueIdentification,
    describe_base,
)
from harness.identify.trials import over_trials
from harness.model import friction
from harness.stages.metrics import joint_load_scale
from harness.stages.plugin_fits import BaseMap, BaseTable, SkippedMethod, base_map, base_table, fit_method
from harness.stages.shared import TorqueConfig, chain_of, families_refused, structural_base_of, torque_config


def configure_torque(t, scenario) -> TorqueConfig:
    """`[torque_identification] validation = "other.toml", friction = true`, validated (one-line
    errors naming the key). `friction` defaults to whether the model declares any friction or rotor
    inertia. Where the validation moves a floating base (`[base_motion]`, as the scenario must:
    harness/sources/base_motion.py), `rows = "base"` or `"all"` (the default): the floating-base fit
    (harness/stages/floating_fit.py), friction only with the joints' rows, and `consistent = true` adds
    the physically consistent fit."""
    validation = scenario.related(t, "validation")
    if validation.robot.joint_names != scenario.robot.joint_names:
        raise t.error("validation", f"{t.data['validation']!r} simulates another robot than {scenario.robot.name!r}")
    declared = not all(f.none for f in scenario.robot.frictions)
    if getattr(validation, "base_motion", None) is None:
        for key in ("rows", "consistent"):
            if t.has(key):
                raise t.error(key, "a floating base's fit: the scenario and its validation need [base_motion]")
        return TorqueConfig(validation, t.boolean("friction", default=declared))
    rows = t.string("rows", default="all", choices=ROWS)
    fit_friction = t.boolean("friction", default=declared and rows == "all")
    if fit_friction and (why := families_refused(scenario.robot, "a floating base's fit identifies")):
        raise t.error("friction", why)
    if fit_friction and rows == "base":
        raise t.error("friction", "the joints' friction and rotor inertia never reach the base rows: rows = \"all\" "
                                  "identifies them on the joints' own")
    return TorqueConfig(validation, fit_friction, rows, t.boolean("consistent", default=False))


def run_builtin(ctx, config: TorqueConfig | None) -> BuiltinIdentification | None:
    if config is None:
        return None
    if config.rows is not None:  # a floating base the bench moves
        from harness.stages.floating_fit import identify

        ti, floating, files = identify(ctx, config)
        return BuiltinIdentification(ti, config.validation.name, floating, files)
    sc = ctx.scenario
    joints = sc.robot.joint_names
    val = ctx.recorded(config.validation)
    pm = build_model(sc.robot, sc.gravity_W)
    chain = chain_of(sc.robot)  # a closed chain: its actuated joints' torques, through G^T Y
    torques = slice(None) if chain is None else list(chain.actuated)
    (q, qd, qdd, tau), (qv, qdv, qddv, tauv) = ctx.training.joint_data(joints), val.joint_data(joints)
    ti = identify_from_torques(pm, joints, q, qd, qdd, tau[:, torques], (qv, qdv, qddv, tauv[:, torques]),
                               structural_base_of(ctx), chain)
    ti.validation_scale = joint_load_scale(sc.robot, val)[torques]
    ti.torque_joints = None if chain is None else list(sc.robot.actuated)
    return BuiltinIdentification(ti, config.validation.name)


@dataclass(frozen=True, eq=False)
class BuiltinIdentification:
    """The run's joint-torque identification (harness/identify/torque_id.py) and the name of the
    validation trajectory it was judged on."""

    fit: TorqueIdentification
    validation: str
    floating: dict | None = None  # a moving floating base's fit: its rows, method and counts (stages/floating_fit.py)
    files: dict | None = None  # its consistent fit's export: {path in the output folder: text}

    def serialise(self, ctx, config) -> dict:
        """results.json's `torque_identification`: the base parameters against the robot's, their
        intervals and identifiability, the friction terms and the validation trajectory's torques."""
        ti = self.fit
        rel = relative_error(ti.beta, ti.beta_true, parameter_scale(ti.beta_true))
        weak = ti.weak
        out = {
            "method": "joint torques only: Pinocchio's joint torque regressor, base parameters by QR with column "
                      f"pivoting of the regressor at {STRUCTURAL_STATES} random states (the model's structure), "
                      "least squares (harness/identify/torque_id.py)",
            "parameters": len(ti.names), "base_parameters": len(ti.beta),
            "condition_number": ti.condition_number,
            "rel_error_definition": f"|identified - true| / max(|true|, {PARAMETER_FLOOR:g} x largest |true|)",
            "uncertainty": "std and 95 % interval from the cluster-robust (CR3) covariance over the samples, "
                           "t quantile with N - 1 degrees of freedom; infinite where the data leave a direction "
                           "undetermined (harness/identify/lstsq.py)",
            "weak_definition": f"identifiable, but its sensitivity to the data is more than {WEAK_RATIO:g} times the "
                               "median base parameter's (harness/identify/lstsq.py), or it exists only through a "
                               f"feature of the robot: its column under {WEAK_STRUCTURE:g} of its kind's, or nearly "
                               "collinear with the others (harness/identify/torque_id.py, structurally_weak); its "
                               "error is reported apart from max_rel_error",
            "max_rel_error": float(rel[~weak].max(initial=0.0)),
            "max_rel_parameter": (ti.expression(int(np.flatnonzero(~weak)[np.argmax(rel[~weak])]))
                                  if (~weak).any() else None),
            "weakly_identifiable": [ti.expression(k) for k in np.flatnonzero(weak)],
            "max_rel_error_weak": float(rel[weak].max()) if weak.any() else None,
            "coverage_ci95": float(np.mean(np.abs(ti.beta - ti.beta_true) <= ti.ci_half_width)),
            "base": [{"expression": ti.expression(k), "true": float(ti.beta_true[k]),
                      "identified": float(ti.beta[k]),
                      "rel_error": float(rel[k]), "std": finite_or_null(ti.std[k]),
                      "ci95": [finite_or_null(ti.beta[k] - ti.ci_half_width[k]),
                               finite_or_null(ti.beta[k] + ti.ci_half_width[k])],
                      "undetermined": bool(np.isinf(ti.std[k])),
                      "sensitivity": finite_or_null(ti.sensitivity[k]), "weakly_identifiable": bool(weak[k])}
                     for k in range(len(ti.beta))],
            "validation": None,
            "friction": self.friction_terms() if ti.base.with_friction else None,
            **(self.floating or {}),
        }
        if ti.validation_error is not None:
            err = relative_error(ti.validation_error, 0.0, ti.validation_scale)
            _, worst_joint = np.unravel_index(np.argmax(err), err.shape)
            out["validation"] = {"scenario": self.validation, "max_rel_error": float(err.max()),
                                 "max_rel_joint": (ti.torque_joints[worst_joint] if ti.torque_joints else
                                                   ti.names[10 * worst_joint].rsplit(".", 1)[0]),
                                 "rms_rel_error": float(np.sqrt(np.mean(err**2))),
                                 "definition": "|predicted - recorded torque| / L_J of the validation run" + (
                                     "; a base row's, |predicted - recorded| / the largest |F_W| or |M_W| of the "
                                     "world's wrench on the base over the run" if self.floating else "")}
        return out

    def friction_terms(self) -> dict:
        """Each joint's friction and rotor inertia: identified where it is a base parameter on its own,
        else the base parameter it enters (a vertical first joint's armature adds to its link's I_zz); a
        friction family's coefficients (Stribeck, asymmetries, load, spring) after them, each its own."""
        ti = self.fit
        r = len(ti.base.independent)
        alone = {ti.base.independent[k]: k for k in range(r)
                 if not np.any(np.abs(ti.base.combination[k]) > COEFFICIENT_FLOOR)}
        alone |= {len(ti.names) + i: r + i for i in range(len(ti.families))}  # each family coefficient its own
        joints: dict[str, dict] = {}
        errors, where = [], []
        for c, name in enumerate([*ti.names, *ti.families]):
            joint, term = name.rsplit(".", 1)
            if term not in friction.IDENTIFIED_KEYS + friction.EXTRA_KEYS:
                continue
            k = alone.get(c)
            true = float(ti.beta_true[k]) if k is not None else None
            if k is None:
                entry = {"in": next((describe_base(ti.names, ti.base, b) for b in range(r)
                                     if ti.base.independent[b] == c or c in ti.base.dependent[
                                         np.abs(ti.base.combination[b]) > COEFFICIENT_FLOOR]), None)}
            else:
                rel = float(relative_error(ti.beta[k], ti.beta_true[k],
                                           max(abs(ti.beta_true[k]), PARAMETER_FLOOR)))
                errors.append(rel)
                where.append(name)
                entry = {"true": true, "identified": float(ti.beta[k]), "rel_error": float(rel)}
            joints.setdefault(joint, {})[term] = entry
        return {"definition": "per joint and term; rel_error = |identified - true| / max(|true|, 1e-6) where the term "
                              "is a base parameter on its own, else `in` names the base parameter it enters",
                "max_rel_error": max(errors, default=None),
                "max_rel_parameter": where[int(np.argmax(errors))] if errors else None, "joints": joints}


@dataclass(frozen=True, eq=False)
class MethodResult:
    name: str
    reference: str
    base: BaseTable | None  # when the method reports parameters
    validation: str | None  # the validation scenario's name
    validation_rel_error: np.ndarray | None  # (N_val, n) |predicted - recorded| / L_J
    validation_t: np.ndarray | None
    validation_joints: list[str]

    def serialise(self) -> dict:
        """This method's entry in results.json's `identification_methods`."""
        entry = {"plugin": self.reference, "base_parameters": None, "validation": None}
        if self.base is not None:
            b, rel = self.base, self.base.rel_error
            worst = int(np.argmax(rel))
            entry["base_parameters"] = {
                "count": len(b.true),
                "max_rel_error": float(rel[worst]),
                "max_rel_parameter": b.expressions[worst],
                "rel_error_definition": f"|identified - true| / max(|true|, {PARAMETER_FLOOR:g} x largest |true|), the "
                                        "structural base parameters of the robot (harness/identify/torque_id.py)",
                "uncertainty": ("std from the method's covariance of its parameters, carried to the base parameters "
                                "(T Sigma T^T); ci95 = identified +- 1.96 std" if b.std is not None else
                                "the method gives no covariance"),
                "coverage_ci95": (float(np.mean(np.abs(b.identified - b.true) <= NORMAL_975 * b.std))
                                  if b.std is not None else None),
                "base": [{"expression": b.expressions[k], "true": float(b.true[k]),
                          "identified": float(b.identified[k]), "rel_error": float(rel[k]),
                          "std": None if b.std is None else float(b.std[k]),
                          "ci95": None if b.std is None else [float(b.identified[k] - NORMAL_975 * b.std[k]),
                                                              float(b.identified[k] + NORMAL_975 * b.std[k])]}
                         for k in range(len(b.true))],
            }
        if self.validation_rel_error is not None:
            e = self.validation_rel_error
            k, j = np.unravel_index(np.argmax(e), e.shape)
            entry["validation"] = {
                "scenario": self.validation, "max_rel_error": float(e.max()),
                "max_rel_joint": self.validation_joints[j], "max_rel_t": float(self.validation_t[k]),
                "rms_rel_error": float(np.sqrt(np.mean(e**2))),
                "max_rel_error_per_joint": dict(zip(self.validation_joints, (float(x) for x in e.max(axis=0)),
                                                    strict=True)),
                "definition": "|predicted - recorded torque| / L_J of the validation run"}
        return entry


def _judge(ctx, entry) -> MethodResult:
    sc, plugin = ctx.scenario, entry.reference
    joints = sc.robot.joint_names
    fitted = fit_method(plugin, entry.instance, joints, *ctx.training.joint_data(joints), ctx.training.t)
    table = base_table(plugin, fitted, joints, base_map(ctx))
    validation = entry.validation or _validation_of(sc)
    val_err = val_t = None
    if validation is not None:
        val = ctx.recorded(validation)
        qv, qdv, qddv, tauv = val.joint_data(joints)
        pred = inverse_dynamics(plugin, "inverse_dynamics of the fitted model", fitted, joints, qv, qdv, qddv)
        val_err, val_t = relative_error(pred, tauv, joint_load_scale(sc.robot, val)), val.t
    if table is None and val_err is None:
        raise PluginError(plugin, "cannot be judged: its fitted model reports no parameters and the scenario "
                                  "names no validation trajectory ([identification] validation = ...)")
    return MethodResult(entry.name, plugin, table, validation.name if validation is not None else None, val_err,
                        val_t, joints)


@dataclass(frozen=True, eq=False)
class MethodResults:
    """Every identification method the scenario plugs in, judged."""

    methods: tuple[MethodResult | SkippedMethod, ...]

    def serialise(self, ctx, config) -> dict:
        """results.json's `identification_methods`: per method, its base parameters against the robot's
        and its torques on the validation trajectory."""
        return {r.name: r.serialise() for r in self.methods}


def run_methods(ctx, config) -> MethodResults | None:
    if not ctx.scenario.methods:
        return None
    return MethodResults(tuple(SkippedMethod.of(e) if e.skipped is not None else _judge(ctx, e)
                               for e in ctx.scenario.methods))


def _validation_of(scenario):
    config = torque_config(scenario)
    return None if config is None else config.validation


def _method_recordings(config, scenario) -> tuple:
    """The validation trajectories of the methods: each one's own, else the torque identification's."""
    return tuple(v for v in (e.validation or _validation_of(scenario) for e in scenario.methods
                             if e.skipped is None) if v is not None)


TORQUE_STAGE = Stage("torque_identification", "joint-torque identification (base parameters)", run_builtin,
                     BuiltinIdentification.serialise, "Torque identification", table="torque_identification",
                     files=lambda result: (result.files or {}) if result is not None else {},
                     configure=configure_torque, recordings=lambda c, sc: (c.validation,) if c is not None else ())
METHODS_STAGE = Stage("identification_methods", "identification methods under test", run_methods,
                      MethodResults.serialise, "Identification methods", recordings=_method_recordings)


# --- a method under measurement noise: `harness sweep` ---------------------------------------------


@dataclass(frozen=True, eq=False)
class _MethodBench:
    """What every trial of one method shares, sent once to each worker: the truth, its measurement,
    the method (rebuilt on the worker from what the scenario names) and the validation data."""

    entry: Any  # harness.runner.scenario.PluginEntry, without its instance where it can be built again
    rec: Any  # the ideal recording
    m: Any  # the scenario's measurement
    joints: list[str]
    bm: BaseMap
    validation: tuple | None  # (q, q', q'', tau, L_J) of the validation trajectory


def _method_setup(bench: _MethodBench) -> tuple:
    """Once per worker: the method built from what the scenario names (its module imported there: on
    a remote worker it must be importable at the same path, or installed), or the object handed to
    the API (forked workers inherit it; Dask workers receive it pickled)."""
    return bench, bench.entry.rebuilt()


def _method_trial(state: tuple, k: int) -> tuple:
    """Trial k: the measurement drawn from seed + k, the method's fit, its base parameters (and
    standard deviations) and its largest validation error."""
    from harness.sources.measurement import measure

    b, method = state
    plugin = b.entry.reference
    meas = measure(b.rec, b.m.with_seed(b.m.seed + k))
    fitted = fit_method(plugin, method, b.joints, *meas.joint_data(b.joints), meas.t)
    table = base_table(plugin, fitted, b.joints, b.bm)
    val = None
    if b.validation is not None:
        qv, qdv, qddv, tauv, load = b.validation
        pred = inverse_dynamics(plugin, "inverse_dynamics of the fitted model", fitted, b.joints, qv, qdv, qddv)
        val = float(np.max(relative_error(pred, tauv, load)))
    if table is None:
        return None, None, val
    return table.identified, table.std, val


def sweep_methods(ctx, trials: int) -> dict:
    """Every identification method of the scenario over `trials` measurements of its recording
    (noise from seeds seed, seed + 1, ...), on `ctx.workers`: per base parameter its bias, spread,
    RMS error and, where the method gives a covariance, the coverage of its 95 % intervals."""
    import dataclasses

    sc = ctx.scenario
    joints = sc.robot.joint_names
    bm = base_map(ctx)
    out = {}
    for entry in sc.methods:
        if entry.skipped is not None:
            out[entry.name] = SkippedMethod.of(entry).serialise()
            continue
        validation = entry.validation or _validation_of(sc)
        val = None
        if validation is not None:
            vrec = ctx.recorded(validation)
            val = (*vrec.joint_data(joints), joint_load_scale(sc.robot, vrec))
        shipped = entry if entry.recipe is None else dataclasses.replace(entry, instance=None, validation=None)
        bench = _MethodBench(shipped, ctx.truth, sc.measurement, joints, bm, val)
        label = f"identification method {entry.name}"
        ctx.progress(label, 0.0)
        rows = ctx.workers.map(_method_setup, (bench,), _method_trial, range(trials),
                               lambda done, total, label=label: ctx.progress(label, done / total))
        out[entry.name] = _method_statistics(entry, rows, bm)
    return out


def _method_statistics(entry, rows: list[tuple], bm: BaseMap) -> dict:

    vals = [r[2] for r in rows if r[2] is not None]
    summary: dict = {"plugin": entry.reference, "trials": len(rows),
                     "validation_rel_error_mean": float(np.mean(vals)) if vals else None,
                     "validation_rel_error_max": float(np.max(vals)) if vals else None,
                     "base_parameters": None}
    if rows and rows[0][0] is not None:
        beta = np.stack([r[0] for r in rows])  # (trials, r)
        with_std = all(r[1] is not None for r in rows)
        half = NORMAL_975 * np.stack([r[1] for r in rows]) if with_std else None
        s = over_trials(beta - bm.true, half, parameter_scale(bm.true))
        lo, hi = s.band
        summary["base_parameters"] = {
            "definition": "per base parameter over the trials: bias = mean error, bias_in_sd = |bias| / the error's "
                          "standard deviation over the trials, significant where |bias| > 3 standard errors of the "
                          "mean; rms_rel_error = RMS error / max(|true|, 1e-6 x largest); coverage of the method's "
                          "95 % intervals (identified +- 1.96 std) where it gives a covariance",
            "count": len(bm.true),
            "max_bias_in_sd": float(np.max(s.bias_in_sd)), "median_bias_in_sd": float(np.median(s.bias_in_sd)),
            "significant_biases": int(s.significant.sum()),
            "median_rms_rel_error": float(np.median(s.rms_rel_error)),
            "max_rms_rel_error": float(np.max(s.rms_rel_error)),
            "coverage_band": [float(lo), float(hi)],
            "coverage_min": float(s.coverage.min()) if with_std else None,
            "coverage_median": float(np.median(s.coverage)) if with_std else None,
            "coverage_max": float(s.coverage.max()) if with_std else None,
            "coverage_outside_band": int(np.sum((s.coverage < lo) | (s.coverage > hi))) if with_std else None,
            "base": [{"expression": bm.expressions[k], "true": float(bm.true[k]), "bias": float(s.bias[k]),
                      "spread": float(s.spread[k]), "bias_in_sd": float(s.bias_in_sd[k]),
                      "significant": bool(s.significant[k]), "rms_rel_error": float(s.rms_rel_error[k]),
                      "coverage": float(s.coverage[k]) if with_std else None} for k in range(len(bm.true))],
        }
    return summary
