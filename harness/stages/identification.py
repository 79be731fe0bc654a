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
    invoke,
)
from harness.torque_id import (
    BETA_FLOOR,
    TorqueIdentification,
    beta_scale,
    identify_from_torques,
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
class MethodResult:
    name: str
    reference: str
    base_rel_error: np.ndarray | None  # per base parameter, when the method reports parameters
    base_count: int
    validation: str | None  # the validation scenario's name
    validation_rel_error: np.ndarray | None  # (N_val, n) |predicted - recorded| / L_J
    validation_joints: list[str]


def _judge(ctx, entry) -> MethodResult:
    sc, method, plugin = ctx.scenario, entry.instance, entry.reference
    joints = sc.robot.joint_names
    to_method, _ = column_maps(method.joint_names, joints)
    q, qd, qdd, tau = joint_data(ctx.measured, joints)
    fitted = invoke(plugin, "fit", method.fit, q[:, to_method], qd[:, to_method], qdd[:, to_method],
                    tau[:, to_method])
    check_protocol(f"{plugin} (its fitted model)", fitted, ModelUnderTest, joints)
    base_rel, base_count = None, 0
    if getattr(fitted, "parameters", None) is not None:
        pm = build_model(sc.robot, sc.gravity_W)
        base = ctx.once(("structural base parameters", False), lambda: structural_base(pm, sc.robot.limits))
        base_count = len(base.independent)
        _, fit_to_robot = column_maps(fitted.joint_names, joints)
        theta = check_array(plugin, "parameters", fitted.parameters, (len(joints), 10))[fit_to_robot].reshape(-1)
        beta_true, beta = base.of(true_parameters(pm)), base.of(theta)
        base_rel = np.abs(beta - beta_true) / beta_scale(beta_true)
    validation = entry.validation or sc.torque_validation
    val_err = None
    if validation is not None:
        val = validation_recording(ctx, validation)
        qv, qdv, qddv, tauv = joint_data(val, joints)
        f_in, f_out = column_maps(fitted.joint_names, joints)
        pred = call(plugin, "inverse_dynamics of the fitted model", fitted.inverse_dynamics, qv[:, f_in],
                    qdv[:, f_in], qddv[:, f_in], shape=tauv.shape)[:, f_out]
        val_err = np.abs(pred - tauv) / joint_load_scale(sc.robot, val)
    if base_rel is None and val_err is None:
        raise PluginError(plugin, "cannot be judged: its fitted model reports no parameters and the scenario "
                                  "names no validation trajectory ([identification] validation = ...)")
    return MethodResult(entry.name, plugin, base_rel, base_count,
                        validation.name if validation is not None else None, val_err, joints)


def run_methods(ctx, config) -> tuple[MethodResult, ...] | None:
    if not ctx.scenario.methods:
        return None
    return tuple(_judge(ctx, e) for e in ctx.scenario.methods)


def serialise_methods(results: tuple[MethodResult, ...], ctx, config) -> dict:
    out = {}
    for r in results:
        entry = {"plugin": r.reference, "base_parameters": None, "validation": None}
        if r.base_rel_error is not None:
            entry["base_parameters"] = {
                "count": r.base_count,
                "max_rel_error": float(r.base_rel_error.max()),
                "rel_error_definition": f"|identified - true| / max(|true|, {BETA_FLOOR:g} x largest |true|), the "
                                        "structural base parameters of the robot (harness/torque_id.py)",
            }
        if r.validation_rel_error is not None:
            e = r.validation_rel_error
            _, j = np.unravel_index(np.argmax(e), e.shape)
            entry["validation"] = {
                "scenario": r.validation, "max_rel_error": float(e.max()), "max_rel_joint": r.validation_joints[j],
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
