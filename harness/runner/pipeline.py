"""The data flow of DESIGN.md for one scenario, the same for every scenario: a source gives the
data (the bench: optimise the excitation where asked, simulate, measure; or a measured log: read,
condition, split), then the registered stages run in order: the core's (harness/stages/), then
those of each study the scenario asks for. Each stage is a function from immutable inputs to a typed result;
this module only chains them, times them and gathers the results.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Iterator
from contextlib import nullcontext
from dataclasses import dataclass
from typing import Any

import numpy as np

from harness.base.plugins import Stage, guard
from harness.base.series import TimeSeries
from harness.base.workers import IN_PROCESS, Workers
from harness.identify.excitation import optimise as optimise_excitation
from harness.model.spec import RobotSpec
from harness.runner.scenario import DataScenario, Scenario
from harness.sources.bench import record
from harness.sources.measurement import measure
from harness.stages import VALIDATION_SPAN, Context, Progress, core_stages, log_stages, recording_key
from harness.stages.shared import with_friction


@dataclass(frozen=True, eq=False)
class StageOutput:
    stage: Stage
    config: Any
    result: Any


@dataclass(frozen=True, eq=False)
class RunOutput:
    scenario: Scenario  # with the optimised motion, where the excitation was optimised
    recording: TimeSeries  # what the run writes: the bench's ideal recording (the truth), or the whole conditioned log
    measured: TimeSeries  # what the identification sees: the measured recording, or the log's training span
    context: Context
    stages: dict[str, StageOutput]  # by results.json key, in the order they ran
    excitation: dict | None = None
    timings: dict | None = None  # seconds per stage

    @property
    def files(self) -> dict[str, str]:
        """The files the stages add to the output folder, {relative path: text}."""
        out: dict[str, str] = {}
        for s in self.stages.values():
            if s.stage.files is not None:
                out.update(s.stage.files(s.result))
        return out

    def __getitem__(self, key: str) -> Any:
        """The typed result of the stage that writes `key` (KeyError: it did not run)."""
        return self.stages[key].result


def _quiet(stage: str, fraction: float | None) -> None:
    pass


class _Timed:
    """Passes progress on and adds up the seconds spent in each stage."""

    def __init__(self, progress: Progress):
        self.progress, self.timings, self.stage, self.start = progress, {}, None, time.perf_counter()

    def __call__(self, stage: str, fraction: float | None) -> None:
        if fraction is None:
            self.close()
            self.stage, self.start = stage, time.perf_counter()
        self.progress(stage, fraction)

    def close(self) -> None:
        if self.stage is not None:
            self.timings[self.stage] = self.timings.get(self.stage, 0.0) + time.perf_counter() - self.start
            self.stage = None

    def drop(self, stage: str) -> None:
        """Forget a stage that turned out to have nothing to do for this scenario."""
        if self.stage == stage:
            self.stage = None


def stages_of(scenario: Scenario | DataScenario) -> Iterator[tuple[Stage, Any, str | None]]:
    """The stages a scenario runs, with their configuration and the study they belong to (None for
    the core's): the core's (a measured log's own, for a log), then each study's."""
    configs = getattr(scenario, "configs", {})
    for stage in log_stages() if isinstance(scenario, DataScenario) else core_stages():
        yield stage, configs.get(stage.key), None
    for study, config in getattr(scenario, "studies", ()):
        for stage in study.stages:
            yield stage, config, study.name


@dataclass(frozen=True, eq=False)
class Sourced:
    """What a source gives the stages (harness.stages.Context): the truth (the bench's ideal
    recording; None for a log), what a fit may read (the measurement of the recording, or the log's
    training span, with a known-payload log beside it), what only the judging reads (the log's
    validation span, or every scenario the bench scenario's stages name, recorded once), and what the
    run writes beside results.json (the recording, or the whole conditioned log)."""

    truth: TimeSeries | None
    training: TimeSeries
    validation: dict[str, TimeSeries]
    written: TimeSeries
    payload: TimeSeries | None = None
    robot: RobotSpec | None = None  # the scenario's robot as the source read it (a closed chain's log: its
    # passive balls' charts turned to the training span, harness/sources/log/closed.py); None: as it was


def from_bench(scenario: Scenario, timed: _Timed) -> Sourced:
    """The scenario's robot simulated in MuJoCo along its motion, then measured; each other scenario
    its stages read (Stage.recordings: a validation trajectory, the same motion without a payload)
    simulated once."""
    timed("simulating in MuJoCo", None)
    recording = record(scenario)
    related: dict[str, TimeSeries] = {}
    for stage, config, _ in stages_of(scenario):
        for setup in (stage.recordings(config, scenario) if stage.recordings is not None else ()):
            if recording_key(setup) not in related:
                timed(f"simulating {setup.name} in MuJoCo", None)
                related[recording_key(setup)] = record(setup)
    return Sourced(recording, measure(recording, scenario.measurement), related, recording)


def from_log(scenario: DataScenario, timed: _Timed) -> Sourced:
    """A measured log (harness/sources/log/) read, conditioned and split once; a known-payload log
    beside it conditioned the same way."""
    from harness.sources.log import load, load_payload
    from harness.sources.log.closed import charted, closed, logged

    timed("reading and conditioning the log", None)
    split = load(scenario.data, logged(scenario.robot))  # a closed chain's log: its actuated joints, the others
    robot = charted(split.training, scenario.robot, scenario.data.file)  # from its loops
    training, validation_span, whole = (closed(s, robot, scenario.data.file)
                                        for s in (split.training, split.validation, split.whole))
    validation = {} if validation_span is None else {VALIDATION_SPAN: validation_span}
    payload = split.source.payload
    loaded = None if payload is None else closed(load_payload(split.source, logged(robot)), robot, payload.file)
    return Sourced(None, training, validation, whole, loaded, None if robot is scenario.robot else robot)


def run(scenario: Scenario | DataScenario, progress: Progress = _quiet,
        workers: Workers = IN_PROCESS) -> RunOutput:
    """One pipeline for every scenario: its source (the bench, or a measured log) gives the data,
    then its stages run in order. The engines are built from the scenario's robot (the truth); each
    model under test and each identification method from what the scenario names, and judged
    against them. A stage's Monte Carlo trials run on `workers` (harness/base/workers.py)."""
    timed = _Timed(progress)
    excitation = None
    if isinstance(scenario, DataScenario):
        data = from_log(scenario, timed)
        if data.robot is not None:  # the log's passive balls in charts of its motion: the truth read in them too
            from harness.model.charts import carried

            truth = None if scenario.truth is None else carried(scenario.truth, data.robot)
            scenario = dataclasses.replace(scenario, robot=data.robot, truth=truth)
    else:
        if scenario.excitation is not None:
            timed("optimising the excitation (Fourier series)", None)
            scenario, excitation = optimise_excitation(scenario, scenario.excitation, with_friction(scenario))
        data = from_bench(scenario, timed)
    ctx = Context(scenario, data.truth, data.training, timed, data.validation, workers=workers, payload=data.payload)
    outputs: dict[str, StageOutput] = {}
    for stage, config, study in stages_of(scenario):
        timed(stage.progress, None)
        # 0/0 where nothing moves or nothing is loaded is NaN, not an error: results.json writes it
        # as null, lists it in run.not_finite, and a gate on it fails closed. A study's stage is
        # plugin code: whatever it raises is the study's failure (exit 2), not the harness's.
        with np.errstate(invalid="ignore", divide="ignore"), \
                (guard(f"study {study}", f"stage {stage.key!r}") if study else nullcontext()):
            result = stage.run(ctx, config)
        ctx.done[stage.key] = result
        if result is None:
            timed.drop(stage.progress)
        else:
            outputs[stage.key] = StageOutput(stage, config, result)
    timed.close()
    return RunOutput(scenario, data.written, data.training, ctx, outputs, excitation, timed.timings)
