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
A method whose tool is not installed is listed as skipped, with the reason; one whose fit raises an
exception is its row, failed, with what it raised (its gates fail: harness/runner/gates.py), and every
other result and the export are written. A method that ends the process or calls sys.exit is bad input,
as everywhere.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from harness.base.numerics import parameter_scale, relative_error
from harness.base.plugins import PluginError, PluginRaised, Stage, guard, inverse_dynamics
from harness.identify.consistent import consistency
from harness.model.friction import IDENTIFIED_KEYS, NONNEGATIVE_KEYS
from harness.stages.metrics import torque_errors
from harness.stages.plugin_fits import SkippedMethod, base_map, fit_method, reported

NONNEGATIVE = tuple(k for k in IDENTIFIED_KEYS if k in NONNEGATIVE_KEYS)  # rotor inertia, viscous, Coulomb
MAX_NOTE = 300  # characters of one of a method's notes kept
BUILT_IN = "harness (built in)"  # the plugin column of the harness's own two fits


@dataclass(frozen=True, eq=False)
class LogMethod:
    name: str
    plugin: str
    predictions: dict[str, np.ndarray]  # span -> (N, n) torques
    theta: np.ndarray | None = None  # (n, 10) its parameters, robot joint order, where it reports them
    friction: np.ndarray | None = None  # (n, 4) [armature, viscous, coulomb, offset], where it reports them
    seconds: float | None = None  # its fit's wall time (None: the harness's own fits)
    notes: tuple[str, ...] = ()
    rollouts: int | None = None  # the simulations it ran, where it reports them (`rollouts` of its fitted model)


@dataclass(frozen=True, eq=False)
class FailedMethod:
    """A method whose fit raised: its row says what, and its gates fail."""

    name: str
    plugin: str
    reason: str
    seconds: float

    def serialise(self) -> dict:
        return {"plugin": self.plugin, "failed": self.reason, "seconds": self.seconds}


@dataclass(frozen=True, eq=False)
class LogMethods:
    joints: list[str]
    methods: tuple[LogMethod | SkippedMethod | FailedMethod, ...]  # the harness's own two first
    measured: dict[str, np.ndarray]  # span -> (N, n) the torques the fits read
    truth: dict[str, np.ndarray]  # span -> the truth's torques at the same states (a bench log)

    def serialise(self, ctx, config) -> dict:
        """results.json's `identification_methods`: one row of the table per method, the harness's own two
        first (`harness_least_squares`, `harness_consistent`, names no plugin may take)."""
        out = {}
        for m in self.methods:
            if isinstance(m, SkippedMethod | FailedMethod):
                out[m.name] = m.serialise()
            elif m.plugin == BUILT_IN:
                out[m.name] = {"plugin": m.plugin, **self._row(ctx, m)}
            else:
                out[m.name] = {"plugin": m.plugin, "seconds": m.seconds, **self._row(ctx, m), "notes": list(m.notes),
                               **({"rollouts": m.rollouts} if m.rollouts is not None else {})}
        return out

    def _row(self, ctx, m: LogMethod) -> dict:
        errors = {span: torque_errors(pred, self.measured[span], self.joints) for span, pred in m.predictions.items()}
        row = {f"{span}_rel_error": e["rel_error"] for span, e in errors.items()}
        row["errors"] = errors
        if self.truth:
            span = "validation" if "validation" in self.truth else "training"
            row["truth"] = {"span": span, "validation_rel_error": torque_errors(
                m.predictions[span], self.truth[span], self.joints)["rel_error"]}
            if m.theta is not None:
                row["base_parameters"] = _against_truth(ctx, m.theta, m.friction)
        row["physical"] = _physical(self.joints, m.theta, m.friction)
        row["friction"] = None if m.friction is None else {
            j: dict(zip(IDENTIFIED_KEYS, map(float, m.friction[k]), strict=True)) for k, j in enumerate(self.joints)}
        return row


