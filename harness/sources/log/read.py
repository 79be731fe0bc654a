"""A log's file read as it is: a CSV's header and columns (or a ROS bag's JointState messages,
harness/sources/bag.py) for the model's joints, every refusal naming the file and the column; the
values made SI (harness/sources/log/units.py). What it gives is a RawLog (harness/sources/log/raw.py):
q, q' where the log has them, tau, no accelerations, the file, its sha256 and the read step's record."""

from __future__ import annotations

import csv
import dataclasses
import hashlib
import io
import os
import re
import stat
import warnings
from pathlib import Path

import numpy as np

from harness.base.series import SeriesError
from harness.base.tomlio import MAX_DATA_BYTES, InputError, Table, too_large
from harness.model.spec import RobotSpec
from harness.sources.log.channels import every_joint
from harness.sources.log.raw import RawLog
from harness.sources.log.schema import SECONDS, SI, DataSource, column_names
from harness.sources.log.units import plausible, refuse_absurd, to_si


def raw_log(path: Path, sha256: str, t: np.ndarray, q: np.ndarray, qd: np.ndarray | None, tau: np.ndarray,
            joints: tuple[str, ...], read: dict, columns: dict[str, list[str]], extra: dict | None = None) -> RawLog:
    """A log as read: no accelerations (they come from its conditioning). What the reading let through
    and a RawLog's invariants refuse (a time that is not finite) is refused naming the file and the column."""
    try:
        return RawLog(t, joints, q, qd, tau, Path(path), sha256, read, extra or {})
    except SeriesError as exc:
        names = columns.get(exc.field, [exc.field])
        raise InputError(path, names[0] if names else exc.field, f"{exc.what}: not a log") from None


TORQUE_FILE_COLUMNS = ("tau",)  # what a separate torque file (`torque_file`) holds; `file` holds the rest


def _kinds(source: DataSource, path: Path) -> tuple[str, ...]:
    """The quantities the CSV at `path` holds: all, or with a torque file its part (a floating base's and
    its contacts' channels in `file`, with the positions)."""
    if source.torque_file is not None and path == source.torque_file:
        return TORQUE_FILE_COLUMNS
    base = tuple(source.floating.columns()) if source.floating is not None else ()
    return ("t", "q", "qd", *(("tau",) if source.torque_file is None else ()), *base)


def _check_header(path: Path, header: list[str], source: DataSource, robot: RobotSpec,
                  kinds: tuple[str, ...] | None = None) -> None:
    """The header has the columns of the quantities `kinds` (those the file holds: `_kinds`) and no
    column of a joint beyond the model's."""
    kinds = _kinds(source, path) if kinds is None else kinds
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


def _header(path: Path, line: bytes) -> list[str]:
    """A CSV's header line as its column names, blanks around them dropped ("t, q1, q2" is read as
    "t,q1,q2"); a name written twice is refused (the log would be read from one of them unsaid)."""
    import pandas as pd

    try:  # what pandas makes of it: a line that is not text, or not a CSV line, is refused here
        parsed = pd.read_csv(io.BytesIO(line), nrows=0).columns
    except (UnicodeDecodeError, ValueError) as exc:
        raise InputError(path, "", f"not a CSV log ({str(exc).splitlines()[0]})") from None
    if not len(parsed) or (len(parsed) == 1 and any(c in str(parsed[0]) for c in " \t;|")):
        # one column whose name holds a separator: a file separated by something other than commas; one
        # plain name is a column (a torque file of the one channel a log measures)
        raise InputError(path, "", f"not a CSV log (one column, {str(parsed[0])[:40] if len(parsed) else ''!r}: "
                                   "its columns are not separated by commas)")
    header = [name.strip() for name in next(csv.reader([line.decode("utf-8-sig", errors="replace")]), [])]
    repeated = [name for k, name in enumerate(header) if name in header[:k]]
    if repeated:
        raise InputError(path, repeated[0], "column named twice in the header")
    return header


