"""Steps 2-6 of the conditioning (harness/sources/log/__init__.py), each stretch of a checked log on
its own: resampling to a uniform grid, a zero-phase low-pass, derivatives, the guard band trimmed at
both ends, decimation.

A filtered log keeps, beside its rows, what a fit needs to filter a nonlinear column of the
velocities as the torques were filtered (`ConditionedLog.full_rate`, a FilteredColumns): the measured
torque of a Coulomb turn is the filtered tanh(q'/v_c), not tanh of the filtered q', and a fit that
compares the one with the other chooses a smeared turn (a larger v_c) the robot does not have."""

from __future__ import annotations

from dataclasses import dataclass, fields
from functools import cached_property

import numpy as np

from harness.base.numerics import sampled
from harness.base.series import TimeSeries, every_row
from harness.base.tomlio import InputError
from harness.model.spec import RobotSpec
from harness.sources.log.checks import Checked, check
from harness.sources.log.raw import RawLog
from harness.sources.log.schema import DataSource
from harness.sources.log.segments import guard_band, segments, split_step


@dataclass(frozen=True, eq=False)
class FilteredColumns:
    """A filtered span's velocities at the grid's full rate, stretch by stretch, with the filter and
    the rows kept: `filtered(fn, t)` is fn of the velocities, (M, n) -> (M, k), computed at the full
    rate, filtered by the same zero-phase low-pass as the torques (scipy.signal.sosfiltfilt) and read
    at the rows kept whose times are `t` (the span's, or a part of them: a span read later by a
    delay's correction), (len(t), k)."""

    sos: np.ndarray
    stretches: tuple[tuple[np.ndarray, np.ndarray], ...]  # per stretch: q' (M, n) at the full rate, rows kept
    t: np.ndarray  # the kept rows' times, every stretch's in order
    cutoff_hz: float = float("inf")  # the low-pass's: what it resolves in time, 1 / (2 pi cutoff_hz)

    def covers(self, t: np.ndarray) -> bool:
        return bool(len(t) and np.all(np.isin(t, self.t)))

    def filtered(self, fn, t: np.ndarray) -> np.ndarray:
        out = np.concatenate([zero_phase(self.sos, fn(qd), self._steady)[rows] for qd, rows in self.stretches])
        return out[self._at(t)]

    @cached_property
    def _steady(self) -> np.ndarray:
        """The filter's steady-state initial conditions per unit step (scipy.signal.sosfilt_zi), once."""
        from scipy.signal import sosfilt_zi

        return sosfilt_zi(self.sos)

    def _at(self, t: np.ndarray) -> np.ndarray:
        """Which kept rows are at the times t; the last answer kept (a search asks for the same rows
        thousands of times)."""
        last = self.__dict__.get("_last_at")
        if last is None or last[0] is not t:
            last = (t, np.isin(self.t, t))
            self.__dict__["_last_at"] = last
        return last[1]

    @staticmethod
    def joined(parts: list[FilteredColumns]) -> FilteredColumns:
        return FilteredColumns(parts[0].sos, tuple(s for p in parts for s in p.stretches),
                               np.concatenate([p.t for p in parts]), parts[0].cutoff_hz)


def zero_phase(sos: np.ndarray, x: np.ndarray, steady: np.ndarray) -> np.ndarray:
    """scipy.signal.sosfiltfilt(sos, x, axis=0) (its default odd padding of 3 (2 sections + 1) rows)
    with its initial conditions `steady` = sosfilt_zi(sos) given: the same operations in the same
    order, bit for bit (tests/test_filtered.py), without recomputing sosfilt_zi and checking
    the filter at every call. A column too short for the padding goes to scipy, which says why."""
    from scipy.signal import sosfilt, sosfiltfilt

    edge = 3 * (2 * len(sos) + 1 - min(int(np.sum(sos[:, 2] == 0)), int(np.sum(sos[:, 5] == 0))))
    if len(x) <= edge:
        return sosfiltfilt(sos, x, axis=0)
    ext = np.concatenate((2 * x[:1] - x[edge:0:-1], x, 2 * x[-1:] - x[-2:-(edge + 2):-1]), axis=0)
    zi = steady.reshape(len(sos), 2, *([1] * (x.ndim - 1)))
    y, _ = sosfilt(sos, ext, axis=0, zi=zi * ext[:1])
    y, _ = sosfilt(sos, y[::-1], axis=0, zi=zi * y[-1:])
    return y[::-1][edge:-edge]


@dataclass(frozen=True, eq=False)
class ConditionedLog(TimeSeries):
    """A conditioned log: its rows (a TimeSeries, its invariants checked), the conditioning's record in
    `meta` (what results.json writes), and what a fit reads beyond the rows, typed."""

    full_rate: FilteredColumns | None = None  # a low-passed span's velocities at the full rate; None unfiltered
    reach_s: float = 0.0  # s: how far a sample's conditioning reaches, the guard between any two parts


