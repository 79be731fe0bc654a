"""Section 2.3 on the bench: the paper's identification form (Eqs. 49-64) and the form with all 10
inertial parameters per body, solved by least squares with the measurement-error floor of each
column (harness/identify/lstsq.py); and the results.json sections of the paper's stages."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from harness.base.numerics import finite_or_null, floats
from harness.base.reference import reference_table
from harness.base.series import TimeSeries
from harness.identify.lstsq import WEAK_RATIO, Estimate, solve, weakly_identifiable
from harness.model.inertia import kind_scale
from harness.model.spec import RobotSpec
from harness.papers.graph_theory_2021.dynamics import GraphModel, Residual, body_series
from harness.papers.graph_theory_2021.full import FULL_PARAMETERS, full_form
from harness.papers.graph_theory_2021.identification import PARAMETERS, id_Y, id_Z, stack_per_body, stack_system
from harness.papers.graph_theory_2021.lagrange import LagrangeOutput, reactions_at
from harness.papers.graph_theory_2021.readings import dither
from harness.sources.measurement import Measurement
from harness.stages.metrics import largest

PACKAGE = "harness.papers.graph_theory_2021"  # its reference tables are in its reference/ folder


@dataclass(frozen=True, eq=False)
class Identification:
    bodies: tuple[str, ...]
    per_body: tuple[Estimate, ...]
    system: Estimate | None  # Eqs. 57-64, all bodies at once (None when not asked for)
    true: np.ndarray  # (n, 6) the true values (m, m, m, J11, J22, J33)
    sample_times: np.ndarray
    resolution: float  # relative resolution of the measurement the floors were taken at

    def serialise(self, ctx, config) -> dict:
        """results.json's `identification`: section 2.3's estimates against the truth and, where the
        study names them, against the paper's Tables 3 and 4."""
        return identification_section(self, config.paper_identified, config.paper_abs_error,
                                      ctx.scenario.measurement.significant_digits)


N_DITHER = 4  # draws for the regressor's measurement-error floor (a size, not a statistic)