def check_columns(source: DataSource, robot: RobotSpec, t: Table) -> None:
    """At load, before any work: the log (and a validation log) has the columns the scenario names,
    or the bag the topic."""
    if source.topic is not None:
        from harness.sources.bag import ODOMETRY, WRENCH, check_bag

        fl = source.floating  # a floating base's topics: its odometry and its contacts' wrenches
        others = () if fl is None else ((fl.topic, ODOMETRY, "data.base.topic"), *(
            (c.topic, WRENCH, f"data.contacts[{k}].topic") for k, c in enumerate(fl.contacts)))
        for path in (source.file, source.validation_file, source.payload and source.payload.file):
            if path is not None:
                check_bag(path, source.topic, others)
        return
    if source.joined:
        _holders(source, robot, {p: _header(p, _first_line(p)) for p in source.files})
        return
    from harness.sources.log.indexed import resolved

    for path in (source.file, source.torque_file, source.validation_file, source.payload and source.payload.file):
        if path is not None:  # a log whose messages name their joints: the columns of its own order
            _check_header(path, _header(path, _first_line(path)), resolved(source, robot, path), robot)


def _holders(source: DataSource, robot: RobotSpec, headers: dict[Path, list[str]]) -> dict[str, Path]:
    """A log in several files: which file holds each quantity (q, q' where named, tau), every one in one
    file and every file holding one, each with the time column; the headers checked as one file's."""
    names = column_names(source, robot)
    holder = {}
    for kind, columns in names.items():
        if kind == "t":
            continue
        for name in columns:
            having = [p for p in source.files if name in headers[p]]
            if len(having) > 1:
                raise InputError(having[1], name, f"column in {having[0].name} too: which file's to read?")
        having = [p for p in source.files if columns[0] in headers[p]]
        if not having:
            raise InputError(source.file, columns[0], f"column missing in every file of the log "
                                                      f"({', '.join(p.name for p in source.files)})")
        holder[kind] = having[0]
    for path in source.files:
        kinds = tuple(k for k, p in holder.items() if p == path)
        if not kinds:
            held = ", ".join(names[k][0] for k in holder)
            raise InputError(path, "", f"holds none of the log's columns ({held}, ...)")
        _check_header(path, headers[path], source, robot, ("t", *kinds))
    return holder


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


def read_raw(source: DataSource, robot: RobotSpec, file: Path | None = None) -> RawLog:
    """The log's columns for the robot's joints, in SI units and at the joints (a motor-side log mapped
    through the model's drives: `at_joints`), its `window` kept; every refusal names the file and the
    column. `file`: another log of the scenario's layout (a validation or payload log)."""
    path = file or source.file
    if source.topic is not None:
        from harness.sources.bag import digest, read_bag

        t, q, qd, tau = read_bag(path, source.topic, source.log_names(robot.joint_names))
        tau = np.where([j in source.unmeasured for j in robot.joint_names], 0.0, tau)  # what it says, not read
        joined, notes, channels = None, [], {}
        if source.floating is not None:  # the base's and the contacts' topics, joined to the joint states
            from harness.sources.log.floating import bag_channels

            keep, channels, joined, notes = bag_channels(source.floating, path, t)
            t, q, tau, qd = t[keep], q[keep], tau[keep], None if qd is None else qd[keep]
        q, qd, tau = to_si(source, robot, q, qd, tau)
        kinds, names = ("q", "qd", "tau"), [f"{source.topic}: {j}" for j in source.log_names(robot.joint_names)]
        _refuse_absurd(source, robot, {"q": q, "qd": qd, "tau": tau}, dict.fromkeys(kinds, path),
                       dict.fromkeys(kinds, names), lambda i: f"message {i + 1}")
        record = _read_record(source, robot, [path], f"the bag's stamps (topic {source.topic})", notes)
        extra = {}
        if joined is not None:
            from harness.sources.log.floating import in_convention

            record["joined_on_time"] = joined
            extra = in_convention(source.floating, channels, path, lambda i: f"joint state {i + 1} joined", robot, q)
        series = raw_log(path, digest(path), t, *at_joints(source, robot, q, qd, tau), tuple(robot.joint_names),
                         record, {"t": [f"{source.topic}: header.stamp"], **dict.fromkeys(kinds, names),
                                  **({} if source.floating is None else source.floating.columns())}, extra)
        return _windowed(source, series)
    from harness.sources.log.indexed import resolved

    source = resolved(source, robot, path)  # a log whose messages name their joints: its own order's columns
    names = column_names(source, robot)
    if source.joined and file is None:
        files, digest, columns, where, notes, joined = _joined_files(source, robot, names)
    else:
        files, digest, columns, where, notes = _row_by_row(source, robot, names, path, file)
        joined = None
    if not len(columns["q"]):
        raise InputError(path, "", "the log has no rows")
    t = (columns["t"][:, 0] * SECONDS[source.units["t"]] if "t" in columns
         else np.arange(len(columns["q"])) / source.sample_rate)
    tau, tau_names = every_joint(source, robot, columns.pop("tau"), names["tau"])
    q, qd, tau = to_si(source, robot, columns.pop("q"), columns.pop("qd", None), tau)
    _refuse_absurd(source, robot, {"q": q, "qd": qd, "tau": tau}, where, {**names, "tau": tau_names},
                   lambda i: f"row {i + 2}")
    time = (f"column {names['t'][0]!r}" + (f" in {source.units['t']}" if source.units["t"] != "s" else "")
            if "t" in columns else f"row k at k / {source.sample_rate:g} s (sample_rate)")
    if joined is not None:
        time += f" of each file, the rows joined on it to those of {Path(joined['reference']).name}"
    record = _read_record(source, robot, files, time, notes)
    if joined is not None:
        record["joined_on_time"] = joined
    extra = {}
    if source.floating is not None:  # the base's and the contacts' channels, in the harness's convention
        from harness.sources.log.floating import in_convention

        extra = in_convention(source.floating, {k: columns.pop(k) for k in source.floating.columns()}, path,
                              lambda i: f"row {i + 2}", robot, q)
    series = raw_log(path, digest.hexdigest(), t, *at_joints(source, robot, q, qd, tau), tuple(robot.joint_names),
                     record, names, extra)
    return _windowed(source, series)


