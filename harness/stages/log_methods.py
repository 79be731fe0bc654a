"""Identification methods on a measured log, judged beside the harness's own fit.

Each method the scenario plugs in (`[identification]`, the door of harness/base/plugins.py) is given
the training span exactly as the harness's fit read it (the same conditioning, and the same delay
correction where the scenario asks for one) and predicts the torques of the validation span, which
neither fit sees. One table then holds, per method and for the harness's least squares and
consistent fit:
- the held-out error ||tau_pred - tau||_F / ||tau||_F on the validation span (and on the training span);
- on a bench log (`[data] truth`), the error against the robot that made the log: the predicted
  torques against the truth's at the same states, and, where the method reports parameters, the
  base parameters against the truth's (with friction and rotor inertia where it reports them:
  harness/identify/torque_id.py's structural base with friction);
- physical validity of what it reports: links whose pseudo-inertia is not positive semidefinite
  (harness/identify/consistent.py, `consistency`) and negative rotor inertias, viscous or Coulomb
  coefficients;
- the friction and rotor inertia it identifies, its own notes (what it cannot do or assumed), and the
  seconds of its fit.
A method whose tool is not installed is listed as skipped, with the reason.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from harness.base.numerics import parameter_scale, relative_error
from harness.base.plugins import PluginError, Stage, check_array, column_maps, guard, inverse_dynamics
from harness.engines.pinocchio import build_model
from harness.identify.consistent import consistency
from harness.identify.torque_id import describe_base, parameter_names, structural_base, true_parameters
from harness.model.friction import IDENTIFIED_KEYS
from harness.stages.identification import base_map, fit_method
from harness.stages.metrics import torque_errors

NONNEGATIVE = ("armature", "viscous", "coulomb")  # a drive's rotor inertia and dissipation; the offset has any sign
MAX_NOTE = 300  # characters of one of a method's notes kept


@dataclass(frozen=True, eq=False)
class LogMethod:
    name: str
    plugin: str
    skipped: str | None = None  # why it did not run (its tool is not installed)
    seconds: float | None = None  # its fit's wall time
    predictions: dict[str, np.ndarray] = field(default_factory=dict)  # span -> (N, n) torques
    theta: np.ndarray | None = None  # (n, 10) its parameters, robot joint order, where it reports them
    friction: np.ndarray | None = None  # (n, 4) [armature, viscous, coulomb, offset], where it reports them
    notes: tuple[str, ...] = ()


@dataclass(frozen=True, eq=False)
class LogMethods:
    joints: list[str]
    methods: tuple[LogMethod, ...]
    measured: dict[str, np.ndarray]  # span -> (N, n) the torques the fits read
    truth: dict[str, np.ndarray]  # span -> the truth's torques at the same states (a bench log)
    harness: dict[str, dict]  # the harness's own rows: "least squares", "consistent" -> what the table shows

    def serialise(self, ctx, config) -> dict:
        """results.json's `identification_methods`: one row of the table per method, the harness's own two
        first (`harness_least_squares`, `harness_consistent`, names no plugin may take)."""
        out = {f"harness_{name.replace(' ', '_')}": {"plugin": "harness (built in)", **row}
               for name, row in self.harness.items()}
        for m in self.methods:
            out[m.name] = {"plugin": m.plugin, "skipped": m.skipped} if m.skipped is not None else {
                "plugin": m.plugin, "seconds": m.seconds, **_row(ctx, self, m.predictions, m.theta, m.friction),
                "notes": list(m.notes)}
        return out


def _row(ctx, lm: LogMethods, predictions: dict, theta, friction) -> dict:
    errors = {span: torque_errors(pred, lm.measured[span], lm.joints) for span, pred in predictions.items()}
    row = {f"{span}_rel_error": e["rel_error"] for span, e in errors.items()}
    row["errors"] = errors
    if lm.truth:
        span = "validation" if "validation" in lm.truth else "training"
        row["truth"] = {"span": span, "validation_rel_error": torque_errors(predictions[span], lm.truth[span],
                                                                             lm.joints)["rel_error"]}
        if theta is not None:
            row["base_parameters"] = _against_truth(ctx, lm.joints, theta, friction)
    row["physical"] = _physical(lm.joints, theta, friction)
    row["friction"] = None if friction is None else {
        j: dict(zip(IDENTIFIED_KEYS, map(float, friction[k]), strict=True)) for k, j in enumerate(lm.joints)}
    return row


def _against_truth(ctx, joints: list[str], theta: np.ndarray, friction: np.ndarray | None) -> dict:
    """The parameters reduced to the truth's structural base parameters: with friction and rotor
    inertia when the method reports them (the rotor inertia is grouped with the link inertias it
    cannot be told from), else the inertial ones alone."""
    sc = ctx.scenario

    def make():
        pm = build_model(sc.truth, sc.gravity_W)
        base = structural_base(pm, sc.truth.limits, with_friction=True)
        return base, base.of(true_parameters(pm, with_friction=True))

    if friction is None:
        bm = base_map(ctx, truth=True)
        beta, true, expressions = bm.T @ theta.ravel(), bm.true, bm.expressions
    else:
        base, true = ctx.once(("truth's structural base with friction",), make)
        beta = base.of(np.concatenate([theta.ravel(), friction.ravel()]))
        expressions = [describe_base(parameter_names(joints, True), base, k) for k in range(len(true))]
    rel = relative_error(beta, true, parameter_scale(true))
    k = int(np.argmax(rel))
    return {"count": len(true), "with_friction": friction is not None, "max_rel_error": float(rel[k]),
            "max_rel_parameter": expressions[k], "median_rel_error": float(np.median(rel))}


def _physical(joints: list[str], theta, friction) -> dict:
    links = None if theta is None else [j for k, j in enumerate(joints) if not consistency(theta[k])["consistent"]]
    negative = None if friction is None else [
        f"{j}.{key}" for k, j in enumerate(joints) for c, key in enumerate(IDENTIFIED_KEYS)
        if key in NONNEGATIVE and friction[k, c] < 0]
    return {"inconsistent_links": None if links is None else len(links), "links": links,
            "negative_count": None if negative is None else len(negative), "negative": negative}


def _reported(plugin: str, fitted, what: str, joints: list[str], width: int) -> np.ndarray | None:
    """The fitted model's (n, width) `what` ("parameters" or "friction"), brought to the robot's joint order."""
    with guard(plugin, f"reading the fitted model's {what}"):
        value = getattr(fitted, what, None)
    if value is None:
        return None
    _, back = column_maps(fitted.joint_names, joints)
    return check_array(plugin, what, value, (len(joints), width))[back]


def _notes(plugin: str, fitted) -> tuple[str, ...]:
    with guard(plugin, "reading the fitted model's notes"):
        notes = getattr(fitted, "notes", ()) or ()
        if isinstance(notes, str) or not all(isinstance(x, str) for x in notes):
            raise PluginError(plugin, "notes must be a sequence of strings")
        return tuple(" ".join(x.split())[:MAX_NOTE] for x in notes)


def _judge(ctx, entry, li) -> LogMethod:
    joints = ctx.scenario.robot.joint_names
    plugin = entry.reference
    if entry.skipped is not None:
        return LogMethod(entry.name, plugin, skipped=entry.skipped)
    ctx.progress(f"identification method {entry.name}", None)
    start = time.perf_counter()
    fitted = fit_method(plugin, entry.instance, joints, *li.states["training"], li.measured["training"],
                        li.t["training"])
    seconds = time.perf_counter() - start
    predictions = {span: inverse_dynamics(plugin, "inverse_dynamics of the fitted model", fitted, joints, *states)
                   for span, states in li.states.items()}
    theta = _reported(plugin, fitted, "parameters", joints, 10)
    friction = _reported(plugin, fitted, "friction", joints, 4)
    return LogMethod(entry.name, plugin, None, seconds, predictions, theta, friction, _notes(plugin, fitted))


def run(ctx, config) -> LogMethods | None:
    sc = ctx.scenario
    li = ctx.done.get("log_identification")
    if not sc.methods or li is None:
        return None
    lm = LogMethods(li.joints, (), li.measured, li.truth, {})
    harness = {name: _row(ctx, lm, {span: pred[name] for span, pred in li.predictions.items()}, theta, friction)
               for name, theta, friction in (("least squares", None, None),
                                             ("consistent", li.fit.theta, li.fit.friction))}
    methods = tuple(_judge(ctx, e, li) for e in sc.methods)
    return LogMethods(li.joints, methods, li.measured, li.truth, harness)


STAGE = Stage("identification_methods", "identification methods on the log", run, LogMethods.serialise,
              "Identification methods")
