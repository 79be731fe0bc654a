"""Step 1 of the conditioning (harness/sources/log/__init__.py), on a whole file: every sample in time
order, the rows a logger repeated dropped, the velocities and positions checked against the units
given (harness/sources/log/units.py), the clock's steps, gaps and jitter counted, positions beyond the
joint limits counted; a record for results.json and the warnings for the terminal."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from harness.base.tomlio import InputError
from harness.model.spec import RobotSpec
from harness.sources.log.raw import RawLog
from harness.sources.log.schema import DataSource
from harness.sources.log.segments import GAP_FACTOR, GAP_SPLIT, split_step
from harness.sources.log.units import check_positions, check_velocities

MAX_UPSAMPLING = 100.0  # a grid this many times finer than the log's own median step is not resampling
DEAD_SHARE = 0.5  # a torque channel reading exactly 0 on this share of the rows measures nothing there


@dataclass(frozen=True, eq=False)
class Checked:
    """Step 1 of the module docstring, on a whole file: its rows in time order, the step's record
    and its warnings."""

    kept: RawLog  # the rows kept: no repeated positions, no repeated times
    record: dict  # the "checks" step of results.json
    warnings: list[str]
    median_step: float  # s

    def rate(self, source: DataSource) -> float:
        """The uniform grid's rate: the scenario's, else one sample per median step."""
        return source.rate or 1.0 / self.median_step


def check(raw: RawLog, robot: RobotSpec, source: DataSource | None = None) -> Checked:
    """Step 1 of the module docstring."""
    path, t = raw.file, raw.t
    if source is None or source.limits_check:
        check_positions(raw, robot, source)
    steps, warnings = [], []
    if source is not None and not source.units_given:
        warnings.append("no units stated ([data] units): taken as rad, rad/s and N m (m, m/s and N for a slide)")
    # a logger's sample and hold repeats the whole row; a quantised encoder repeats a position while
    # the torques move on, and that is data
    same_q = np.all(raw.q[1:] == raw.q[:-1], axis=1)
    whole = same_q & np.all(raw.tau[1:] == raw.tau[:-1], axis=1)
    if raw.qd is not None:
        whole &= np.all(raw.qd[1:] == raw.qd[:-1], axis=1)
    held = np.r_[False, whole]
    same_time = np.r_[False, t[1:] == t[:-1]]
    drop = held | same_time
    keep = ~drop
    tk = t[keep]
    backwards = np.flatnonzero(np.diff(tk) <= 0)
    if len(backwards):
        row = np.flatnonzero(keep)[backwards[0] + 1]
        raise InputError(path, "t", f"time goes backwards at row {row + 2} ({t[row]:g} s after "
                                    f"{tk[backwards[0]]:g} s): not a log in time order")
    if len(tk) < 10:
        dropped = int(drop.sum())
        raise InputError(path, "t", f"{len(tk)} distinct sample{'' if len(tk) == 1 else 's'} in {len(raw.t)} rows, "
                                    "at least 10 needed" + (f" ({dropped} rows repeat the time, or the whole row, of "
                                                            "the row before them, and are dropped)" if dropped else ""))
    kept = raw if keep.all() else raw.span(keep)  # the rows kept: checked here, conditioned after
    check_velocities(kept, robot, source)
    dt = np.diff(tk)
    median = float(np.median(dt))
    if source is not None and source.rate is not None and source.rate * median > MAX_UPSAMPLING:
        raise InputError(path, "rate", f"{source.rate:g} Hz is {source.rate * median:.3g} times the log's own rate "
                                       f"(its median step {median:.3g} s): a grid over {MAX_UPSAMPLING:g} times finer "
                                       "than the samples would be made by interpolation alone. Is t in seconds?")
    gaps = dt > GAP_FACTOR * median
    jitter = float(np.std(dt) / median)
    steps.append({"step": "checks", "rows": len(raw.t), "repeated_rows_dropped": int(held.sum()),
                  "repeated_positions_kept": int(np.sum(same_q & ~whole)),
                  "equal_times_dropped": int((same_time & ~held).sum()), "median_step_s": median,
                  "min_step_s": float(dt.min()), "max_step_s": float(dt.max()), "jitter": jitter,
                  "gaps": int(gaps.sum()), "gap_definition": f"a step over {GAP_FACTOR:g} x the median"})
    if held.any():
        warnings.append(f"{int(held.sum())} rows repeat the previous row whole (positions"
                        f"{', velocities' if raw.qd is not None else ''} and torques: sample and hold): dropped")
    split_over = split_step(source, median) if source is not None else GAP_SPLIT * median
    bridged = gaps & (dt <= split_over)
    if bridged.any():
        warnings.append(f"{int(bridged.sum())} steps over {GAP_FACTOR:g} median steps but not over {split_over:.3g} s "
                        f"(largest {dt[bridged].max():.3g} s, median step {median:.3g} s): bridged by interpolation")
    beyond = {}
    for j, name in enumerate(robot.joint_names):
        lo, hi = (robot.limits or {}).get(name, (-np.inf, np.inf))
        outside = int(np.sum((kept.q[:, j] < lo) | (kept.q[:, j] > hi)))
        if outside:
            beyond[name] = outside
    if beyond:
        warnings.append("positions beyond the model's joint limits: "
                        + ", ".join(f"{k} {v} rows" for k, v in beyond.items()))
    steps[0]["beyond_joint_limits"] = beyond
    unmeasured = () if source is None else source.unmeasured  # declared: no channel of theirs is read
    zero = {name: float(share) for name, share in zip(kept.joints, np.mean(kept.tau == 0.0, axis=0), strict=True)
            if name not in unmeasured}
    dead = [name for name, share in zero.items() if share >= DEAD_SHARE]
    steps[0]["torque_zero_share"], steps[0]["torque_channels_zero"] = zero, dead
    if dead:
        warnings.append("torque channels that read exactly 0 on most rows (a channel that measures nothing, or a "
                        "joint held by its brake?): " + ", ".join(f"{name} {100 * zero[name]:.0f} %" for name in dead)
                        + "; the fit reads them as measured ([data] unmeasured = [...] leaves a channel out, its "
                          "joint's motion kept)")
    return Checked(kept, steps[0], warnings, median)