def _row_by_row(source: DataSource, robot: RobotSpec, names: dict[str, list[str]], path: Path, file: Path | None):
    """A log in one file, or with its torques in a file of their own read row by row with it: the files
    read, the digest of their bytes one after the other, the columns {kind: (rows, n)}, each kind's file,
    and what the reading must say (a last line cut short, dropped)."""
    files = [path] + ([source.torque_file] if source.torque_file is not None and file is None else [])
    digest = hashlib.sha256()  # of the files' bytes one after the other, as they are parsed
    columns, rows, cut, where = {}, [], [], {}
    for p in files:  # with a torque file, the torques in a file of their own, row by row
        kinds = {kind: names[kind] for kind in _kinds(source, p) if kind in names}
        read, count, short = _csv(p, kinds, source, robot, digest)
        columns.update(read)
        rows.append(count)
        cut += [p] if short else []
        where.update(dict.fromkeys(kinds, p))
    if len(rows) > 1 and rows[0] != rows[1]:
        raise InputError(source.torque_file, "", f"{rows[1]} rows, where {path.name} has {rows[0]}: the two files "
                                                 "are read row by row")
    notes = []
    if cut:  # the row a logger stopped writing mid-line: its numbers may be cut short
        columns = {kind: x[:-1] for kind, x in columns.items()}
        notes.append(f"{', '.join(p.name for p in cut)}: the last line has no line end (the file cut short while "
                     f"written?): row {rows[0] + 1} dropped" + (" from both files" if len(files) > 1 else ""))
    return files, digest, columns, where, notes


def _joined_files(source: DataSource, robot: RobotSpec, names: dict[str, list[str]]):
    """A log in several files, each with its own time column: each file's columns read (`_holders`
    says which file holds which quantity), a cut last line dropped from its file, and the rows joined on
    time to those of the file holding the positions (harness/sources/log/join.py). As `_row_by_row`,
    and the join's record."""
    from harness.sources.log.join import join_on_time

    holder = _holders(source, robot, {p: _header(p, _first_line(p)) for p in source.files})
    digest = hashlib.sha256()
    read, notes = {}, []
    for p in source.files:
        kinds = {"t": names["t"], **{k: names[k] for k, h in holder.items() if h == p}}
        columns, count, short = _csv(p, kinds, source, robot, digest, tuple(kinds))
        if short:
            columns = {k: x[:-1] for k, x in columns.items()}
            notes.append(f"{p.name}: the last line has no line end (the file cut short while written?): row "
                         f"{count + 1} dropped")
        read[p] = columns
    reference = holder["q"]
    scale = SECONDS[source.units["t"]]
    join = join_on_time(reference, read[reference]["t"][:, 0] * scale,
                        {p: read[p]["t"][:, 0] * scale for p in source.files if p != reference}, names["t"][0])
    columns = {"t": read[reference]["t"][join.keep]}
    for kind, p in holder.items():
        columns[kind] = read[p][kind][join.keep] if p == reference else read[p][kind][join.rows[p]]
    return list(source.files), digest, columns, dict(holder), notes + join.warnings, join.record


