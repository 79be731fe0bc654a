"""A measured log read, checked, conditioned and split once (harness/sources/log/__init__.py): the
training span, the only data a fit reads, and the validation span, which only the judging reads,
conditioned apart so that no filter, difference or interpolation reaches across the split (the guard
band between them is the trim at the end of the one and the start of the other)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from harness.base.series import every_row
from harness.base.tomlio import InputError
from harness.model.spec import RobotSpec
from harness.sources.log import defaults
from harness.sources.log.checks import check
from harness.sources.log.condition import ConditionedLog, TrainingSpan, condition, conditioned
from harness.sources.log.indexed import resolved
from harness.sources.log.read import read_raw
from harness.sources.log.schema import DataSource
from harness.sources.log.segments import segment_record, segments, split_step
from harness.sources.log.velocity import judged

LOG_FILE = "data.csv"  # the conditioned log, written beside results.json
MIN_SPAN_ROWS = 10  # rows each side of the split needs before conditioning


@dataclass(frozen=True, eq=False)
class Split:
    """A conditioned log split once: `training`, what a fit may read; `validation`, what only the
    judging reads (the last part by time, another file, or none); `guard_band_s`, the seconds between
    the two (None where the validation span is another file); `whole`, the spans one after the other
    as written to data.csv, its `meta` the conditioning record (the training span's steps, the whole
    file's checks, the stretches, the split and the defaults the data decided)."""

    training: TrainingSpan
    validation: ConditionedLog | None
    guard_band_s: float | None
    whole: ConditionedLog
    source: DataSource  # the scenario's [data] with what the data decided (harness/sources/log/defaults.py)

    def __post_init__(self):
        """The one check that the spans are disjoint: each is conditioned from rows on its side of the
        split only, so an overlap is the harness's fault, not the log's."""
        if self.guard_band_s is not None and not self.training.t[-1] < self.validation.t[0]:
            raise RuntimeError(f"the training span (to {self.training.t[-1]:g} s) and the validation span (from "
                               f"{self.validation.t[0]:g} s) overlap")


def load(source: DataSource, robot: RobotSpec) -> Split:
    """The log read (`read_raw`), checked whole (`check`), cut at every gap (a step over `gap` median
    steps) and, when split by time, at the split: each stretch is resampled, filtered, differentiated
    and trimmed on its own (on the whole file's grid rate), so that no filter or difference reaches
    across a gap or the split (the trim at both ends of each stretch is the guard band). A validation
    file is conditioned whole, on its own."""
    given = source  # a validation file's columns resolved from the scenario's own (its messages' order)
    source = resolved(source, robot, source.file)
    checked = check(read_raw(source, robot), robot, source)  # the rows read let go of: `kept` holds what is used
    kept, rate = checked.kept, checked.rate(source)
    t_split = None if source.validation_from is None else \
        kept.t[0] + source.validation_from * (kept.t[-1] - kept.t[0])
    # what the data decide, they decide from the training rows alone
    training_rows = kept if t_split is None else kept.span(kept.t < t_split)
    kept, velocities, late = judged(kept, training_rows, list(robot.joint_names), source.velocities)
    source, chosen = defaults.resolve(source, kept if t_split is None else kept.span(kept.t < t_split), rate)
    longest = split_step(source, checked.median_step)
    pieces = segments(kept.t, longest)
    notes: list[str] = [late] if late else []
    if chosen is not None:
        notes.append(f"no cutoff given, and the accelerations would carry noise (the motion within "
                     f"{max(chosen['motion_band_hz']):.3g} Hz): a {chosen['cutoff_hz']:.3g} Hz low-pass chosen"
                     + ("" if source.decimate_given else f", decimate {chosen['decimate']}")
                     + " (data.conditioning.defaults)")
    if len(pieces) > 1:
        notes.append(f"{len(pieces) - 1} gap(s) over {longest:.3g} s (largest {float(np.max(np.diff(kept.t))):.3g} "
                     f"s): the log is conditioned in {len(pieces)} stretches, nothing filtered across a gap")
    record = segment_record(kept.t, pieces, source, checked.median_step)
    if source.validation_from is None:
        log = conditioned(kept, pieces, source, robot, rate, checked, "log", notes)
        log.meta["segments"], log.meta["defaults"], log.meta["velocities"] = record, chosen, velocities
        log.meta["warnings"] = log.meta["warnings"] + notes
        val = None
        if source.validation_file is not None:
            of_file = resolved(given, robot, source.validation_file)
            val = condition(read_raw(of_file, robot, source.validation_file), of_file, robot)
        return Split(TrainingSpan.of(log), val, None, dataclasses.replace(log, full_rate=None), source)
    before = kept.t < t_split
    if before.sum() < MIN_SPAN_ROWS or (~before).sum() < MIN_SPAN_ROWS:
        raise InputError(source.file, "validation.from", f"splitting at {t_split:g} s leaves too few rows "
                                                         f"({int(before.sum())} and {int((~before).sum())})")
    spans = {name: [p[side[p]] for p in pieces if side[p].any()] for name, side in (("training", before),
                                                                                      ("validation", ~before))}
    train, val = (conditioned(kept, spans[name], source, robot, rate, checked, f"{name} span", notes)
                  for name in ("training", "validation"))
    train = TrainingSpan.of(train)
    guard = float(val.t[0] - train.t[-1])
    conditioning = dict(train.meta)
    conditioning["warnings"] = conditioning["warnings"] + notes
    conditioning["segments"], conditioning["defaults"], conditioning["velocities"] = record, chosen, velocities
    conditioning["validation"] = {
        "from_fraction": source.validation_from, "t_split": float(t_split),
        "training_samples": len(train.t), "validation_samples": len(val.t),
        "guard_band_s": guard, "disjoint": True,
        "conditioned": "each span on its own (resampling, filter, derivatives, trim): nothing crosses the split",
        "training": {"t_start": train.meta["t_start"], "t_end": train.meta["t_end"]},
        "validation": {"t_start": val.meta["t_start"], "t_end": val.meta["t_end"]}}
    whole = ConditionedLog(joints=train.joints, contacts=train.contacts, meta=conditioning, reach_s=train.reach_s,
                           **every_row([train, val]))
    return Split(train, val, guard, whole, source)


def load_payload(source: DataSource, robot: RobotSpec) -> ConditionedLog | None:
    """The known-payload log (`[data.payload]`), conditioned as a validation file is, or None."""
    if source.payload is None:
        return None
    source = resolved(source, robot, source.payload.file)
    return condition(read_raw(source, robot, source.payload.file), source, robot)
