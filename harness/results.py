"""results.json: the one place its schema is defined.

Top-level sections, in order: `schema`, `passed` and `gates` (the verdict), `run` (when, with
which versions, the scenario file's text), `scenario`, `model`, `recording`, `graph` (the paper's
matrices and the unconstrained-dynamics residual on the recording), `identification`, `lagrange`
(constraints, Eq. 111, multipliers, conditioning, forward simulation), `torques` (MuJoCo,
Pinocchio RNEA and the graph model, and the joint reaction wrenches). Every
number is finite (NaN or infinity is an error when writing, never a silent `NaN` token).
"""

from __future__ import annotations

import json
import platform
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from harness.compare import DEFINITION, joint_load_scale, pair_metrics, wrench_metrics
from harness.gates import check
from harness.graph.dynamics import GraphModel, Residual
from harness.graph.identification import PARAMETERS
from harness.lagrange import reactions_at
from harness.paper import reference_table
from harness.recording import Recording
from harness.scenario import Scenario
from harness.spec import RobotSpec

if TYPE_CHECKING:
    from harness.pipeline import Identification, RunOutput

SCHEMA = {"name": "harness-results", "version": 1}
RECORDING_FILE = "recording.csv"
RESULTS_FILE = "results.json"


def _list(v: np.ndarray) -> list[float]:
    return [float(x) for x in np.ravel(v)]


def scenario_section(s: Scenario) -> dict:
    return {
        "name": s.name,
        "file": str(s.source),
        "description": s.description,
        "model_file": str(s.robot.source),
        "gravity": _list(s.gravity_W),
        "duration": s.duration,
        "output_steps": s.output_steps,
        "output_dt": s.output_dt,
        "sample_times": _list(s.sample_times),
        "motion": {j: {"type": m.kind, "description": m.describe()} for j, m in s.motion.items()},
        "simulation": {
            "integrator": s.simulation.integrator,
            "timestep": s.simulation.timestep,
            "tracking_bandwidth": s.simulation.tracking_bandwidth,
        },
        "measurement": s.measurement.describe(),
    }


def model_section(spec: RobotSpec) -> dict:
    bodies = []
    for b in spec.bodies:
        row = {"name": b.name, "massless": b.massless, "mass": b.mass}
        row.update(zip(("J11", "J22", "J33"), _list(b.principal_inertia), strict=True))
        if b.cylinder is not None:
            row.update(shape="cylinder", length=b.cylinder.length, radius=b.cylinder.radius,
                       density=b.cylinder.density)
        row.update(com=_list(b.p_W_com0), e1=_list(b.R_WB0[:, 0]), e2=_list(b.R_WB0[:, 1]))
        bodies.append(row)
    joints = [{"name": j.name, "type": j.type, "parent": j.parent, "child": j.child,
               "point": _list(j.p_W0), "axis": _list(j.axis_W0)} for j in spec.joints]
    return {"name": spec.name, "file": str(spec.source), "description": spec.description,
            "bodies": bodies, "joints": joints}


def recording_section(rec: Recording) -> dict:
    meta = rec.meta
    tracking = {}
    for j, name in enumerate(rec.joints):
        tracking[name] = {
            "q_max_abs_error": float(np.max(np.abs(rec.q[:, j] - meta["q_ref"][:, j]))),
            "qd_max_abs_error": float(np.max(np.abs(rec.qd[:, j] - meta["qd_ref"][:, j]))),
            "qdd_max_abs_error": float(np.max(np.abs(rec.qdd[:, j] - meta["qdd_ref"][:, j]))),
        }
    gimbal = {b: _list(rec.t[rec.gimbal[:, i]]) for i, b in enumerate(rec.bodies)
              if rec.gimbal[:, i].any()}
    return {
        "file": RECORDING_FILE,
        "max_tracking_error": max(v["q_max_abs_error"] for v in tracking.values()),
        "rows": len(rec.t),
        "t_start": float(rec.t[0]),
        "t_end": float(rec.t[-1]),
        "joints": list(rec.joints),
        "bodies": list(rec.bodies),
        "engine": meta["engine"],
        "engine_version": meta["engine_version"],
        "integrator": meta["integrator"],
        "timestep": meta["timestep"],
        "substeps_per_row": meta["substeps"],
        "tracking_bandwidth": meta["tracking_bandwidth"],
        "tracking_error": tracking,
        "gimbal_lock_rows": gimbal,
    }


