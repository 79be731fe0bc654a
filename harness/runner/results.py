"""results.json: the one place its layout is defined. This module only serialises: each stage
serialises its own typed result (harness/base/plugins.py, Stage.serialise), and the verdict is added by
harness.gates.

Top-level sections, in order: `schema`, `passed` and `gates` (the verdict), `run` (its id, when, with
which versions, the scenario file's text, the studies that ran, seconds per stage), `scenario`,
`model`, `recording`, then one section per stage that ran, under the stage's key: `torques`
(MuJoCo, Pinocchio RNEA and every model under test, joint reaction wrenches, mass matrices),
`torque_identification`, `identification_methods`, and those of the studies (for the graph-theory
paper: `graph`, `identification`, `identification_full`, `lagrange`). Every number is finite: a
NaN or infinity that a stage computes is written as null and its path listed in `run.not_finite`
(never a silent `NaN` token; a gate on it fails closed).
"""

from __future__ import annotations

import json
import math
import platform
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from harness.base.numerics import floats
from harness.base.series import TimeSeries
from harness.model.spec import RobotSpec
from harness.runner.scenario import Scenario
from harness.sources.base_motion import model_notes

if TYPE_CHECKING:
    from harness.runner.pipeline import RunOutput

SCHEMA = {"name": "harness-results", "version": 1}
RECORDING_FILE = "recording.csv"
RESULTS_FILE = "results.json"


STARTS = ("log_identification", "floating_log")  # the sections of a log's identification, each with its start check


def said_first(results: dict) -> list[str]:
    """What a run says at the head of the terminal and of the report, in order: a log's start check's findings
    (an arm's or a floating base's), then the log's conditioning's warnings and its identification's."""
    li = next((results[k] for k in STARTS if k in results), {})
    return [*li.get("start", {}).get("said", []), *results.get("data", {}).get("conditioning", {}).get("warnings", []),
            *li.get("warnings", [])]


def scenario_section(s: Scenario) -> dict:
    return {
        "name": s.name,
        "file": str(s.source),
        "description": s.description,
        "model_file": str(s.robot.source),
        "model_notes": model_notes(s),
        "gravity": floats(s.gravity_W),
        "duration": s.duration,
        "output_steps": s.output_steps,
        "output_dt": s.output_dt,
        "sample_times": floats(s.sample_times),
        "motion": {j: {"type": m.kind, "description": m.describe()} for j, m in s.motion.items()},
        "simulation": {
            "integrator": s.simulation.integrator,
            "timestep": s.simulation.timestep,
            "tracking_bandwidth": s.simulation.tracking_bandwidth,
        },
        "measurement": s.measurement.describe(),
    }


def data_scenario_section(s) -> dict:
    return {"name": s.name, "file": str(s.source), "description": s.description, "model_file": str(s.robot.source),
            "model_notes": model_notes(s), "gravity": floats(s.gravity_W), "data": s.data.describe()}


def data_section(log) -> dict:
    """The measured log and every step of its conditioning (harness/sources/log/)."""
    from harness.sources.log import LOG_FILE

    return {"file": LOG_FILE, "rows": len(log.t), "joints": list(log.joints), "t_start": float(log.t[0]),
            "t_end": float(log.t[-1]),
            "conditioning": {**log.meta, "reach_s": log.reach_s}}  # how far a sample's conditioning reaches


def model_section(spec: RobotSpec) -> dict:
    bodies = []
    for b in spec.bodies:
        row = {"name": b.name, "massless": b.massless, "mass": b.mass}
        row.update(zip(("J11", "J22", "J33"), floats(b.principal_inertia), strict=True))
        if b.cylinder is not None:
            row.update(shape="cylinder", length=b.cylinder.length, radius=b.cylinder.radius,
                       density=b.cylinder.density)
        row.update(com=floats(b.p_W_com0), e1=floats(b.R_WB0[:, 0]), e2=floats(b.R_WB0[:, 1]))
        bodies.append(row)
    drives = spec.transmission
    joints = [{"name": j.name, "type": j.type, "parent": j.parent, "child": j.child,
               "point": floats(j.p_W0), "axis": floats(j.axis_W0),
               **({"friction": j.friction.as_dict()} if not j.friction.none and drives is None else {})}
              for j in spec.joints]
    out = {"name": spec.name, "file": str(spec.source), "description": spec.description,
           "bodies": bodies, "joints": joints}
    if drives is not None:  # each motor's law, in motor units, reaching the joints through N
        out["transmission"] = {**drives.describe(spec.joint_names),
                               "laws": {m: f.as_dict() for m, f in zip(drives.motors, spec.frictions, strict=True)}}
    return out


