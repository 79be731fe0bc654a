"""results.json: the one place its schema is defined.

Top-level sections, in order: `schema`, `scenario`, `model`, `recording`. Later stages add their
own sections through `build_results(..., **sections)`. Every number is finite (NaN or infinity
is an error when writing, never a silent `NaN` token in the JSON).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from harness.recording import Recording
from harness.scenario import Scenario
from harness.spec import RobotSpec

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


def build_results(scenario: Scenario, recording: Recording, **sections: dict) -> dict:
    out = {
        "schema": SCHEMA,
        "scenario": scenario_section(scenario),
        "model": model_section(scenario.robot),
        "recording": recording_section(recording),
    }
    out.update(sections)
    return out


def write_results(path: Path, results: dict) -> None:
    Path(path).write_text(json.dumps(results, indent=2, allow_nan=False) + "\n")