def graph_section(model: GraphModel, residual: Residual) -> dict:
    top = model.topology
    worst_t = np.nanmax(np.where(residual.evaluated, residual.translational, np.nan))
    worst_r = np.nanmax(np.where(residual.evaluated, residual.rotational, np.nan))
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
            "max_translational": float(worst_t),
            "max_rotational": float(worst_r),
            "rows_evaluated": int(residual.evaluated.sum()),
            "rows_not_evaluated": skipped,
        },
    }


def parameter_scale(true: np.ndarray) -> np.ndarray:
    """What a parameter's error is relative to: its true value, or, where that is zero (a thin
    rod about its own axis, a point mass), the largest true value of its kind in the model."""
    kinds = np.array([0, 0, 0, 1, 1, 1])
    largest = np.array([np.max(np.abs(true[:, kinds == k])) for k in (0, 1)])[kinds]
    return np.where(true != 0.0, np.abs(true), largest)


def full_identification_section(full) -> dict:
    """All 10 parameters per body. Errors relative to the largest true value of the same kind (m;
    m c, at least m times the radius of gyration; I_O) in that body: a product of inertia or a
    centre-of-mass component that is zero up to round-off (1e-28 in the UR5 URDF) cannot be
    recovered relative to itself."""
    from harness.graph.full import FULL_PARAMETERS, GROUPS

    rows = []
    for i, body in enumerate(full.bodies):
        ls, true = full.per_body[i], full.true[i]
        kind_scale = np.zeros(10)
        for g in GROUPS:
            kind_scale[list(g)] = np.max(np.abs(true[list(g)]))
        # first moments: at least m r_g, r_g = sqrt(max I / m) the radius of gyration (a centre of mass
        # on the joint point has m c = 0, and its own largest value is round-off)
        kind_scale[1:4] = max(kind_scale[1], np.sqrt(true[0] * kind_scale[4]))
        for c, name in enumerate(FULL_PARAMETERS):
            ok = bool(ls.identifiable[c])
            scale = kind_scale[c]
            rows.append({"body": body, "name": name, "true": float(true[c]),
                         "identified": float(ls.x[c]) if ok else None,
                         "rel_error": float((ls.x[c] - true[c]) / scale) if ok and scale > 0 else None,
                         "std": float(ls.std[c]) if ok else None, "identifiable": ok, "reason": ls.reasons[c]})
    rel = [abs(r["rel_error"]) for r in rows if r["rel_error"] is not None]
    return {
        "method": "10 inertial parameters per body at its inner joint point, in its joint frame "
                  "(harness/graph/full.py); true values: Pinocchio's dynamic parameters",
        "rel_error_definition": "(identified - true) / largest true value of the same kind in the body "
                                "(m; m c, at least m r_g with r_g the radius of gyration; I_O)",
        "parameters": rows,
        "max_abs_rel_error": max(rel) if rel else None,
        "not_identifiable": [f"{r['body']}.{r['name']}" for r in rows if not r["identifiable"]],
    }