@dataclass(frozen=True, eq=False)
class TrainingSpan(ConditionedLog):
    """The training span (harness/sources/log/split.py): the only rows a fit may read. The fitting steps
    of a log's identification take this type and refuse another (`fits_on`); what they find (a delay, a
    torque constant) the judging applies to the validation span, never the fit. A span of it, a delay
    corrected or a factor applied (dataclasses.replace), stays one."""

    @staticmethod
    def of(log: ConditionedLog) -> TrainingSpan:
        return TrainingSpan(**{f.name: getattr(log, f.name) for f in fields(log)})


def fits_on(series: TimeSeries) -> TrainingSpan:
    """`series` where it is the training span; a fit handed another (the validation span, a whole log) is
    a harness bug, refused here."""
    if not isinstance(series, TrainingSpan):
        raise TypeError(f"a fit reads the training span alone, and was handed a {type(series).__name__}")
    return series


def condition(raw: RawLog, source: DataSource, robot: RobotSpec) -> ConditionedLog:
    """Steps 1-6, for a log taken whole (a validation file, a payload log), cut at its gaps."""
    checked = check(raw, robot, source)
    notes: list[str] = []
    pieces = segments(checked.kept.t, split_step(source, checked.median_step))
    log = conditioned(checked.kept, pieces, source, robot, checked.rate(source), checked, raw.file.name, notes)
    log.meta["warnings"] = log.meta["warnings"] + notes
    return log


def smooth(kept: RawLog, source: DataSource, robot: RobotSpec, rate: float, checks: dict,
           check_warnings: list[str]) -> ConditionedLog:
    """Steps 2-6 of the package docstring on checked rows (`check`), whose record and warnings
    open the conditioning's."""
    from scipy.signal import butter, sosfiltfilt

    path, tk, raw = kept.file, kept.t, kept
    steps = [*([raw.read] if raw.read else []), checks]
    warnings = [*raw.read.get("warnings", []), *check_warnings]
    # 2. uniform grid
    grid = tk[0] + np.arange(int(np.floor((tk[-1] - tk[0]) * rate)) + 1) / rate

    def resample(x: np.ndarray) -> np.ndarray:
        return sampled(tk, x, grid)

    q, tau = resample(raw.q), resample(raw.tau)
    qd = resample(raw.qd) if raw.qd is not None else None
    extra = {k: resample(x.reshape(len(tk), -1)) for k, x in raw.extra.items()}  # a floating base's, flattened
    steps.append({"step": "resample", "rate_hz": rate, "method": "linear interpolation of the kept rows",
                  "samples": len(grid)})
    # 3. zero-phase low-pass
    if source.cutoff is not None:
        if source.cutoff >= rate / 2:
            raise InputError(path, "cutoff", f"{source.cutoff:g} Hz is not below the Nyquist frequency "
                                             f"{rate / 2:g} Hz of the {rate:g} Hz grid")
        sos = butter(source.filter_order, source.cutoff, fs=rate, output="sos")
        pad = 3 * (2 * len(sos) + 1)
        if len(grid) <= pad:
            raise InputError(path, "cutoff", f"{len(grid)} samples are too few to filter (need over {pad})")

        def lowpass(x: np.ndarray) -> np.ndarray:
            """Column by column into one array (the same numbers as the whole at once: its padded copies
            are a column's, not the quantity's)."""
            out = np.empty_like(x)
            for j in range(x.shape[1]):
                out[:, j] = sosfiltfilt(sos, x[:, j])
            return out

        q, tau = lowpass(q), lowpass(tau)
        qd = lowpass(qd) if qd is not None else None
        extra = {k: lowpass(x) for k, x in extra.items()}
        steps.append({"step": "low-pass", "filter": f"Butterworth order {source.filter_order}, applied forward "
                      "and backward (zero phase, scipy.signal.sosfiltfilt)", "cutoff_hz": source.cutoff,
                      "signals": ["q", "qd" if raw.qd is not None else None, "tau"]})
    else:
        warnings.append("no low-pass filter (`cutoff`): accelerations are differences of unfiltered data")
    # 4. derivatives
    h = 1.0 / rate
    if qd is None:
        qd = np.gradient(q, h, axis=0)
    qdd = np.gradient(qd, h, axis=0)
    if "base_twist_W" in extra:
        extra["base_rate_W"] = np.gradient(extra["base_twist_W"], h, axis=0)
    steps.append({"step": "differentiate", "method": "central differences (numpy.gradient, second order) of the "
                  "filtered " + ("velocities" if raw.qd is not None else "positions (velocities) and velocities"),
                  "velocities": "measured" if raw.qd is not None else "differentiated"})
    # 5. trim and decimate
    trim = guard_band(source, rate)
    k0 = int(np.ceil(trim * rate))
    rows = np.arange(k0, len(grid) - k0, source.decimate)
    if len(rows) < 10:
        raise InputError(path, "trim", f"trimming {trim:g} s at each end leaves {len(rows)} samples")
    if source.cutoff is not None and source.decimate > 1 and source.cutoff >= rate / source.decimate / 2:
        raise InputError(path, "decimate", f"keeping every {source.decimate}th sample of {rate:g} Hz aliases the "
                                           f"{source.cutoff:g} Hz band: the cut-off must be below "
                                           f"{rate / source.decimate / 2:g} Hz")
    steps.append({"step": "trim and decimate", "trim_s": trim, "decimate": source.decimate,
                  "samples": len(rows), "rate_hz": rate / source.decimate})
    conditioning = {"file": str(path), "sha256": raw.sha256, "steps": steps, "warnings": warnings,
                    "t_start": float(grid[rows[0]]), "t_end": float(grid[rows[-1]])}
    full_rate = FilteredColumns(sos, ((qd, rows),), grid[rows], float(source.cutoff)) \
        if source.cutoff is not None else None
    base = floating_rows(source, robot, q[rows], {k: x[rows] for k, x in extra.items()}) if extra else {}
    return ConditionedLog(grid[rows], tuple(robot.joint_names), q[rows], qd[rows], qdd[rows], tau[rows],
                          meta=conditioning, full_rate=full_rate, reach_s=trim, **base)


