"""The generic stages of a run, registered in the order they run. A study (a paper's package, or a
user's) adds its own stages through harness.base.plugins.Study; the pipeline treats both alike."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from harness.base.plugins import Stage
from harness.base.workers import IN_PROCESS, Workers
from harness.engines.recording import Recording

Progress = Callable[[str, float | None], None]


@dataclass(frozen=True, eq=False)
class Context:
    """What every stage may read: the scenario; `recording`, the truth (the bench's ideal recording,
    or a measured log whole); `measured`, what the fit may use (the measurement of the recording, or
    the log's training span); `validation`, a log's validation span, which the pipeline checks is
    disjoint from the training span; and the results of the stages that ran before, by key.
    `cache` holds what several stages need and is made once per run (a validation recording, a
    built model). `workers` is where a stage with independent trials (a Monte Carlo) runs them."""

    scenario: Any  # the run's harness.runner.scenario.Scenario (a DataScenario for a measured log)
    recording: Recording
    measured: Recording
    progress: Progress
    done: dict[str, object] = field(default_factory=dict)
    cache: dict[object, object] = field(default_factory=dict)
    workers: Workers = IN_PROCESS  # where a stage's independent trials may run (harness/base/workers.py)
    validation: object | None = None  # a measured log's validation span, disjoint from `measured` (the training span)

    def once(self, key: object, make: Callable[[], object]) -> object:
        """`make()` the first time `key` is asked for in this run, the same object after that."""
        if key not in self.cache:
            self.cache[key] = make()
        return self.cache[key]


LOG_TABLES = ("friction_law", "refinement")  # the scenario tables of log_stages(), known without importing them
# (their modules import the convex solver and the optimiser: a simulated scenario does not pay for that)


def log_stages() -> tuple[Stage, ...]:
    """The stages of a measured log's run (harness/sources/log.py)."""
    from harness.stages import log_identification, log_methods, refinement

    return (log_identification.STAGE, log_methods.STAGE, refinement.STAGE)


def core_stages() -> tuple[Stage, ...]:
    from harness.stages import estimators, identification, limits, payload, torques

    return (limits.STAGE, torques.STAGE, identification.TORQUE_STAGE, identification.METHODS_STAGE, estimators.STAGE,
            payload.STAGE)
