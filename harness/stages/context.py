"""What every stage reads: the run's Context, as the source gave it (harness/runner/pipeline.py)."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

from harness.base.series import TimeSeries
from harness.base.workers import IN_PROCESS, Workers

Progress = Callable[[str, float | None], None]

VALIDATION_SPAN = "validation span"  # a measured log's validation span, in Context.validation


@dataclass(frozen=True, eq=False)
class Context:
    """What every stage may read, as its source gave it (harness/runner/pipeline.py):
    - `scenario`, the run's harness.runner.scenario.Scenario (a DataScenario for a measured log);
    - `truth`, the bench's ideal recording, which the engines are judged on (None on a measured log:
      nobody knows its truth);
    - `training`, the only data a fit reads: the measurement of the bench's recording, or a log's
      training span;
    - `validation`, data no fit reads, by name: a log's validation span (VALIDATION_SPAN), or each
      scenario a bench scenario's stages name (a validation trajectory, the run without a payload:
      Stage.recordings), recorded once by the source (`recorded`);
    - `done`, the results of the stages that ran before, by key.
    `cache` holds what several stages compute and is made once per run (a built model, the structural
    base parameters). `workers` is where a stage with independent trials (a Monte Carlo) runs them."""

    scenario: Any
    truth: TimeSeries | None
    training: TimeSeries
    progress: Progress
    validation: Mapping[str, TimeSeries] = field(default_factory=dict)
    done: dict[str, object] = field(default_factory=dict)
    cache: dict[object, object] = field(default_factory=dict)
    workers: Workers = IN_PROCESS  # where a stage's independent trials may run (harness/base/workers.py)
    payload: TimeSeries | None = None  # a log with a known load ([data.payload]), conditioned as the log is:
    # read by the fit as the training span is (it fixes the scale of the torque constants)

    def once(self, key: object, make: Callable[[], object]) -> object:
        """`make()` the first time `key` is asked for in this run, the same object after that."""
        if key not in self.cache:
            self.cache[key] = make()
        return self.cache[key]

    def recorded(self, setup) -> TimeSeries:
        """The bench's recording of another scenario a stage names (`Stage.recordings`), which the
        source recorded before the stages ran."""
        return self.validation[recording_key(setup)]


def recording_key(setup) -> str:
    """The name under which a related scenario's recording is kept in Context.validation."""
    return str(setup.source)