def floating_rows(source: DataSource, robot: RobotSpec, q: np.ndarray, extra: dict) -> dict:
    """A floating base's fields of a conditioned span (harness/base/series.py) from its resampled, filtered,
    differentiated (the twist's rate, as the joints' q'' are) and trimmed channels `extra` (each flattened to
    (N, k)): the quaternion made unit again, each contact's point from the kinematics at the span's states."""
    from harness.model.contacts import contact_points
    from harness.model.floating import BaseMotion

    pose = extra["base_pose"].copy()
    pose[:, 3:] /= np.linalg.norm(pose[:, 3:], axis=1, keepdims=True)
    out = {"base_pose": pose, "base_twist_W": extra["base_twist_W"], "base_rate_W": extra["base_rate_W"]}
    contacts = source.floating.contacts
    if contacts:
        k = len(contacts)
        base = BaseMotion.from_rows(pose, out["base_twist_W"], out["base_rate_W"])
        out.update(contacts=tuple(c.name for c in contacts), contact_F_W=extra["contact_F_W"].reshape(-1, k, 3),
                   contact_M_W=extra["contact_M_W"].reshape(-1, k, 3),
                   contact_x_W=contact_points(robot, contacts, base, q))
    return out



def conditioned(kept: RawLog, pieces: list[np.ndarray], source: DataSource, robot: RobotSpec, rate: float,
                 checked: Checked, label: str, notes: list[str]) -> ConditionedLog:
    """Each stretch of rows conditioned on its own (steps 2-5), the stretches too short for the filter
    and the trim dropped (said in `notes`), the rest joined in time order."""
    reach = guard_band(source, rate)
    pad = 3 * (2 * int(np.ceil(source.filter_order / 2)) + 1) if source.cutoff is not None else 0
    logs, dropped = [], []
    for rows in pieces:
        t0, t1 = kept.t[rows[0]], kept.t[rows[-1]]
        samples = int(np.floor((t1 - t0) * rate)) + 1
        if samples <= pad or samples - 2 * int(np.ceil(reach * rate)) < 10 * source.decimate:
            dropped.append((float(t0), float(t1)))
            continue
        # a stretch's rows are consecutive: a view of them, not a copy
        stretch = slice(rows[0], rows[-1] + 1) if rows[-1] - rows[0] + 1 == len(rows) else rows
        logs.append(smooth(kept.span(stretch), source, robot, rate, checked.record, checked.warnings))
    if dropped:
        notes.append(f"{label}: {len(dropped)} stretch(es) between gaps too short to filter and trim "
                     f"({', '.join(f'{a:.3g}-{b:.3g} s' for a, b in dropped[:4])}"
                     f"{' ...' if len(dropped) > 4 else ''}): dropped")
    if not logs:
        raise InputError(kept.file, "gap", f"{label}: no stretch between gaps is long enough to filter and "
                                           f"trim ({2 * reach:.3g} s of trim and 10 samples at least)")
    if len(logs) == 1:
        return logs[0]
    rows = every_row(logs)  # the stretches in time order
    conditioning = dict(logs[0].meta)
    conditioning["t_end"] = logs[-1].meta["t_end"]
    full_rate = FilteredColumns.joined([g.full_rate for g in logs]) if all(g.full_rate is not None for g in logs) \
        else None
    return ConditionedLog(joints=logs[0].joints, contacts=logs[0].contacts, meta=conditioning, full_rate=full_rate,
                          reach_s=logs[0].reach_s, **rows)