def identification_section(ident: Identification, scenario: Scenario) -> dict:
    paper = reference_table(scenario.paper_identified) if scenario.paper_identified else {}
    paper_err = reference_table(scenario.paper_abs_error) if scenario.paper_abs_error else {}
    scale = parameter_scale(ident.true)
    rows = []
    for i, body in enumerate(ident.bodies):
        ls = ident.per_body[i]
        for c, name in enumerate(PARAMETERS):
            true, x = float(ident.true[i, c]), ls.x[c]
            ok = bool(ls.identifiable[c])
            rows.append({
                "body": body, "name": name, "true": true,
                "identified": float(x) if ok else None,
                "abs_error": float(x - true) if ok else None,
                "rel_error": float((x - true) / scale[i, c]) if ok else None,
                "std": float(ls.std[c]) if ok else None,
                "rel_std_percent": float(100 * ls.std[c] / abs(x)) if ok and x != 0 else None,
                "ci95": [float(ls.ci_low[c]), float(ls.ci_high[c])] if ok else None,
                "true_in_ci95": bool(ls.ci_low[c] <= true <= ls.ci_high[c]) if ok else None,
                "identifiable": ok, "reason": ls.reasons[c],
                "paper_identified": paper.get((body, name)),
                "paper_abs_error": paper_err.get((body, name)),
            })
    identified = [r for r in rows if r["identifiable"]]
    sys = ident.system
    per_body_x = np.concatenate([ls.x for ls in ident.per_body])
    both = sys.identifiable & np.concatenate([ls.identifiable for ls in ident.per_body])
    return {
        "method": "least squares per body (Eq. 56) and for the whole system (Eq. 64)",
        "uncertainty": "std and 95 % interval from the cluster-robust (CR3) covariance over the sample times, "
                       "t quantile with G - 1 degrees of freedom (harness/identify.py)",
        "rel_error_definition": "(identified - true) / |true|; where the true value is zero, relative to the "
                                "largest true value of the same kind (mass or moment of inertia) in the model",
        "sample_times": _list(ident.sample_times),
        "significant_digits": scenario.measurement.significant_digits,
        "larger_error_than_paper": {
            f"{r['body']}.{r['name']}": "ours" if abs(r["abs_error"]) > abs(r["paper_abs_error"]) else "paper's"
            for r in rows if r["abs_error"] is not None and r["paper_abs_error"] is not None},
        "measurement_resolution": ident.resolution,
        "excitation": "a parameter is identifiable when its regressor column is at least 10 times "
                      "what measurement error alone produces, and its column is not collinear "
                      "with others (harness/identify.py)",
        "max_abs_rel_error": max((abs(r["rel_error"]) for r in identified), default=None),
        "not_identifiable": [f"{r['body']}.{r['name']}" for r in rows if not r["identifiable"]],
        "not_identifiable_count": sum(not r["identifiable"] for r in rows),
        "coverage_ci95": (sum(r["true_in_ci95"] for r in identified) / len(identified)) if identified else None,
        "max_error_in_std": max((abs(r["abs_error"]) / r["std"] for r in identified if r["std"]), default=None),
        "parameters": rows,
        "per_body": [{"body": b, "rows": ls.rows, "column_snr": _list(ls.column_snr),
                      "singular_values": _list(ls.singular_values),
                      "residual_norm": ls.residual_norm}
                     for b, ls in zip(ident.bodies, ident.per_body, strict=True)],
        "system": {
            "rows": sys.rows,
            "identifiable_count": int(sys.identifiable.sum()),
            "same_verdicts_as_per_body": bool(np.array_equal(
                sys.identifiable, np.concatenate([ls.identifiable for ls in ident.per_body]))),
            "max_rel_difference_from_per_body": float(np.max(
                np.abs(sys.x[both] - per_body_x[both]) / scale.reshape(-1)[both], initial=0.0)),
        },
    }


def _finite(x: float) -> float | None:
    return float(x) if np.isfinite(x) else None


def lagrange_section(out: RunOutput) -> dict:
    lg, sc = out.lagrange, out.scenario
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
            "cond_Phi_q": [_finite(c) for c in sol.cond_Phi_q],
            "cond_system": [_finite(c) for c in sol.cond_system],
            "axis_rows_rank_deficient": f.axis_rank_deficient,
            "rows_solved": int(ev.sum()),
            "acceleration_check_max_rel_error": _finite(np.max(sol.acceleration_error[ev], initial=-np.inf)),
            "reaction_check_max_rel_error": _finite(np.max(sol.reaction_error[ev], initial=-np.inf)),
        }
    normal = lg.formulations["normal"].solution
    section = {
        "definition": "Eq. 111 with the rotational rows premultiplied by D^T (harness/graph/"
                      "constrained.py); checks: |[r''; omega'] - recorded| / |recorded| and "
                      "|-Phi_q^T lambda - recorded reactions| / |recorded reactions| per row",
        "rows_evaluated": int(normal.evaluated.sum()),
        "rows_not_evaluated": [{"t": float(t), "reason": "a body's cond(D) > 100, or Eq. 111 singular"}
                               for t in normal.t[~normal.evaluated]],
        "t": _list(normal.t),
        "formulations": forms,
        "at_time": None,
        "forward_simulation": None,
    }
    if lg.time_row is not None:
        row = lg.time_row
        paper = reference_table(sc.lagrange.paper_lambda) if sc.lagrange.paper_lambda else {}
        bodies = []
        if normal.evaluated[row]:
            for entry in reactions_at(lg, sc.robot, out.model, out.recording, row):
                entry["paper_lambda_magnitudes"] = [paper.get((entry["body"], f"lambda_{a}"))
                                                    for a in range(1, 6)]
                bodies.append(entry)
        section["at_time"] = {"t": float(out.recording.t[row]), "formulation": "normal",
                              "evaluated": bool(normal.evaluated[row]), "bodies": bodies}
    if lg.forward is not None:
        fw, ol = lg.forward, lg.open_loop
        departure = ol.t[-1] if not ol.completed else None
        section["forward_simulation"] = {
            "method": "quaternions and omega^(i), normal constraint rows, Baumgarte 10/s, RK4 with "
                      "MuJoCo's step and stage torques, plus a correction toward the prescribed "
                      "motion (harness/graph/forward.py)",
            "largest_joint_deviation": float(fw.q_error.max()),
            "max_joint_deviation": dict(zip(sc.robot.joint_names, _list(fw.q_error), strict=True)),
            "max_position_deviation": fw.r_error,
            "max_abs_phi": fw.max_abs_phi,
            "correction_over_drive": dict(zip(sc.robot.joint_names, _list(fw.feedback_ratio),
                                              strict=True)),
            "open_loop_departure_time": None if departure is None else float(departure),
            "open_loop_note": "with the recorded torques alone the replay leaves MuJoCo's trajectory "
                              "by more than 1e-6 at this time (null: it never does)",
        }
    return section


