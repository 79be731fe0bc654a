"""The public API: what a user's script, notebook or test suite calls.

    import harness
    result = harness.run("scenarios/my_arm.toml")
    result.passed                   # every gate passed
    for g in result.gates:          # name, metric, value, limit, direction, passed, reason
        print(g.name, g.value, g.limit, g.passed)
    result.results                  # the content of results.json
    result.recording                # the recording (harness.recording.Recording)

`harness.load_scenario(path)` and `harness.load_model(path)` load and validate a scenario or a
robot description (TOML or URDF model file) without running anything. Bad input raises
harness.InputError (file, key, message); a plugin that breaks its protocol raises
harness.PluginError.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from harness.recording import Recording
from harness.scenario import DataScenario, Scenario
from harness.scenario import load_scenario as _load_scenario
from harness.spec import RobotSpec, load_spec


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


@dataclass(frozen=True, eq=False)
class Result:
    scenario: str
    passed: bool
    gates: tuple[GateRow, ...]
    results: dict  # results.json
    recording: Recording
    output: Any = None  # the pipeline's typed results (harness.pipeline.RunOutput)

    @property
    def failed(self) -> tuple[GateRow, ...]:
        return tuple(g for g in self.gates if not g.passed)


def load_scenario(path: str | Path) -> Scenario | DataScenario:
    return _load_scenario(Path(path))


def load_model(path: str | Path) -> RobotSpec:
    return load_spec(Path(path))


def run(scenario: str | Path | Scenario, progress=None, workers=None) -> Result:
    """Run one scenario (a path, or a loaded Scenario) through the whole pipeline and check its
    gates. Nothing is written to disk. `workers` (a harness.workers.Workers; default this process)
    is where a stage's Monte Carlo trials run."""
    from harness.gates import verdict
    from harness.pipeline import run as run_pipeline
    from harness.results import build_results

    sc = scenario if isinstance(scenario, Scenario | DataScenario) else load_scenario(scenario)
    given = {"progress": progress, "workers": workers}  # the rest: the pipeline's defaults
    out = run_pipeline(sc, **{k: v for k, v in given.items() if v is not None})
    results = verdict(sc.gates, build_results(out), sc.source)
    rows = tuple(GateRow(**r) for r in results["gates"])
    return Result(sc.name, results["passed"], rows, results, out.recording, out)