def _regressor(model: GraphModel, rec: TimeSeries, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The paper's identification form (Eqs. 49-51) at the given rows: id_Y, id_Z."""
    s = body_series(rec, model.topology, rows)
    return id_Y(s, model.g_W), id_Z(s)


def measured_rows(measured: TimeSeries, times: np.ndarray) -> np.ndarray:
    """Rows of a (possibly subsampled) measured recording at the given times."""
    dt = measured.t[1] - measured.t[0] if len(measured.t) > 1 else 1.0
    return np.array([int(np.argmin(np.abs(measured.t - ts))) for ts in times
                     if np.min(np.abs(measured.t - ts)) <= 1e-9 * dt], dtype=int)


def _solve_per_body(form: Callable[[TimeSeries], tuple[np.ndarray, np.ndarray]], measured: TimeSeries,
                    measurement: Measurement, names: tuple[str, ...], scale: np.ndarray):
    """Per-body least squares of a regressor form Y x = Z (Y: (N, n, rows, p)), each column judged
    against its measurement-error floor: Y rebuilt from the measured channels moved within the
    measurement's errors (fixed seed, so a run is reproducible), the rms change of each column.
    scale: (n, p) the parameters' magnitudes in the model's own values (for the sensitivities).
    Returns Y, Z, the floors and the per-body solutions."""
    Y, Z = form(measured)
    rng = np.random.default_rng(0)
    dY = [form(dither(measured, measurement, rng))[0] - Y for _ in range(N_DITHER)]
    K, L = stack_per_body(Y, Z)
    floor = np.sqrt(np.mean([np.linalg.norm(stack_per_body(d, Z)[0], axis=1) ** 2 for d in dY], axis=0))
    N, n, k = Y.shape[:3]
    sample, channel = np.repeat(np.arange(N), k), np.tile(np.arange(k), N)  # rows of one body
    per_body = [solve(K[i], L[i], names, floor[i], sample, channel, scale[i]) for i in range(n)]
    # weak against the median over all bodies: one body's few parameters are no population
    weak = weakly_identifiable(np.concatenate([ls.sensitivity for ls in per_body])).reshape(n, -1)
    return Y, Z, floor, tuple(replace(ls, weak=w) for ls, w in zip(per_body, weak, strict=True))


def identify(model: GraphModel, measured: TimeSeries, rows: np.ndarray,
             measurement: Measurement, truth: GraphModel | None = None, with_system: bool = True) -> Identification:
    """Section 2.3: per body (Eq. 56) and for the whole system (Eq. 64)."""
    scale = parameter_scale(np.column_stack([model.m, model.m, model.m, model.J]))
    Y, Z, floor, per_body = _solve_per_body(lambda rec: _regressor(model, rec, rows), measured, measurement,
                                            PARAMETERS, scale)
    N, n = Y.shape[:2]
    system = None
    if with_system:
        Ks, Ls = stack_system(Y, Z)
        names = [f"{b}.{p}" for b in model.topology.bodies for p in PARAMETERS]
        system = solve(Ks, Ls, names, floor.reshape(-1), np.repeat(np.arange(N), 6 * n),
                       np.tile(np.arange(6 * n), N), scale.reshape(-1))
    truth = truth or model
    true = np.column_stack([truth.m, truth.m, truth.m, truth.J])
    return Identification(model.topology.bodies, per_body, system, true, measured.t[rows], measurement.resolution)


@dataclass(frozen=True, eq=False)
class FullIdentification:
    bodies: tuple[str, ...]
    per_body: tuple[Estimate, ...]
    true: np.ndarray  # (n, 10) Pinocchio's dynamic parameters of the true robot

    def serialise(self, ctx, config) -> dict:
        """results.json's `identification_full`: all 10 parameters per body against the truth."""
        return full_identification_section(self)


def identify_full(spec, model: GraphModel, measured: TimeSeries, rows: np.ndarray, measurement: Measurement,
                  true: np.ndarray) -> FullIdentification:
    """All 10 inertial parameters per body (harness/papers/graph_theory_2021/full.py), with the same excitation test
    and uncertainty as the paper's form."""
    *_, per_body = _solve_per_body(lambda rec: full_form(spec, model, rec, rows), measured, measurement,
                                   FULL_PARAMETERS, np.array([kind_scale(t) for t in true]))
    return FullIdentification(model.topology.bodies, per_body, true)



def graph_section(model: GraphModel, residual: Residual, D_error: float) -> dict:
    top = model.topology
    skipped = [{"t": float(residual.t[k]), "body": top.bodies[i], "cond_D": float(residual.cond_D[k, i])}
               for k, i in zip(*np.nonzero(~residual.evaluated), strict=True)]
    return {
        "bodies": list(top.bodies),
        "joints": list(top.joints),
        "S": top.S.tolist(),
        "S_e": top.S_e.tolist(),
        "unconstrained_residual": {
            "definition": "|A_i q_i'' - B_i| / |B_i| (Eq. 36), translational and rotational parts "
                          "separately, at every row where cond(D_i) <= 100",
            "max_translational": largest(residual.translational, residual.evaluated),
            "max_rotational": largest(residual.rotational, residual.evaluated),
            "rows_evaluated": int(residual.evaluated.sum()),
            "rows_not_evaluated": skipped,
        },
        "cardano": {
            "definition": "largest |D(theta) - D_ref(theta)| over every recorded body and row, D of Eq. 33 and "
                          "D_ref its columns (Ry Rz)^T e_x, Rz^T e_y, e_z from a rotation library: with A(0i) the "
                          "engine's orientation, D theta' is then the engine's angular velocity",
            "D_max_abs_error": D_error,
        },
    }


def parameter_scale(true: np.ndarray) -> np.ndarray:
    """What a parameter's error is relative to: its true value, or, where that is zero (a thin
    rod about its own axis, a point mass), the largest true value of its kind in the model."""
    kinds = np.array([0, 0, 0, 1, 1, 1])
    largest = np.array([np.max(np.abs(true[:, kinds == k])) for k in (0, 1)])[kinds]
    return np.where(true != 0.0, np.abs(true), largest)


WEAK_DEFINITION = (f"identifiable, but its sensitivity to the data (relative change per relative change of the "
                   f"data, worst direction) is more than {WEAK_RATIO:g} times the median parameter's; its error "
                   "is reported apart from max_abs_rel_error (harness/identify/lstsq.py)")


def _weakness(ls: Estimate, c: int) -> dict:
    k = ls.sensitivity[c]
    return {"sensitivity": float(k) if np.isfinite(k) else None, "weakly_identifiable": bool(ls.weak[c])}


def full_identification_section(full) -> dict:
    """All 10 parameters per body. Errors relative to the largest true value of the same kind (m;
    m c, at least m times the radius of gyration; I_O) in that body: a product of inertia or a
    centre-of-mass component that is zero up to round-off (1e-28 in the UR5 URDF) cannot be
    recovered relative to itself."""

    rows = []
    for i, body in enumerate(full.bodies):
        ls, true = full.per_body[i], full.true[i]
        scales = kind_scale(true)
        for c, name in enumerate(FULL_PARAMETERS):
            ok = bool(ls.identifiable[c])
            scale = scales[c]
            rows.append({"body": body, "name": name, "true": float(true[c]),
                         "identified": float(ls.beta[c]) if ok else None,
                         "rel_error": float((ls.beta[c] - true[c]) / scale) if ok and scale > 0 else None,
                         "std": finite_or_null(ls.std[c]) if ok else None, "identifiable": ok, "reason": ls.reasons[c],
                         **_weakness(ls, c)})
    rel = [abs(r["rel_error"]) for r in rows if r["rel_error"] is not None and not r["weakly_identifiable"]]
    weak = [abs(r["rel_error"]) for r in rows if r["rel_error"] is not None and r["weakly_identifiable"]]
    return {
        "method": "10 inertial parameters per body at its inner joint point, in its joint frame "
                  "(harness/papers/graph_theory_2021/full.py); true values: Pinocchio's dynamic parameters",
        "rel_error_definition": "(identified - true) / largest true value of the same kind in the body "
                                "(m; m c, at least m r_g with r_g the radius of gyration; I_O)",
        "parameters": rows,
        "weak_definition": WEAK_DEFINITION,
        "max_abs_rel_error": max(rel) if rel else None,
        "not_identifiable": [f"{r['body']}.{r['name']}" for r in rows if not r["identifiable"]],
        "weakly_identifiable": [f"{r['body']}.{r['name']}" for r in rows if r["weakly_identifiable"]],
        "max_abs_rel_error_weak": max(weak) if weak else None,
    }


def identification_section(ident: Identification, paper_identified: str | None, paper_abs_error: str | None,
                           significant_digits: int | None) -> dict:
    paper = reference_table(PACKAGE, paper_identified) if paper_identified else {}
    paper_err = reference_table(PACKAGE, paper_abs_error) if paper_abs_error else {}
    scale = parameter_scale(ident.true)
    rows = []
    for i, body in enumerate(ident.bodies):
        ls = ident.per_body[i]
        for c, name in enumerate(PARAMETERS):
            true, x = float(ident.true[i, c]), ls.beta[c]
            ok = bool(ls.identifiable[c])
            rows.append({
                "body": body, "name": name, "true": true,
                "identified": float(x) if ok else None,
                "abs_error": float(x - true) if ok else None,
                "rel_error": float((x - true) / scale[i, c]) if ok else None,
                "std": finite_or_null(ls.std[c]) if ok else None,
                "rel_std_percent": finite_or_null(100 * ls.std[c] / abs(x)) if ok and x != 0 else None,
                "ci95": [finite_or_null(ls.ci_low[c]), finite_or_null(ls.ci_high[c])] if ok else None,
                "true_in_ci95": bool(ls.ci_low[c] <= true <= ls.ci_high[c]) if ok else None,
                "identifiable": ok, "reason": ls.reasons[c], **_weakness(ls, c),
                "paper_identified": paper.get((body, name)),
                "paper_abs_error": paper_err.get((body, name)),
            })
    identified = [r for r in rows if r["identifiable"]]
    strong = [r for r in identified if not r["weakly_identifiable"]]
    weak = [r for r in identified if r["weakly_identifiable"]]
    sys = ident.system
    per_body_x = np.concatenate([ls.beta for ls in ident.per_body])
    both = sys.identifiable & np.concatenate([ls.identifiable for ls in ident.per_body])
    return {
        "method": "least squares per body (Eq. 56) and for the whole system (Eq. 64)",
        "uncertainty": "std and 95 % interval from the cluster-robust (CR3) covariance over the sample times, "
                       "t quantile with G - 1 degrees of freedom (harness/identify/lstsq.py)",
        "rel_error_definition": "(identified - true) / |true|; where the true value is zero, relative to the "
                                "largest true value of the same kind (mass or moment of inertia) in the model",
        "sample_times": floats(ident.sample_times),
        "significant_digits": significant_digits,
        "larger_error_than_paper": {
            f"{r['body']}.{r['name']}": "ours" if abs(r["abs_error"]) > abs(r["paper_abs_error"]) else "paper's"
            for r in rows if r["abs_error"] is not None and r["paper_abs_error"] is not None},
        "measurement_resolution": ident.resolution,
        "excitation": "a parameter is identifiable when its regressor column is at least 10 times "
                      "what measurement error alone produces, and its column is not collinear "
                      "with others (harness/identify/lstsq.py)",
        "weak_definition": WEAK_DEFINITION,
        "max_abs_rel_error": max((abs(r["rel_error"]) for r in strong), default=None),
        "not_identifiable": [f"{r['body']}.{r['name']}" for r in rows if not r["identifiable"]],
        "weakly_identifiable": [f"{r['body']}.{r['name']}" for r in weak],
        "max_abs_rel_error_weak": max((abs(r["rel_error"]) for r in weak), default=None),
        "not_identifiable_count": sum(not r["identifiable"] for r in rows),
        "coverage_ci95": (sum(r["true_in_ci95"] for r in identified) / len(identified)) if identified else None,
        "max_error_in_std": max((abs(r["abs_error"]) / r["std"] for r in identified if r["std"]), default=None),
        "parameters": rows,
        "per_body": [{"body": b, "rows": ls.rows, "column_snr": floats(ls.column_snr),
                      "singular_values": floats(ls.singular_values),
                      "residual_norm": ls.residual_norm}
                     for b, ls in zip(ident.bodies, ident.per_body, strict=True)],
        "system": {
            "rows": sys.rows,
            "identifiable_count": int(sys.identifiable.sum()),
            "same_verdicts_as_per_body": bool(np.array_equal(
                sys.identifiable, np.concatenate([ls.identifiable for ls in ident.per_body]))),
            "max_rel_difference_from_per_body": float(np.max(
                np.abs(sys.beta[both] - per_body_x[both]) / scale.reshape(-1)[both], initial=0.0)),
        },
    }


def lagrange_section(lg: LagrangeOutput, paper_lambda: str | None, spec: RobotSpec, model: GraphModel,
                     rec: TimeSeries) -> dict:
    forms = {}
    for name, f in lg.formulations.items():
        sol = f.solution
        ev = sol.evaluated
        forms[name] = {
            "rows": f.constraints.m,
            "labels": f.constraints.labels,
            "max_abs_phi_on_recording": f.max_abs_phi,
            "max_abs_phi_dot_on_recording": f.max_abs_phi_dot,
            "rank_Phi_q_min": int(sol.rank_Phi_q.min()),
            "rank_Phi_q_max": int(sol.rank_Phi_q.max()),
            "cond_Phi_q": [finite_or_null(c) for c in sol.cond_Phi_q],
            "cond_system": [finite_or_null(c) for c in sol.cond_system],
            "axis_rows_rank_deficient": f.axis_rank_deficient,
            "rows_solved": int(ev.sum()),
            "acceleration_check_max_rel_error": finite_or_null(np.max(sol.acceleration_error[ev], initial=-np.inf)),
            "reaction_check_max_rel_error": finite_or_null(np.max(sol.reaction_error[ev], initial=-np.inf)),
        }
    normal = lg.formulations["normal"].solution
    section = {
        "definition": "Eq. 111 with the rotational rows premultiplied by D^T (harness/papers/graph_theory_2021/"
                      "constrained.py); checks: |[r''; omega'] - recorded| / |recorded| and "
                      "|-Phi_q^T lambda - recorded reactions| / |recorded reactions| per row",
        "rows_evaluated": int(normal.evaluated.sum()),
        "rows_not_evaluated": [{"t": float(t), "reason": "a body's cond(D) > 100, or Eq. 111 singular"}
                               for t in normal.t[~normal.evaluated]],
        "t": floats(normal.t),
        "formulations": forms,
        "at_time": None,
        "forward_simulation": None,
    }
    if lg.time_row is not None:
        row = lg.time_row
        paper = reference_table(PACKAGE, paper_lambda) if paper_lambda else {}
        bodies = []
        if normal.evaluated[row]:
            for entry in reactions_at(lg, spec, model, rec, row):
                entry["paper_lambda_magnitudes"] = [paper.get((entry["body"], f"lambda_{a}"))
                                                    for a in range(1, 6)]
                bodies.append(entry)
        section["at_time"] = {"t": float(rec.t[row]), "formulation": "normal",
                              "evaluated": bool(normal.evaluated[row]), "bodies": bodies}
    if lg.forward is not None:
        fw, ol = lg.forward, lg.open_loop
        departure = ol.t[-1] if not ol.completed else None
        section["forward_simulation"] = {
            "method": "quaternions and omega^(i), normal constraint rows, Baumgarte 10/s, RK4 with "
                      "MuJoCo's step and stage torques, plus a correction toward the prescribed "
                      "motion (harness/papers/graph_theory_2021/forward.py)",
            # the time integrated to: the recording's end unless a deviation beyond 1e-6 stopped it
            "integrated_until": float(fw.t[-1]),
            "recording_end": float(rec.t[-1]),
            "largest_joint_deviation": float(fw.q_error.max()),
            "max_joint_deviation": dict(zip(spec.joint_names, floats(fw.q_error), strict=True)),
            "max_position_deviation": fw.r_error,
            "max_abs_phi": fw.max_abs_phi,
            "correction_over_drive": dict(zip(spec.joint_names, floats(fw.feedback_ratio),
                                              strict=True)),
            "largest_correction_over_drive": float(np.max(fw.feedback_ratio)),
            "open_loop_departure_time": None if departure is None else float(departure),
            "open_loop_note": "with the recorded torques alone the replay leaves MuJoCo's trajectory "
                              "by more than 1e-6 at this time (null: it never does)",
        }
    return section


