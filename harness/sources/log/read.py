"""A log's file read as it is: a CSV's header and columns (or a ROS bag's JointState messages,
harness/sources/bag.py) for the model's joints, every refusal naming the file and the column; the
values made SI (harness/sources/log/units.py). What it gives is a raw TimeSeries: q, q' where the log
has them, tau, no accelerations, and the file and its sha256 in `meta`."""

from __future__ import annotations

import csv
import hashlib
import io
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from harness.base.series import TimeSeries
from harness.base.tomlio import MAX_DATA_BYTES, InputError, Table, read_bounded
from harness.model.spec import RobotSpec
from harness.sources.log.schema import DataSource, column_names
from harness.sources.log.units import to_si

if TYPE_CHECKING:  # pandas is imported where a log is read: a bench run does not need it
    import pandas as pd


def raw_series(path: Path, sha256: str, t: np.ndarray, q: np.ndarray, qd: np.ndarray | None, tau: np.ndarray,
               joints: tuple[str, ...]) -> TimeSeries:
    """A log as read: no accelerations (they come from its conditioning), the file named in `meta`."""
    return TimeSeries(t, joints, q, qd, None, tau, meta={"file": Path(path), "sha256": sha256})


TORQUE_FILE_COLUMNS = ("tau",)  # what a separate torque file (`torque_file`) holds; `file` holds the rest


def _kinds(source: DataSource, path: Path) -> tuple[str, ...]:
    """The quantities the CSV at `path` holds: all, or with a torque file its part."""
    if source.torque_file is None:
        return ("t", "q", "qd", "tau")
    return TORQUE_FILE_COLUMNS if path == source.torque_file else ("t", "q", "qd")


def _check_header(path: Path, header: list[str], source: DataSource, robot: RobotSpec) -> None:
    kinds = _kinds(source, path)
    for kind, names in column_names(source, robot).items():
        if kind not in kinds:
            continue
        for name in names:
            if name not in header:
                raise InputError(path, name, f"column missing (the log has {', '.join(map(str, header[:12]))}"
                                             f"{' ...' if len(header) > 12 else ''})")
    n = len(robot.joints)
    for k in (k for k in ("q", "qd", "tau") if k in kinds):
        if k in source.columns and isinstance(source.columns[k], str) and "{j}" in source.columns[k]:
            extra = source.columns[k].format(j=n + 1, name="")
            if extra in header:
                raise InputError(path, extra, f"the log has a column for joint {n + 1}; the model {robot.name!r} "
                                              f"has {n} joints ({', '.join(robot.joint_names)})")


def _read_frame(path: Path, nrows: int | None = None, content: bytes | None = None) -> pd.DataFrame:
    """The CSV at `path` (or its `content`, already read) as a table; refusals name the file."""
    import pandas as pd
    try:
        df = pd.read_csv(io.BytesIO(content) if content is not None else path, low_memory=False, nrows=nrows)
    except (OSError, UnicodeDecodeError, ValueError, pd.errors.ParserError) as exc:
        raise InputError(path, "", f"not a CSV log ({str(exc).splitlines()[0]})") from None
    if len(df.columns) < 2:
        raise InputError(path, "", f"not a CSV log (one column, {str(df.columns[0])[:40]!r})")
    # the header's names as written, blanks around them dropped ("t, q1, q2" is read as "t,q1,q2"); pandas
    # would rename a repeated name ("q1", "q1.1") and the log would be read from one of them unsaid
    text = content if content is not None else _first_line(path)
    end = text.find(b"\n")
    line = text if end < 0 else text[:end]  # not split: `content` may be the whole file
    header = [name.strip() for name in next(csv.reader([line.decode("utf-8-sig", errors="replace")]), [])]
    if len(header) == len(df.columns):
        repeated = [name for k, name in enumerate(header) if name in header[:k]]
        if repeated:
            raise InputError(path, repeated[0], "column named twice in the header")
        df.columns = header
    return df


def check_columns(source: DataSource, robot: RobotSpec, t: Table) -> None:
    """At load, before any work: the log (and a validation log) has the columns the scenario names,
    or the bag the topic."""
    if source.topic is not None:
        from harness.sources.bag import check_bag

        for path in (source.file, source.validation_file, source.payload and source.payload.file):
            if path is not None:
                check_bag(path, source.topic)
        return
    for path in (source.file, source.torque_file, source.validation_file, source.payload and source.payload.file):
        if path is not None:
            _check_header(path, list(_read_frame(path, nrows=0, content=_first_line(path)).columns), source, robot)


HEADER_BYTES = 1 << 20  # a log's header line: thousands of columns fit


def _first_line(path: Path) -> bytes:
    """A log's header line, read no further than HEADER_BYTES."""
    try:
        with open(path, "rb") as f:
            line = f.readline(HEADER_BYTES + 1)
    except OSError as exc:
        raise InputError(path, "", f"cannot read ({exc.strerror or exc})") from None
    if len(line) > HEADER_BYTES:
        raise InputError(path, "", f"no header line within its first {HEADER_BYTES >> 20} MiB: not a CSV log")
    return line