def recording_section(rec: TimeSeries) -> dict:
    meta, drive = rec.meta, rec.drive
    tracking = {}
    for j, name in enumerate(rec.joints):
        tracking[name] = {
            "q_max_abs_error": float(np.max(np.abs(rec.q[:, j] - drive.q_ref[:, j]))),
            "qd_max_abs_error": float(np.max(np.abs(rec.qd[:, j] - drive.qd_ref[:, j]))),
            "qdd_max_abs_error": float(np.max(np.abs(rec.qdd[:, j] - drive.qdd_ref[:, j]))),
        }
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
        "integrator": drive.integrator,
        "timestep": drive.timestep,
        "substeps_per_row": drive.substeps,
        "tracking_bandwidth": meta["tracking_bandwidth"],
        "tracking_error": tracking,
        "engine_warnings": list(meta.get("warnings", [])),
    }


def run_section(out: RunOutput, when: str) -> dict:
    from importlib.metadata import version  # installed versions, without importing what the run did not need

    import mujoco
    import pinocchio

    from harness.base.version import __version__
    from harness.runner.folder import new_id

    return {
        "id": new_id(),  # the run's: its output folder's manifests carry it (harness/runner/folder.py)
        "time": when,
        "versions": {"harness": __version__, "python": platform.python_version(), "numpy": np.__version__,
                     "mujoco": mujoco.__version__, "pinocchio": pinocchio.__version__,
                     "pandas": version("pandas"), "scipy": version("scipy")},
        "models_under_test": {m.name: {"plugin": m.reference, "model_file": str(m.robot.source)}
                              for m in out.scenario.models},
        "identification_methods": {m.name: m.reference for m in out.scenario.methods},
        "studies": [study.name for study, _ in out.scenario.studies],
        "workers": out.context.workers.describe(),  # where a stage's Monte Carlo trials ran
        "timings": out.timings or {},
        "scenario_text": out.scenario.text,
    }


def build_results(out: RunOutput, when: str | None = None) -> dict:
    """results.json without the verdict (harness.runner.gates.verdict adds it). `when` (ISO time) defaults
    to now; it, `run.id` and `run.timings` are the only fields that differ between two runs of a scenario
    (`run.workers` too, where the two ran their trials on different workers)."""
    when = when or datetime.now(UTC).isoformat(timespec="seconds")
    from harness.runner.scenario import DataScenario

    data = isinstance(out.scenario, DataScenario)
    results = {
        "schema": SCHEMA,
        "run": run_section(out, when),
        "scenario": data_scenario_section(out.scenario) if data else scenario_section(out.scenario),
        "model": model_section(out.scenario.robot),
        **({"data": data_section(out.recording)} if data else {"recording": recording_section(out.recording)}),
    }
    with np.errstate(invalid="ignore", divide="ignore"):  # NaN becomes null below, and is listed
        for key, s in out.stages.items():
            results[key] = s.stage.serialise(s.result, out.context, s.config)
    if out.excitation is not None:
        results["excitation"] = out.excitation
    results, results["run"]["not_finite"] = with_nulls(results)
    return results


def with_nulls(tree: dict) -> tuple[dict, list[str]]:
    """The tree with every NaN or infinite number replaced by null, and the paths where it was."""
    found: list[str] = []
    return _finite(tree, "", found), found


def _finite(node, path: str, found: list[str]):
    """The tree with every NaN or infinite number replaced by null, its path noted in `found`: a
    gate on such a value fails closed, and the file stays valid JSON."""
    if isinstance(node, dict):
        return {k: _entry(v, path, k, found) for k, v in node.items()}
    if isinstance(node, list | tuple):
        return [_entry(v, path, i, found) for i, v in enumerate(node)]
    if _not_finite(node):
        found.append(path)
        return None
    return node


def _not_finite(x) -> bool:
    return isinstance(x, float | np.floating) and not math.isfinite(x)


def _entry(value, path: str, key, found: list[str]):
    """An entry of a dict or list: a finite number or other leaf as it is, anything else through
    `_finite` at its path (spelt out only there: a results tree holds thousands of numbers, nearly
    all finite)."""
    if isinstance(value, dict | list | tuple) or _not_finite(value):
        return _finite(value, f"{path}.{key}" if path else str(key), found)
    return value


def write_results(path: Path, results: dict) -> None:
    Path(path).write_text(json.dumps(results, indent=2, allow_nan=False) + "\n")