def _refuse_absurd(source: DataSource, robot: RobotSpec, values: dict[str, np.ndarray | None], files: dict[str, Path],
                   names: dict[str, list[str]], row_of) -> None:
    """Each quantity read (SI, at the log's side) refused where a value is beyond anything the model's
    size allows (harness/sources/log/units.py, `refuse_absurd`)."""
    bounds = plausible(robot, source)
    revolute = np.array([j.revolute for j in robot.joints])
    for kind, x in values.items():
        if x is not None:
            refuse_absurd(kind, x, bounds[kind], files[kind], names[kind], row_of, revolute,
                          source.units[kind] != SI[kind])


def _read_record(source: DataSource, robot: RobotSpec, files: list[Path], time: str,
                 warnings: list[str] | None = None) -> dict:
    """The conditioning's first step: what was read, where its time came from, and at which side of the
    drives it was measured (a motor-side log mapped to the joints through the model's transmission);
    `warnings`, what reading it did that the terminal must say (a cut last line dropped)."""
    record = {"step": "read", "files": [str(f) for f in files], "time": time, "side": source.side,
              "warnings": list(warnings or [])}
    if source.side == "motor":
        record["to_joints"] = {"rule": "q = N^-1 (q_m - offset), q' = N^-1 q'_m, tau = N^T tau_m",
                               **robot.transmission.describe(robot.joint_names)}
    return record


CHUNK_ROWS = 1 << 14  # a CSV log's rows parsed at a time
STREAM_BUFFER = 1 << 20  # bytes of its file read at a time


class _Digested(io.RawIOBase):
    """A file's bytes as they are read, hashed into `digest` and counted: refused beyond `limit`."""

    def __init__(self, f, path: Path, digest, limit: int):
        self.f, self.path, self.digest, self.limit, self.size, self.last = f, path, digest, limit, 0, b""

    def readable(self) -> bool:
        return True

    def readinto(self, buffer) -> int:
        count = self.f.readinto(buffer)
        if count:
            self.size += count
            if self.size > self.limit:
                raise too_large(self.path, self.limit)
            self.digest.update(memoryview(buffer)[:count])
            self.last = bytes(memoryview(buffer)[count - 1:count])
        return count