def torques_section(out: RunOutput) -> dict:
    rec, spec = out.recording, out.scenario.robot
    joints = spec.joint_names
    mj = rec.tau[:, [rec.joint_index(j) for j in joints]]
    sources = {"mujoco": mj, "pinocchio": out.pinocchio.tau, "graph": out.graph_inverse.tau}
    scale = joint_load_scale(spec, rec)
    cols = [rec.joint_index(j) for j in joints]
    F_rec, M_rec = rec.F_W[:, cols], rec.M_W[:, cols]
    return {
        "joints": joints,
        "definition": DEFINITION,
        "load_scale": dict(zip(joints, _list(scale), strict=True)),
        "samples": [{"t": float(t), **{k: _list(v[i]) for k, v in sources.items()}}
                    for i, t in enumerate(rec.t)],
        **{f"{a}_vs_{b}": pair_metrics(sources[a], sources[b], scale, rec.t, joints)
           for a, b in (("graph", "pinocchio"), ("graph", "mujoco"), ("pinocchio", "mujoco"))},
        "reactions": {
            "definition": "|a - b| / largest |b| of the joint over the run, b the recorded wrench "
                          "(force of the inner on the outer body, moment about the joint point)",
            "pinocchio_vs_mujoco": {"force": wrench_metrics(out.pinocchio.F_W, F_rec, rec.t, joints),
                                    "moment": wrench_metrics(out.pinocchio.M_W, M_rec, rec.t, joints)},
            "graph_vs_mujoco": {"force": wrench_metrics(out.graph_inverse.F_W, F_rec, rec.t, joints),
                                "moment": wrench_metrics(out.graph_inverse.M_W, M_rec, rec.t, joints)},
        },
    }


def run_section(out: RunOutput, when: str) -> dict:
    import matplotlib
    import mujoco
    import pandas
    import pinocchio

    from harness import __version__

    return {
        "time": when,
        "versions": {"harness": __version__, "python": platform.python_version(), "numpy": np.__version__,
                     "mujoco": mujoco.__version__, "pinocchio": pinocchio.__version__,
                     "pandas": pandas.__version__, "matplotlib": matplotlib.__version__},
        "model_under_test": str(out.scenario.tested.source),
        "timings": out.timings or {},
        "scenario_text": out.scenario.text,
    }


def build_results(out: RunOutput, when: str | None = None) -> dict:
    """The whole results.json. `when` (ISO time) defaults to now; it and `run.timings` (seconds per
    stage) are the only fields that differ between two runs of the same scenario."""
    when = when or datetime.now(UTC).isoformat(timespec="seconds")
    results = {
        "schema": SCHEMA,
        "run": run_section(out, when),
        "scenario": scenario_section(out.scenario),
        "model": model_section(out.scenario.robot),
        "recording": recording_section(out.recording),
        "graph": graph_section(out.model, out.residual),
        "identification": identification_section(out.identification, out.scenario),
        "lagrange": lagrange_section(out),
        "torques": torques_section(out),
    }
    if out.design_comparison is not None:
        results["design_comparison"] = out.design_comparison
    if out.audit is not None:
        results["inertia_matrix_audit"] = out.audit
    if out.excitation is not None:
        results["excitation"] = out.excitation
        results["scenario"]["motion"] = {j: {"type": m.kind, "description": m.describe()}
                                         for j, m in out.scenario.motion.items()}
    if out.identification_full is not None:
        results["identification_full"] = full_identification_section(out.identification_full)
    if out.torque_identification is not None:
        from harness.torque_id import section as torque_id_section

        results["torque_identification"] = torque_id_section(out.torque_identification,
                                                             out.scenario.torque_validation.name)
    rows, passed = check(out.scenario.gates, results)
    return {"schema": SCHEMA, "passed": passed, "gates": rows,
            **{k: v for k, v in results.items() if k != "schema"}}


def write_results(path: Path, results: dict) -> None:
    Path(path).write_text(json.dumps(results, indent=2, allow_nan=False) + "\n")