def read_raw(source: DataSource, robot: RobotSpec, file: Path | None = None) -> TimeSeries:
    """The log's columns for the robot's joints, in SI units and at the joints (a motor-side log mapped
    through the model's drives: `at_joints`), its `window` kept; every refusal names the file and the
    column. `file`: another log of the scenario's layout (a validation or payload log)."""
    path = file or source.file
    if source.topic is not None:
        from harness.sources.bag import digest, read_bag

        t, q, qd, tau = read_bag(path, source.topic, source.log_names(robot.joint_names))
        q, qd, tau = to_si(source, robot, q, qd, tau)
        series = raw_series(path, digest(path), t, *at_joints(source, robot, q, qd, tau), tuple(robot.joint_names))
        series.meta["read"] = _read_record(source, robot, [path], f"the bag's stamps (topic {source.topic})")
        return _windowed(source, series)
    names = column_names(source, robot)
    frames = [(path, *_csv(path, source, robot))]
    if source.torque_file is not None and file is None:  # the torques in a file of their own, row by row
        frames.append((source.torque_file, *_csv(source.torque_file, source, robot)))
    columns = {kind: np.column_stack([_column(p, df, c) for c in names[kind]])
               for p, df, _ in frames for kind in _kinds(source, p) if kind in names}
    if len(frames) > 1 and len(frames[0][1]) != len(frames[1][1]):
        raise InputError(source.torque_file, "", f"{len(frames[1][1])} rows, where {path.name} has "
                                                 f"{len(frames[0][1])}: the two files are read row by row")
    rows = len(frames[0][1])
    t = columns["t"][:, 0] if "t" in columns else np.arange(rows) / source.sample_rate
    digest = hashlib.sha256(b"".join(content for _, _, content in frames)).hexdigest()
    q, qd, tau = to_si(source, robot, columns["q"], columns.get("qd"), columns["tau"])
    series = raw_series(path, digest, t, *at_joints(source, robot, q, qd, tau), tuple(robot.joint_names))
    series.meta["read"] = _read_record(source, robot, [p for p, _, _ in frames],
                                       f"column {names['t'][0]!r}" if "t" in columns
                                       else f"row k at k / {source.sample_rate:g} s (sample_rate)")
    return _windowed(source, series)


def _read_record(source: DataSource, robot: RobotSpec, files: list[Path], time: str) -> dict:
    """The conditioning's first step: what was read, where its time came from, and at which side of the
    drives it was measured (a motor-side log mapped to the joints through the model's transmission)."""
    record = {"step": "read", "files": [str(f) for f in files], "time": time, "side": source.side}
    if source.side == "motor":
        record["to_joints"] = {"rule": "q = N^-1 (q_m - offset), q' = N^-1 q'_m, tau = N^T tau_m",
                               **robot.transmission.describe(robot.joint_names)}
    return record


def _csv(path: Path, source: DataSource, robot: RobotSpec):
    """A CSV of the log, read once (parsed and hashed): its table, checked against the columns the
    scenario names in it, and its bytes."""
    content = read_bounded(path, MAX_DATA_BYTES)
    df = _read_frame(path, content=content)
    if df.empty:
        raise InputError(path, "", "the log has no rows")
    _check_header(path, list(df.columns), source, robot)
    return df, content


def _column(path: Path, df, name: str) -> np.ndarray:
    import pandas as pd

    x = pd.to_numeric(df[name], errors="coerce").to_numpy(dtype=float)
    bad = np.flatnonzero(~np.isfinite(x))
    if len(bad):
        raise InputError(path, name, f"row {bad[0] + 2} is {_cell(df[name].iloc[bad[0]])}, not a finite number "
                                     f"({len(bad)} such row{'s' if len(bad) > 1 else ''})")
    return x


def at_joints(source: DataSource, robot: RobotSpec, q: np.ndarray, qd: np.ndarray | None,
              tau: np.ndarray) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
    """A motor-side log's motor positions, velocities and torques (`side = "motor"`) at the joints,
    through the model's transmission (harness/model/drives.py): q = N^-1 (q_m - offset),
    q' = N^-1 q'_m, tau = N^T tau_m. A joint-side log as it is."""
    if source.side != "motor":
        return q, qd, tau
    t = robot.transmission
    return t.joint_positions(q), None if qd is None else t.joint_rates(qd), t.joint_torques(tau)


def _windowed(source: DataSource, series: TimeSeries) -> TimeSeries:
    """The rows inside the scenario's `window` ([t0, t1] s), said in `meta`."""
    if source.window is None:
        return series
    t0, t1 = source.window
    keep = (series.t >= t0) & (series.t <= t1)
    if keep.sum() < 10:
        raise InputError(series.meta["file"], "window", f"[{t0:g}, {t1:g}] s keeps {int(keep.sum())} rows of a log "
                                                       f"from {series.t[0]:g} to {series.t[-1]:g} s")
    kept = series.span(keep)
    kept.meta["read"] = {**series.meta["read"], "window": {"t_start": t0, "t_end": t1, "rows": int(keep.sum()),
                                                           "rows_before": len(series.t)}}
    return kept


def _cell(value) -> str:
    """A cell of the log as its reader saw it: text quoted, a missing value (empty, or a marker such as
    NA or nan, which the CSV reader turns into NaN) said so, a number as Python writes it."""
    if isinstance(value, str):
        return repr(value)
    try:
        x = float(value)
    except (TypeError, ValueError):
        return repr(value)
    return "empty (or a missing-value marker: NA, nan, null)" if np.isnan(x) else repr(x)
