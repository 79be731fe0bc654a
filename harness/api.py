"""The public API: what a user's script, notebook or test suite calls.

    import harness
    result = harness.run("scenarios/my_arm.toml")
    result.passed                   # every gate passed
    for g in result.gates:          # name, metric, value, limit, direction, passed, reason
        print(g.name, g.value, g.limit, g.passed)
    result.results                  # the content of results.json
    result.recording                # the recording (harness.base.series.TimeSeries)

A model object is judged without a module file or a scenario entry (in a notebook, say):

    result = harness.run("kr500_rail", models={"mine": MyModel()})   # or model=MyModel()
    result.results["torques"]["mine_vs_pinocchio"]["max_rel_error"]

It is judged like a `[model_under_test]` of that name (default "model"): against MuJoCo and
Pinocchio on the scenario's motion and at its random states, with the gates the scenario has on
it, else the standard ones (`model_gates`). A scenario can be a dict with a scenario file's layout
(`harness.load_scenario(dict, folder=...)`: files it names are relative to `folder`).

`harness.load_scenario(path)` and `harness.load_model(path)` load and validate a scenario or a
robot description (TOML or URDF model file) without running anything; a bare name is a scenario
in ./scenarios/, the current folder or built into the package. Bad input raises
harness.InputError (file, key, message); a plugin that breaks its protocol raises
harness.PluginError.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from harness.base.plugins import ModelUnderTest, check_protocol
from harness.base.series import TimeSeries
from harness.base.tomlio import InputError
from harness.identify.ls_model import ExportedModel
from harness.model.load import load_spec
from harness.model.spec import RobotSpec
from harness.runner.gates import Gate
from harness.runner.judging import judged, judging_metrics
from harness.runner.scenario import DataScenario, PluginEntry, Scenario, scenario_from_dict
from harness.runner.scenario import load_scenario as _load_scenario


@dataclass(frozen=True)
class GateRow:
    name: str
    metric: str
    value: float | None  # None: the result is null, not a number or not finite (the gate fails)
    limit: float
    direction: str  # "at_most" or "at_least"
    passed: bool
    reason: str = ""
    where: str = ""  # where the worst case lies (a joint and time, a parameter), when the result says
    skipped: bool = False  # what it judges did not run (a method whose tool is not installed): `reason` says why


@dataclass(frozen=True, eq=False)
class Result:
    scenario: str
    passed: bool
    gates: tuple[GateRow, ...]
    results: dict  # results.json
    recording: TimeSeries
    output: Any = None  # the pipeline's typed results (harness.runner.pipeline.RunOutput)

    @property
    def failed(self) -> tuple[GateRow, ...]:
        return tuple(g for g in self.gates if not g.passed)


def load_scenario(scenario: str | Path | dict, folder: str | Path = ".", name: str = "scenario"
                  ) -> Scenario | DataScenario:
    """A scenario file (a path, or a bare name: harness/base/builtin.py), or a dict with its layout whose
    files are relative to `folder`."""
    if isinstance(scenario, dict):
        return scenario_from_dict(scenario, name, folder)
    from harness.base.builtin import resolve

    return _load_scenario(resolve(scenario, "scenarios"))


MODEL_GATE_LIMIT = 1e-9  # a model of the scenario's own robot agrees with the engines at round-off (about 1e-15)


def model_gates(name: str, limit: float = MODEL_GATE_LIMIT) -> tuple[Gate, ...]:
    """The standard gates on a model under test: its torques against MuJoCo and Pinocchio along the
    motion, and against Pinocchio at the random states."""
    return tuple(Gate(m, m, limit) for m in judging_metrics("model_under_test", name)[:3])


def with_models(sc: Scenario, models: dict[str, Any]) -> Scenario:
    """The scenario with model objects added as models under test (checked against the protocol),
    each with the standard gates where the scenario has none on it."""
    if not isinstance(sc, Scenario):
        raise InputError(sc.source, "models", "a scenario with [data] is judged on its log: it takes no model")
    entries, gates = list(sc.models), list(sc.gates)
    for name, obj in models.items():
        if not isinstance(name, str) or not name.isidentifier() or name in ("mujoco", "pinocchio"):
            raise InputError(sc.source, "models", f"{name!r} must be a plain identifier other than mujoco and "
                                                  "pinocchio: it names metrics")
        reference = f"{type(obj).__name__} object"
        check_protocol(reference, obj, ModelUnderTest, sc.robot.joint_names)
        entries = [e for e in entries if e.name != name] + [PluginEntry(name, reference, sc.robot, obj)]
        if not judged("model_under_test", name, tuple(gates)):
            gates += model_gates(name)
    return dataclasses.replace(sc, models=tuple(entries), gates=tuple(gates))


def load_model(path: str | Path) -> RobotSpec:
    return load_spec(Path(path))


@dataclass(frozen=True, eq=False)
class IdentifiedModel(ExportedModel):
    """A model a log run identified and exported (`identified_model`): `joint_names`, and
    `inverse_dynamics(q, qd, qdd)` (arrays (N, n) in that order, SI) the joint torques it predicts: the
    links' rigid-body torques (Pinocchio's RNEA) and each drive's law, through the transmission where
    the model has drives (harness/model/drives.py). `spec` is the whole description."""

    spec: RobotSpec
    gravity_W: np.ndarray

    def inverse_dynamics(self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
        from harness.engines.pinocchio import build_model, rnea

        return rnea(build_model(self.spec, self.gravity_W), *self.states(q, qd, qdd)).tau


def identified_model(folder: str | Path, fit: str = "consistent"):
    """The model a `harness run` of a measured log exported: `folder` is the run's output folder (with
    results.json) or its `identified/` folder, read from its model
    file (identified/robot.toml: the URDF with the drives' or joints' laws). A folder whose files are not
    all one run's, as it wrote them (identified/manifest.json; results.json's run id beside it), is
    refused (InputError). The gravity is the one the fits were made at (robot.toml's `[model] gravity`, else
    least_squares.toml's `gravity`: a base off level read off the torques, harness/identify/gravity.py), else
    the scenario's in results.json, else standard gravity along -z. `fit = "least squares"`:
    the least-squares fit of the base parameters (identified/least_squares.toml, evaluated with that
    model file's kinematics and laws; harness/identify/ls_model.py), with the same `joint_names` and
    `inverse_dynamics`."""
    import json

    from harness.model.export import LEAST_SQUARES_FILE, MODEL_FILE
    from harness.runner.folder import verify

    if fit not in ("consistent", "least squares"):
        raise ValueError(f"fit must be 'consistent' or 'least squares', not {fit!r}")
    folder = Path(folder)
    here = folder / "identified" if (folder / "identified").is_dir() else folder
    model = here / MODEL_FILE
    if not model.is_file():
        raise InputError(model, "", "no identified model file here: a log run of a robot read from a URDF writes it "
                                    "(identified/robot.toml)")
    run = verify(here).run  # every file of one run, as it wrote them
    from harness.identify.ls_model import LeastSquaresFit, LeastSquaresModel

    path = here / LEAST_SQUARES_FILE
    ls = LeastSquaresFit.read(path) if path.is_file() else None
    gravity = (0.0, 0.0, -9.80665)
    results = here.parent / "results.json"
    if results.is_file():
        written = json.loads(results.read_text())
        if written.get("run", {}).get("id") != run:
            raise InputError(results, "run.id", f"{written.get('run', {}).get('id')!r}, where {here.name}/ is run "
                                                f"{run!r}'s: the two are not one run's")
        gravity = written.get("scenario", {}).get("gravity", gravity)
    if ls is not None and ls.gravity_W is not None:  # the gravity the fits were made at (a base off level)
        gravity = ls.gravity_W
    spec = load_spec(model)
    if spec.gravity_W is not None:  # the model file states it ([model] gravity: every run since it could)
        gravity = spec.gravity_W
    if fit == "consistent":
        return IdentifiedModel(spec, np.asarray(gravity, dtype=float))
    if ls is None:
        raise InputError(path, "", "no least-squares fit here: a log run writes it (identified/least_squares.toml)")
    return LeastSquaresModel(ls, load_spec(here / ls.model), np.asarray(gravity, dtype=float))


def run(scenario: str | Path | dict | Scenario, progress=None, workers=None, models: dict[str, Any] | None = None,
        model: Any = None, folder: str | Path = ".") -> Result:
    """Run one scenario (a path or name, a dict, or a loaded Scenario) through the whole pipeline
    and check its gates. Nothing is written to disk. `models` ({name: object}) or `model` (named
    "model") are judged as models under test besides the scenario's own. `workers` (a
    harness.base.workers.Workers; default this process) is where a stage's Monte Carlo trials run. A
    dict's files are relative to `folder`."""
    from harness.base.plugins import user_interrupts
    from harness.runner.gates import verdict
    from harness.runner.pipeline import run as run_pipeline
    from harness.runner.results import build_results

    sc = scenario if isinstance(scenario, Scenario | DataScenario) else load_scenario(scenario, folder)
    objects = {**({"model": model} if model is not None else {}), **(models or {})}
    if objects:
        sc = with_models(sc, objects)
    given = {"progress": progress, "workers": workers}  # the rest: the pipeline's defaults
    with user_interrupts():
        out = run_pipeline(sc, **{k: v for k, v in given.items() if v is not None})
    results = verdict(sc.gates, build_results(out), sc.source)
    rows = tuple(GateRow(**r) for r in results["gates"])
    return Result(sc.name, results["passed"], rows, results, out.recording, out)