def _csv(path: Path, wanted: dict[str, list[str]], source: DataSource, robot: RobotSpec,
         digest, kinds: tuple[str, ...] | None = None) -> tuple[dict[str, np.ndarray], int, bool]:
    """The columns `wanted` ({kind: names}) of the CSV at `path`, {kind: (rows, len(names))}, its row
    count, and whether its last line was cut short (the file ends without a line end: a logger stopped
    mid-line; that row is the caller's to drop): its header checked against the scenario's columns,
    its rows parsed CHUNK_ROWS at a time and only those columns kept (a long log's text and its other
    columns are never held whole), every byte hashed into `digest` as it is read. A cell that is not a
    finite number is refused naming its column, its first row and how many rows have one (a cut last
    line's cells aside)."""
    import pandas as pd

    bad: dict[int, list] = {}  # position -> [its first bad row, that cell, how many, its last bad row]
    try:
        with open(path, "rb") as f:  # read once, from its header to its end
            info = os.fstat(f.fileno())  # a regular file refused at its size; a stream as it is read
            if stat.S_ISREG(info.st_mode) and info.st_size > MAX_DATA_BYTES:
                raise too_large(path, MAX_DATA_BYTES)
            raw = _Digested(f, path, digest, MAX_DATA_BYTES)
            stream = io.BufferedReader(raw, STREAM_BUFFER)
            line = stream.readline(HEADER_BYTES + 1)
            if len(line) > HEADER_BYTES:
                raise InputError(path, "", f"no header line within its first {HEADER_BYTES >> 20} MiB: not a CSV log")
            header = _header(path, line)
            _check_header(path, header, source, robot, kinds)
            at = {name: header.index(name) for names in wanted.values() for name in names}
            positions = sorted(set(at.values()))
            pieces: dict[int, list[np.ndarray]] = {k: [] for k in positions}
            # as many fields as the header's: a short row's last are empty (refused below, naming its row),
            # a longer row is an error (pandas warns of the first row's and drops its last fields)
            with warnings.catch_warnings(), pd.read_csv(
                    stream, header=None, names=range(len(header)), index_col=False,
                    chunksize=CHUNK_ROWS, low_memory=False) as chunks:
                warnings.simplefilter("error", pd.errors.ParserWarning)
                for chunk in chunks:
                    for k in positions:
                        # a copy: a view would keep the chunk's block of every column alive
                        x = pd.to_numeric(chunk[k], errors="coerce").to_numpy(dtype=float, copy=True)
                        wrong = np.flatnonzero(~np.isfinite(x))
                        if len(wrong):
                            seen = bad.setdefault(k, [int(chunk.index[wrong[0]]) + 2, chunk[k].iloc[wrong[0]], 0, 0])
                            seen[2:] = seen[2] + len(wrong), int(chunk.index[wrong[-1]]) + 2
                        pieces[k].append(x)
            while stream.read(STREAM_BUFFER):  # whatever follows the last row, hashed too
                pass
    except OSError as exc:
        raise InputError(path, "", f"cannot read file ({exc.strerror or exc})") from None
    except pd.errors.ParserWarning:
        raise InputError(path, "", f"not a CSV log (its first row has more fields than its header's "
                                   f"{len(header)})") from None
    except (UnicodeDecodeError, ValueError, pd.errors.ParserError) as exc:
        # pandas counts the lines it was given, from the one after the header: the file's are one more
        said = re.sub(r"\bline (\d+)", lambda m: f"line {int(m.group(1)) + 1}", str(exc).splitlines()[0])
        raise InputError(path, "", f"not a CSV log ({said})") from None
    rows = sum(len(x) for x in pieces[positions[0]])
    cut = rows > 0 and raw.last not in (b"\n", b"\r")
    if not rows:
        raise InputError(path, "", "the log has no rows")
    for name, k in at.items():
        if k in bad:
            row, cell, count, last = bad[k]
            if cut and last == rows + 1 and count == 1:  # the cut line's alone: dropped with it
                continue
            raise InputError(path, name, f"row {row} is {_cell(cell)}, not a finite number "
                                         f"({count} such row{'s' if count > 1 else ''})")
    out, kinds = {}, list(wanted.items())
    for i, (kind, names) in enumerate(kinds):  # each column's pieces let go of once the last kind needing them has them
        out[kind] = np.empty((rows, len(names)))
        for c, name in enumerate(names):
            out[kind][:, c] = np.concatenate(pieces[at[name]])
        later = {at[name] for _, rest in kinds[i + 1:] for name in rest}
        for k in {at[name] for name in names} - later:
            pieces[k] = []
    return out, rows, cut


def at_joints(source: DataSource, robot: RobotSpec, q: np.ndarray, qd: np.ndarray | None,
              tau: np.ndarray) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
    """A motor-side log's motor positions, velocities and torques (`side = "motor"`) at the joints,
    through the model's transmission (harness/model/drives.py): q = N^-1 (q_m - offset),
    q' = N^-1 q'_m, tau = N^T tau_m; a joint that an unmeasured motor turns has no torque read (zero:
    schema.with_unmeasured_motors). A joint-side log as it is."""
    if source.side != "motor":
        return q, qd, tau
    t = robot.transmission
    tau = t.joint_torques(tau)
    tau[:, [robot.joint_names.index(j) for j in source.unmeasured]] = 0.0
    return t.joint_positions(q), None if qd is None else t.joint_rates(qd), tau


def _windowed(source: DataSource, series: RawLog) -> RawLog:
    """The rows inside the scenario's `window` ([t0, t1] s), said in the read step's record."""
    if source.window is None:
        return series
    t0, t1 = source.window
    keep = (series.t >= t0) & (series.t <= t1)
    if keep.sum() < 10:
        raise InputError(series.file, "window", f"[{t0:g}, {t1:g}] s keeps {int(keep.sum())} rows of a log "
                                                f"from {series.t[0]:g} to {series.t[-1]:g} s")
    return dataclasses.replace(series.span(keep), read={**series.read, "window": {
        "t_start": t0, "t_end": t1, "rows": int(keep.sum()), "rows_before": len(series.t)}})


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
