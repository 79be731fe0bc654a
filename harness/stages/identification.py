"""Identification from joint torques: the built-in method (harness/torque_id.py) and every
identification method the scenario plugs in, on the same measured data and judged the same way.

Judged twice: the base parameters (the combinations of the 10 inertial parameters per body that
the torques determine, found from the Pinocchio regressor of the training data) against the
truth's, where the method reports parameters; and the torques the identified model predicts on a
validation trajectory it never saw, against the recorded ones, relative to each joint's load L_J.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from harness.bench import record
from harness.compare import joint_load_scale
from harness.engines.pinocchio import build_model
from harness.plugins import (
    ModelUnderTest,
    PluginError,
    Stage,
    call,
    check_array,
    check_protocol,
    column_maps,
    guard,
    invoke,
)
from harness.torque_id import (
    BETA_FLOOR,
    TorqueIdentification,
    beta_scale,
    describe_base,
    identify_from_torques,
    parameter_names,
    structural_base,
    true_parameters,
)
from harness.torque_id import section as torque_id_section


def joint_data(rec, joints: list[str]) -> tuple[np.ndarray, ...]:
    """(q, q', q'', tau) of a recording in the given joint order, each (N, n)."""
    cols = [rec.joint_index(j) for j in joints]
    return rec.q[:, cols], rec.qd[:, cols], rec.qdd[:, cols], rec.tau[:, cols]


def validation_recording(ctx, scenario):
    """The validation scenario simulated once per run, whichever stage asks first."""
    def make():
        ctx.progress(f"simulating the validation trajectory {scenario.name}", None)
        return record(scenario)

    return ctx.once(("validation recording", str(scenario.source)), make)


def run_builtin(ctx, config) -> TorqueIdentification | None:
    sc = ctx.scenario
    if sc.torque_validation is None:
        return None
    joints = sc.robot.joint_names
    val = validation_recording(ctx, sc.torque_validation)
    pm = build_model(sc.robot, sc.gravity_W)
    base = ctx.once(("structural base parameters", sc.torque_friction),
                    lambda: structural_base(pm, sc.robot.limits, with_friction=sc.torque_friction))
    ti = identify_from_torques(pm, joints, *joint_data(ctx.measured, joints), joint_data(val, joints), base)
    ti.validation_scale = joint_load_scale(sc.robot, val)
    return ti


def serialise_builtin(ti: TorqueIdentification, ctx, config) -> dict:
    return torque_id_section(ti, ctx.scenario.torque_validation.name)


@dataclass(frozen=True, eq=False)
class BaseTable:
    """A method's parameters reduced to the robot's structural base parameters (harness/torque_id.py)."""

    expressions: list[str]  # each base parameter as the combination of standard parameters it stands for
    true: np.ndarray  # (r,) the robot's
    identified: np.ndarray  # (r,) the method's
    std: np.ndarray | None  # (r,) from the method's covariance, when it gives one

    @property
    def rel_error(self) -> np.ndarray:
        return np.abs(self.identified - self.true) / beta_scale(self.true)


@dataclass(frozen=True, eq=False)
class MethodResult:
    name: str
    reference: str
    base: BaseTable | None  # when the method reports parameters
    validation: str | None  # the validation scenario's name
    validation_rel_error: np.ndarray | None  # (N_val, n) |predicted - recorded| / L_J
    validation_t: np.ndarray | None
    validation_joints: list[str]


def base_table(ctx, plugin: str, fitted, joints: list[str]) -> BaseTable | None:
    """The fitted model's `parameters` ((n, 10), its joint order) and, when given, `covariance`
    ((10 n, 10 n), of those parameters flattened row by row) as the robot's structural base
    parameters beta = T theta, with covariance T Sigma T^T. None: it reports no parameters."""
    sc = ctx.scenario
    with guard(plugin, "reading the fitted model's parameters"):
        theta, cov = getattr(fitted, "parameters", None), getattr(fitted, "covariance", None)
    if theta is None:
        return None
    pm = build_model(sc.robot, sc.gravity_W)
    base = ctx.once(("structural base parameters", False), lambda: structural_base(pm, sc.robot.limits))
    n = len(joints)
    _, fit_to_robot = column_maps(fitted.joint_names, joints)
    order = (np.asarray(fit_to_robot)[:, None] * 10 + np.arange(10)).reshape(-1)  # theta's entries, robot order
    theta = check_array(plugin, "parameters", theta, (n, 10)).reshape(-1)[order]
    T = np.zeros((len(base.independent), 10 * n))
    T[np.arange(len(base.independent)), base.independent] = 1.0
    T[:, base.dependent] = base.combination
    std = None
    if cov is not None:
        cov = check_array(plugin, "covariance", cov, (10 * n, 10 * n))[np.ix_(order, order)]
        var = np.einsum("ij,jk,ik->i", T, cov, T)
        if np.any(var < -1e-12 * np.max(np.abs(var), initial=0.0)):
            raise PluginError(plugin, "covariance is not positive semidefinite on the base parameters")
        std = np.sqrt(np.maximum(var, 0.0))
    names = parameter_names(joints)
    return BaseTable([describe_base(names, base, k) for k in range(len(base.independent))],
                     base.of(true_parameters(pm)), T @ theta, std)


def fit_method(plugin: str, method, joints: list[str], q, qd, qdd, tau):
    """A method's fit on measured (q, q', q'', tau) in the robot's joint order; the fitted model,
    checked against the model-under-test protocol."""
    to_method, _ = column_maps(method.joint_names, joints)
    fitted = invoke(plugin, "fit", method.fit, q[:, to_method], qd[:, to_method], qdd[:, to_method],
                    tau[:, to_method])
    check_protocol(f"{plugin} (its fitted model)", fitted, ModelUnderTest, joints)
    return fitted


def _judge(ctx, entry) -> MethodResult:
    sc, plugin = ctx.scenario, entry.reference
    joints = sc.robot.joint_names
    fitted = fit_method(plugin, entry.instance, joints, *joint_data(ctx.measured, joints))
    table = base_table(ctx, plugin, fitted, joints)
    validation = entry.validation or sc.torque_validation
    val_err = val_t = None
    if validation is not None:
        val = validation_recording(ctx, validation)
        qv, qdv, qddv, tauv = joint_data(val, joints)
        f_in, f_out = column_maps(fitted.joint_names, joints)
        pred = call(plugin, "inverse_dynamics of the fitted model", fitted.inverse_dynamics, qv[:, f_in],
                    qdv[:, f_in], qddv[:, f_in], shape=tauv.shape)[:, f_out]
        val_err, val_t = np.abs(pred - tauv) / joint_load_scale(sc.robot, val), val.t
    if table is None and val_err is None:
        raise PluginError(plugin, "cannot be judged: its fitted model reports no parameters and the scenario "
                                  "names no validation trajectory ([identification] validation = ...)")
    return MethodResult(entry.name, plugin, table, validation.name if validation is not None else None, val_err,
                        val_t, joints)


def run_methods(ctx, config) -> tuple[MethodResult, ...] | None:
    if not ctx.scenario.methods:
        return None
    return tuple(_judge(ctx, e) for e in ctx.scenario.methods)


CI95 = 1.959963984540054  # the normal 97.5 % quantile: a method's covariance states no degrees of freedom


def serialise_methods(results: tuple[MethodResult, ...], ctx, config) -> dict:
    out = {}
    for r in results:
        entry = {"plugin": r.reference, "base_parameters": None, "validation": None}
        if r.base is not None:
            b, rel = r.base, r.base.rel_error
            worst = int(np.argmax(rel))
            entry["base_parameters"] = {
                "count": len(b.true),
                "max_rel_error": float(rel[worst]),
                "max_rel_parameter": b.expressions[worst],
                "rel_error_definition": f"|identified - true| / max(|true|, {BETA_FLOOR:g} x largest |true|), the "
                                        "structural base parameters of the robot (harness/torque_id.py)",
                "uncertainty": ("std from the method's covariance of its parameters, carried to the base parameters "
                                "(T Sigma T^T); ci95 = identified +- 1.96 std" if b.std is not None else
                                "the method gives no covariance"),
                "coverage_ci95": (float(np.mean(np.abs(b.identified - b.true) <= CI95 * b.std))
                                  if b.std is not None else None),
                "base": [{"expression": b.expressions[k], "true": float(b.true[k]),
                          "identified": float(b.identified[k]), "rel_error": float(rel[k]),
                          "std": None if b.std is None else float(b.std[k]),
                          "ci95": None if b.std is None else [float(b.identified[k] - CI95 * b.std[k]),
                                                              float(b.identified[k] + CI95 * b.std[k])]}
                         for k in range(len(b.true))],
            }
        if r.validation_rel_error is not None:
            e = r.validation_rel_error
            k, j = np.unravel_index(np.argmax(e), e.shape)
            entry["validation"] = {
                "scenario": r.validation, "max_rel_error": float(e.max()), "max_rel_joint": r.validation_joints[j],
                "max_rel_t": float(r.validation_t[k]),
                "rms_rel_error": float(np.sqrt(np.mean(e**2))),
                "max_rel_error_per_joint": dict(zip(r.validation_joints, (float(x) for x in e.max(axis=0)),
                                                    strict=True)),
                "definition": "|predicted - recorded torque| / L_J of the validation run"}
        out[r.name] = entry
    return out


def _render_builtin(results: dict, rec) -> str:
    from harness.report.sections import torque_identification

    return torque_identification(results)


def _render_methods(results: dict, rec) -> str:
    from harness.report.sections import identification_methods

    return identification_methods(results)


TORQUE_STAGE = Stage("torque_identification", "joint-torque identification (base parameters)", run_builtin,
                     serialise_builtin, "Torque identification", _render_builtin)
METHODS_STAGE = Stage("identification_methods", "identification methods under test", run_methods,
                      serialise_methods, "Identification methods", _render_methods)