def _against_truth(ctx, theta: np.ndarray, friction: np.ndarray | None) -> dict:
    """The parameters reduced to the truth's structural base parameters: with friction and rotor
    inertia when the method reports them (the rotor inertia is grouped with the link inertias it
    cannot be told from), else the inertial ones alone."""
    bm = base_map(ctx, truth=True, with_friction=friction is not None)
    x = theta.ravel() if friction is None else np.concatenate([theta.ravel(), friction.ravel()])
    rel = relative_error(bm.T @ x, bm.true, parameter_scale(bm.true))
    k = int(np.argmax(rel))
    return {"count": len(bm.true), "with_friction": friction is not None, "max_rel_error": float(rel[k]),
            "max_rel_parameter": bm.expressions[k], "median_rel_error": float(np.median(rel))}


def _physical(joints: list[str], theta, friction) -> dict:
    links = None if theta is None else [j for k, j in enumerate(joints) if not consistency(theta[k])["consistent"]]
    negative = None if friction is None else [
        f"{j}.{key}" for k, j in enumerate(joints) for c, key in enumerate(IDENTIFIED_KEYS)
        if key in NONNEGATIVE and friction[k, c] < 0]
    return {"inconsistent_links": None if links is None else len(links), "links": links,
            "negative_count": None if negative is None else len(negative), "negative": negative}


def _notes(plugin: str, fitted) -> tuple[str, ...]:
    with guard(plugin, "reading the fitted model's notes"):
        notes = getattr(fitted, "notes", ()) or ()
        if isinstance(notes, str) or not all(isinstance(x, str) for x in notes):
            raise PluginError(plugin, "notes must be a sequence of strings")
        return tuple(" ".join(x.split())[:MAX_NOTE] for x in notes)


def _rollouts(plugin: str, fitted) -> int | None:
    with guard(plugin, "reading the fitted model's rollouts"):
        count = getattr(fitted, "rollouts", None)
        if count is not None and (isinstance(count, bool) or not isinstance(count, int | np.integer) or count < 0):
            raise PluginError(plugin, f"rollouts must be a count (a non-negative integer), not {count!r}")
        return None if count is None else int(count)


def _judge(ctx, entry, li) -> LogMethod | SkippedMethod | FailedMethod:
    if entry.skipped is not None:
        return SkippedMethod.of(entry)
    joints = ctx.scenario.robot.joint_names
    plugin = entry.reference
    ctx.progress(f"identification method {entry.name}", None)
    start = time.perf_counter()
    judged = li.judged
    try:
        fitted = fit_method(plugin, entry.instance, joints, *judged.states["training"], judged.measured["training"],
                            judged.t["training"])
    except PluginRaised as exc:
        return FailedMethod(entry.name, plugin, exc.message, time.perf_counter() - start)
    seconds = time.perf_counter() - start
    predictions = {span: inverse_dynamics(plugin, "inverse_dynamics of the fitted model", fitted, joints, *states)
                   for span, states in judged.states.items()}
    return LogMethod(entry.name, plugin, predictions, reported(plugin, fitted, "parameters", joints, 10),
                     reported(plugin, fitted, "friction", joints, 4), seconds, _notes(plugin, fitted),
                     _rollouts(plugin, fitted))


def run(ctx, config) -> LogMethods | None:
    sc = ctx.scenario
    li = ctx.done.get("log_identification")
    if not sc.methods or li is None:
        return None
    own = tuple(LogMethod(f"harness_{name.replace(' ', '_')}", BUILT_IN,
                          {span: pred[name] for span, pred in li.judged.predictions.items()}, theta, friction)
                for name, theta, friction in (("least squares", None, None),
                                              ("consistent", li.fit.theta, li.fit.friction)))
    return LogMethods(li.joints, own + tuple(_judge(ctx, e, li) for e in sc.methods), li.judged.measured,
                      li.judged.truth)


STAGE = Stage("identification_methods", "identification methods on the log", run, LogMethods.serialise,
              "Identification methods")
