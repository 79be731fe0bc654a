"""A measured joint log as the source of a run, beside the MuJoCo bench.

A scenario's `[data]` table names a CSV file and its columns, `{j}` standing for 1..n in the
model's joint order and `{name}` for a joint's name, or a list of column names in joint order:

    [data]
    file = "log.csv"                      # relative to the scenario file
    columns = { t = "t", q = "q{j}", qd = "qd{j}", tau = "tau{j}" }   # qd may be left out
    units = { q = "rad", qd = "rad/s", tau = "N m" }   # or "deg", "deg/s", "current" (default SI, said so)
    torque_constant = [0.11, ...]         # N m/A per joint (motor side), with tau = "current"
    gear_ratio = [100, ...]               # per joint, with tau = "current"
    cutoff = 10.0                         # Hz, zero-phase low-pass (default: none)
    filter_order = 4                      # Butterworth order (applied forward and backward)
    rate = 1000.0                         # Hz, the uniform grid (default: 1 / the median step)
    decimate = 10                         # keep every 10th sample of the filtered grid (default 1)
    trim = 0.3                            # s dropped at each end of every stretch (default 3 / cutoff)
    gap = 5.0                             # a step over 5 median steps splits the log (default: `split_step`)
    limits_check = true                   # refuse positions far beyond the joint limits (a unit mistake?)
    truth = "bench_robot.toml"            # the model that made the log, where known: errors against it too
    delay = "estimate"                    # the torque channels' lag behind the encoders: or "correct", "none"
    identify_torque_constants = true      # currents: each joint's constant identified (default: with a payload log)
    repeat = 4                            # the fit repeated on 4 disjoint segments of the training span
    payload = { file = "loaded.csv", body = "wrist_3_link", mass = 2.0, com = [...], inertia = [...] }
    validation = { from = 0.7 }           # the last 30 % by time is kept for validation

Instead of `file` and `columns`, `bag` (a rosbag2 folder or a ROS 1 .bag file) and `topic` (its
sensor_msgs/JointState topic) read a ROS bag, matching joints by name (harness/sources/bag.py); a
validation `file` is then a bag too.

Units are converted on reading (`to_si`): degrees of revolute joints to radians; motor currents to
joint torques, tau = i k_t N. A revolute joint whose positions reach UNIT_FACTOR times its limit is
refused, with the unit that would fit suggested; so are velocities that are not the positions' rate
of change (`_check_velocities`: t in milliseconds, q' in deg/s read as rad/s, a column of the other
sign), and a grid over MAX_UPSAMPLING times finer than the log.

Conditioning, in this order, each step stated in results.json (`data.conditioning`), each warning
also printed once on the terminal:
1. checks, on the whole file: every cell a finite number (else the file, the column and the row are
   named); time strictly increasing once repeated rows are dropped; the velocities against the
   positions' rate of change; rows that repeat the previous row's positions exactly (a logger's
   sample and hold) dropped and counted; steps over twice the median and the clock's jitter
   counted; positions beyond the model's joint limits counted;
2. the log cut at every gap (a step over `split_step`) and, when split by time, at the split: each
   stretch alone goes through steps 3-6, and one too short for them is dropped, said so;
3. resampling of q, q', tau to a uniform grid (the whole file's rate) by linear interpolation;
4. a zero-phase Butterworth low-pass (scipy.signal.sosfiltfilt) of q, q', tau;
5. velocities (where the log has none) and accelerations by central differences of the filtered
   signals (numpy.gradient, second order);
6. `trim` seconds dropped at both ends of the stretch (filter and difference transients: the guard
   band at every gap and at the split), then decimation.
Nothing of the validation span reaches the training span; the two are checked disjoint. The file's
sha256 is recorded.
"""

from __future__ import annotations

import csv
import hashlib
import io
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from harness.base.numerics import sampled
from harness.base.tomlio import MAX_DATA_BYTES, InputError, Table, read_bounded
from harness.model.spec import RobotSpec

if TYPE_CHECKING:  # pandas and scipy.signal are imported where a log is read: a bench run needs neither
    import pandas as pd

LOG_FILE = "data.csv"  # the conditioned log, written beside results.json
GAP_FACTOR = 2.0  # a step more than twice the median is a gap
TRIM_PERIODS = 3.0  # default trim: three periods of the cut-off frequency
MAX_FILTER_ORDER = 20


UNITS = {"q": ("rad", "deg"), "qd": ("rad/s", "deg/s"), "tau": ("N m", "current")}
SI = {"q": "rad", "qd": "rad/s", "tau": "N m"}
GAP_SPLIT = 5.0  # default: a step over five median steps splits the log into segments
DELAY_CHOICES = ("estimate", "correct", "none")
MAX_REPEAT = 100
UNIT_FACTOR = 3.0  # positions beyond the joint limits by this factor or more look like a unit mistake
VELOCITY_FACTOR = 3.0  # the positions' rate of change and the logged velocities this far apart: a unit mistake
TRACKING = 0.5  # a joint whose logged velocity follows its positions' changes this closely (cosine) moves
TIME_UNITS = ((1e-3, "milliseconds"), (1e-6, "microseconds"), (1e-9, "nanoseconds"))
MAX_UPSAMPLING = 100.0  # a grid this many times finer than the log's own median step is not resampling


@dataclass(frozen=True)
class KnownPayload:
    """`[data.payload]`: a log of the same robot, the same motion or another, carrying a known load on
    `body`: its mass (kg), centre of mass and inertia about it (world frame at q = 0, as a model file's
    `[payload]`: Ixx, Iyy, Izz, Ixy, Ixz, Iyz). What it adds to the torques is known, so it fixes the
    scale the currents' torque constants leave open."""

    file: Path
    body: str
    mass: float
    com_W: np.ndarray
    inertia: np.ndarray


@dataclass(frozen=True)
class DataSource:
    file: Path
    columns: dict[str, str | tuple[str, ...]]  # "t", "q", "qd" (optional), "tau" -> a template with {j} or
    # {name}, or (q, qd, tau) an explicit list of column names in the model's joint order
    cutoff: float | None
    filter_order: int
    rate: float | None
    decimate: int
    trim: float | None
    validation_from: float | None  # fraction of the duration where the validation span starts
    validation_file: Path | None
    units: dict[str, str] = field(default_factory=lambda: dict(SI))  # of revolute joints; prismatic: m, m/s
    units_given: bool = False  # False: SI taken, and said so
    torque_constant: tuple[float, ...] | None = None  # N m/A per joint (motor side), with units.tau = "current"
    gear_ratio: tuple[float, ...] | None = None  # per joint, with units.tau = "current"
    gap: float | None = None  # a step over this many median steps splits the log (default: `split_step`)
    limits_check: bool = True  # positions far beyond the joint limits (a unit mistake?) are refused
    truth: Path | None = None  # the model that made the log, where it is known (a bench log): errors against it
    topic: str | None = None  # a ROS bag's JointState topic: `file` is then the bag (harness/sources/bag.py)
    delay: str = "estimate"  # the torque channels' delay behind the encoders: "estimate", "correct" or "none"
    payload: KnownPayload | None = None  # a second log with a known load: the torque constants identified
    identify_constants: bool = False  # currents: each joint's torque constant identified (up to one scale alone)
    repeat: int | None = None  # the fit repeated on this many disjoint segments of the training span

    def describe(self) -> dict:
        return {"file": str(self.file),
                "columns": {k: list(v) if isinstance(v, tuple) else v for k, v in self.columns.items()},
                "units": dict(self.units), "units_given": self.units_given,
                "torque_constant": list(self.torque_constant) if self.torque_constant else None,
                "gear_ratio": list(self.gear_ratio) if self.gear_ratio else None,
                "cutoff_hz": self.cutoff, "filter_order": self.filter_order, "rate_hz": self.rate,
                "decimate": self.decimate, "trim_s": self.trim, "gap_median_steps": self.gap,
                "validation_from": self.validation_from,
                "validation_file": str(self.validation_file) if self.validation_file else None,
                "truth": str(self.truth) if self.truth else None, "bag_topic": self.topic, "delay": self.delay,
                "identify_torque_constants": self.identify_constants, "repeat_segments": self.repeat,
                "payload_log": None if self.payload is None else {
                    "file": str(self.payload.file), "body": self.payload.body, "mass": self.payload.mass,
                    "com": [float(x) for x in self.payload.com_W], "inertia": [float(x) for x in self.payload.inertia]}}


@dataclass(frozen=True, eq=False)
class JointLog:
    """Joint positions, velocities, accelerations and torques on a uniform grid, (N, n) each."""

    t: np.ndarray
    joints: tuple[str, ...]
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    tau: np.ndarray
    conditioning: dict = field(default_factory=dict)

    def joint_index(self, name: str) -> int:
        return self.joints.index(name)

    def span(self, rows: np.ndarray | slice) -> JointLog:
        return JointLog(self.t[rows], self.joints, self.q[rows], self.qd[rows], self.qdd[rows], self.tau[rows],
                        self.conditioning)

    def to_frame(self) -> pd.DataFrame:
        import pandas as pd
        cols: dict[str, np.ndarray] = {"t": self.t}
        for j, name in enumerate(self.joints):
            for k in ("q", "qd", "qdd", "tau"):
                cols[f"{k}_{name}"] = getattr(self, k)[:, j]
        return pd.DataFrame(cols)

    def write_csv(self, path: Path) -> None:
        self.to_frame().to_csv(path, index=False, float_format="%.17g")


def read_log_csv(path: Path | str) -> JointLog:
    """A conditioned log written by write_csv, read back (for `harness report`)."""
    import pandas as pd
    try:
        df = pd.read_csv(io.BytesIO(read_bounded(path, MAX_DATA_BYTES)))
    except (ValueError, pd.errors.ParserError) as exc:
        raise InputError(path, "", f"cannot read the conditioned log ({str(exc).splitlines()[0]})") from None
    joints = tuple(c[2:] for c in df.columns if c.startswith("q_"))
    need = ["t", *(f"{k}_{j}" for j in joints for k in ("q", "qd", "qdd", "tau"))]
    bad = [c for c in need if c not in df.columns or not pd.api.types.is_numeric_dtype(df[c]) or df[c].isna().any()]
    if bad:
        raise InputError(path, bad[0], "missing, empty or not a number in some row")

    def per_joint(k: str) -> np.ndarray:
        return df[[f"{k}_{j}" for j in joints]].to_numpy()

    return JointLog(df["t"].to_numpy(), joints, per_joint("q"), per_joint("qd"), per_joint("qdd"), per_joint("tau"))


def read_source(t: Table, scenario_file: Path, joints: int | None = None) -> DataSource:
    """The `[data]` table, validated (the file must exist and be inside reach of the scenario);
    `joints`, the model's number of joints, checks explicit column lists and per-joint constants."""
    topic = None
    if t.either("file", "bag", "file (a CSV log) or bag (a ROS bag: a rosbag2 folder or a ROS 1 .bag file)") == "bag":
        file = (scenario_file.parent / t.string("bag")).resolve()
        if not file.exists():
            raise t.error("bag", f"no bag {t.data['bag']!r} (looked for {file})")
        topic = t.string("topic")
        if t.has("columns"):
            raise t.error("columns", "a bag's JointState messages name their joints: no columns to give")
        columns: dict[str, str | tuple[str, ...]] = {}
        ct = None
    else:
        file = _file(t, "file", scenario_file)
        ct = t.table("columns")
        columns = {"t": ct.string("t")}
    for k in ("q", "qd", "tau"):
        if ct is None or (k == "qd" and not ct.has("qd")):
            continue
        if isinstance(ct.data.get(k), list):
            names = ct.strings(k, choices=None)
            if joints is not None and len(names) != joints:
                raise ct.error(k, f"{len(names)} columns for a model of {joints} joints (one per joint, in the "
                                  "model's joint order)")
            columns[k] = names
            continue
        v = ct.string(k)
        if "{j}" not in v and "{name}" not in v:
            raise ct.error(k, f"a per-joint column needs {{j}} (1..n in the model's joint order) or {{name}} (the "
                              f"joint's name), or a list of the columns in joint order, got {v!r}")
        try:
            v.format(j=1, name="joint")
        except (KeyError, IndexError, ValueError):
            raise ct.error(k, f"{v!r}: only {{j}} and {{name}} may stand in braces") from None
        columns[k] = v
    if ct is not None:
        ct.finish()
    units, units_given = dict(SI), t.has("units")
    if units_given:
        ut = t.table("units")
        for k, choices in UNITS.items():
            if ut.has(k):
                units[k] = ut.string(k, choices=choices)
        ut.finish()
    constant = ratio = None
    if units["tau"] == "current":
        constant, ratio = (_per_joint(t, key, joints) for key in ("torque_constant", "gear_ratio"))
    elif t.has("torque_constant") or t.has("gear_ratio"):
        raise t.error("torque_constant" if t.has("torque_constant") else "gear_ratio",
                      'only for a log of motor currents (units = { tau = "current" })')
    gap = t.number("gap", positive=True) if t.has("gap") else None
    if gap is not None and gap <= GAP_FACTOR:
        raise t.error("gap", f"{gap:g} median steps: more than {GAP_FACTOR:g} (a clock's jitter is not a gap)")
    limits_check = t.boolean("limits_check", default=True)
    truth = _file(t, "truth", scenario_file) if t.has("truth") else None
    delay = t.string("delay", default="estimate", choices=DELAY_CHOICES)
    payload = None
    if t.has("payload"):
        pt = t.table("payload")
        payload = KnownPayload(_file(pt, "file", scenario_file, bag=topic is not None), pt.string("body"),
                               pt.number("mass", positive=True), pt.vector("com"), pt.vector("inertia", length=6))
        pt.finish()
    identify_constants = t.boolean("identify_torque_constants", default=payload is not None)
    repeat = t.integer("repeat", minimum=2) if t.has("repeat") else None
    if repeat is not None and repeat > MAX_REPEAT:
        raise t.error("repeat", f"{repeat} segments: at most {MAX_REPEAT}")
    if (payload is not None or identify_constants) and units["tau"] != "current":
        raise t.error("payload" if payload is not None else "identify_torque_constants",
                      'identifies the torque constants of a log of motor currents: give units = { tau = "current" }')
    cutoff = t.number("cutoff", positive=True) if t.has("cutoff") else None
    order = t.integer("filter_order", default=4, minimum=1)
    if order > MAX_FILTER_ORDER:
        raise t.error("filter_order", f"{order}: at most {MAX_FILTER_ORDER} (a steeper Butterworth rings longer "
                                      "after every edge of the data without a useful gain in the band)")
    rate = t.number("rate", positive=True) if t.has("rate") else None
    decimate = t.integer("decimate", default=1, minimum=1)
    trim = t.number("trim", nonnegative=True) if t.has("trim") else None
    v_from = v_file = None
    if t.has("validation"):
        vt = t.table("validation")
        if vt.either("from", "file", "from (a fraction of the log's duration) or file (another log)") == "from":
            v_from = vt.number("from")
            if not 0.0 < v_from < 1.0:
                raise vt.error("from", f"{v_from:g} is outside the log: a fraction of its duration in (0, 1)")
        else:
            v_file = _file(vt, "file", scenario_file, bag=topic is not None)
        vt.finish()
    t.finish()
    return DataSource(file, columns, cutoff, order, rate, decimate, trim, v_from, v_file, units, units_given, constant,
                      ratio, gap, limits_check, truth, topic, delay, payload, identify_constants, repeat)


def _per_joint(t: Table, key: str, joints: int | None) -> tuple[float, ...]:
    """A positive number per joint (a list in the model's joint order), or one for every joint."""
    if isinstance(t.data.get(key), list):
        values = t.vector(key, length=joints)
    else:
        values = np.full(joints or 1, t.number(key, positive=True))
    if not np.all(np.isfinite(values) & (values > 0)):
        raise t.error(key, "every value must be a positive number")
    return tuple(float(v) for v in values)


def _file(t: Table, key: str, scenario_file: Path, bag: bool = False) -> Path:
    """A file named relative to the scenario; a bag may be a folder (rosbag2)."""
    path = (scenario_file.parent / t.string(key)).resolve()
    if not (path.exists() if bag else path.is_file()):
        raise t.error(key, f"file {t.data[key]!r} not found (looked for {path})")
    return path


@dataclass(frozen=True, eq=False)
class RawLog:
    file: Path
    sha256: str
    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray | None
    tau: np.ndarray
    rows: int

    def span(self, keep: np.ndarray) -> RawLog:
        """The rows where `keep` holds."""
        return RawLog(self.file, self.sha256, self.t[keep], self.q[keep], None if self.qd is None else self.qd[keep],
                      self.tau[keep], int(keep.sum()))


def column_names(source: DataSource, robot: RobotSpec) -> dict[str, list[str]]:
    """The log's column of each quantity and joint: {j} is 1..n in the model's joint order, {name}
    the joint's name."""
    return {k: [v] if k == "t" else list(v) if isinstance(v, tuple) else
            [v.format(j=j + 1, name=name) for j, name in enumerate(robot.joint_names)]
            for k, v in source.columns.items()}


def _check_header(path: Path, header: list[str], source: DataSource, robot: RobotSpec) -> None:
    for names in column_names(source, robot).values():
        for name in names:
            if name not in header:
                raise InputError(path, name, f"column missing (the log has {', '.join(map(str, header[:12]))}"
                                             f"{' ...' if len(header) > 12 else ''})")
    n = len(robot.joints)
    for k in ("q", "qd", "tau"):
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
    for path in (source.file, source.validation_file, source.payload and source.payload.file):
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


def read_raw(source: DataSource, robot: RobotSpec, file: Path | None = None) -> RawLog:
    """The log's columns for the robot's joints; every refusal names the file and the column."""
    import pandas as pd
    path = file or source.file
    if source.topic is not None:
        from harness.sources.bag import digest, read_bag

        t, q, qd, tau = read_bag(path, source.topic, robot.joint_names)
        q, qd, tau = to_si(source, robot, q, qd, tau)
        return RawLog(Path(path), digest(path), t, q, qd, tau, len(t))
    content = read_bounded(path, MAX_DATA_BYTES)  # read once: parsed and hashed
    df = _read_frame(path, content=content)
    if df.empty:
        raise InputError(path, "", "the log has no rows")
    _check_header(path, list(df.columns), source, robot)

    def column(name: str) -> np.ndarray:
        x = pd.to_numeric(df[name], errors="coerce").to_numpy(dtype=float)
        bad = np.flatnonzero(~np.isfinite(x))
        if len(bad):
            raise InputError(path, name, f"row {bad[0] + 2} is {_cell(df[name].iloc[bad[0]])}, not a finite number "
                                         f"({len(bad)} such row{'s' if len(bad) > 1 else ''})")
        return x

    names = column_names(source, robot)
    t = column(names["t"][0])
    q, tau = (np.column_stack([column(c) for c in names[k]]) for k in ("q", "tau"))
    qd = np.column_stack([column(c) for c in names["qd"]]) if "qd" in names else None
    digest = hashlib.sha256(content).hexdigest()
    q, qd, tau = to_si(source, robot, q, qd, tau)
    return RawLog(Path(path), digest, t, q, qd, tau, len(t))


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


def to_si(source: DataSource, robot: RobotSpec, q: np.ndarray, qd: np.ndarray | None,
          tau: np.ndarray) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
    """The log's q, q', tau in SI units: degrees of revolute joints to radians; motor currents to
    joint torques, tau = i k_t N (torque constant k_t in N m/A on the motor side, gear ratio N)."""
    revolute = np.array([j.revolute for j in robot.joints])
    if source.units["q"] == "deg":
        q = np.where(revolute, np.radians(q), q)
    if qd is not None and source.units["qd"] == "deg/s":
        qd = np.where(revolute, np.radians(qd), qd)
    if source.units["tau"] == "current":
        tau = tau * np.asarray(source.torque_constant) * np.asarray(source.gear_ratio)
    return q, qd, tau


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
        _check_units(raw, robot, source)
    steps, warnings = [], []
    if source is not None and not source.units_given:
        warnings.append("no units stated ([data] units): taken as rad, rad/s and N m (m, m/s and N for a slide)")
    held = np.r_[False, np.all(raw.q[1:] == raw.q[:-1], axis=1)]
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
        raise InputError(path, "t", f"{len(tk)} distinct sample{'' if len(tk) == 1 else 's'} in {raw.rows} rows, "
                                    "at least 10 needed" + (f" ({dropped} rows repeat the time or the positions of "
                                                            "the row before them, and are dropped)" if dropped else ""))
    kept = raw.span(keep)  # the rows kept: checked here, conditioned after
    _check_velocities(kept, robot, source)
    dt = np.diff(tk)
    median = float(np.median(dt))
    if source is not None and source.rate is not None and source.rate * median > MAX_UPSAMPLING:
        raise InputError(path, "rate", f"{source.rate:g} Hz is {source.rate * median:.3g} times the log's own rate "
                                       f"(its median step {median:.3g} s): a grid over {MAX_UPSAMPLING:g} times finer "
                                       "than the samples would be made by interpolation alone. Is t in seconds?")
    gaps = dt > GAP_FACTOR * median
    jitter = float(np.std(dt) / median)
    steps.append({"step": "checks", "rows": raw.rows, "repeated_rows_dropped": int(held.sum()),
                  "equal_times_dropped": int((same_time & ~held).sum()), "median_step_s": median,
                  "min_step_s": float(dt.min()), "max_step_s": float(dt.max()), "jitter": jitter,
                  "gaps": int(gaps.sum()), "gap_definition": f"a step over {GAP_FACTOR:g} x the median"})
    if held.any():
        warnings.append(f"{int(held.sum())} rows repeat the previous row's positions exactly (sample and hold): "
                        "dropped")
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
    return Checked(kept, steps[0], warnings, median)


def _check_velocities(kept: RawLog, robot: RobotSpec, source: DataSource | None) -> None:
    """The logged velocities against the positions' rate of change, joint by joint: k, the
    least-squares slope of (q[i+1] - q[i]) / (t[i+1] - t[i]) on (q'[i] + q'[i+1]) / 2 over the kept
    rows (1.02 on every joint of the real Panda log of scenarios/panda_gaz2019.toml, 1.000 on a bench
    log), judged where the two follow each other (their cosine at least TRACKING: the joint moves). A
    k beyond VELOCITY_FACTOR either way, or negative, is a unit, time-base or sign mistake: refused,
    naming the likeliest one (t in milliseconds gives k = 1e-3 on every joint; q' in deg/s read as
    rad/s, k = 1/57.3)."""
    if kept.qd is None or len(kept.t) < 3:
        return
    d = np.diff(kept.q, axis=0) / np.diff(kept.t)[:, None]
    v = 0.5 * (kept.qd[1:] + kept.qd[:-1])
    dv, vv, dd = (d * v).sum(axis=0), (v * v).sum(axis=0), (d * d).sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        k, cosine = dv / vv, dv / np.sqrt(vv * dd)
    moves = np.isfinite(cosine) & (np.abs(cosine) >= TRACKING)
    off = moves & ~((k >= 1.0 / VELOCITY_FACTOR) & (k <= VELOCITY_FACTOR))
    if not off.any():
        return
    columns = source is not None and source.topic is None and "qd" in source.columns
    names = column_names(source, robot) if columns else {"t": ["t"], "qd": list(robot.joint_names)}
    j = int(np.flatnonzero(off)[0])

    def near(x: float, to: float) -> bool:
        return x > 0 and abs(np.log(x / to)) < np.log(1.5)

    how = "the least-squares slope of the differences of q over those of t on q'; 1 in a consistent log"
    every = off.sum() == moves.sum()
    time_base = [unit for factor, unit in TIME_UNITS if every and all(near(x, factor) for x in k[off])]
    if time_base:
        median = float(np.median(k[off]))
        raise InputError(kept.file, names["t"][0], f"on every joint that moves, q changes {median:.3g} times as fast "
                                                   f"as the logged q' says ({how}): t in {time_base[0]}? t must be in "
                                                   "seconds")
    hint = ("q' in deg/s read as rad/s? units = { qd = \"deg/s\" }" if near(k[j], np.pi / 180) else
            "q in degrees with q' in radians? give both units" if near(k[j], 180 / np.pi) else
            "q' has the opposite sign to q's changes" if near(-k[j], 1.0) else
            "q' is not the rate of change of q in the units given")
    raise InputError(kept.file, names["qd"][j], f"joint {robot.joint_names[j]!r}: q changes {k[j]:.3g} times as "
                                                f"fast as the logged q' says ({how}): {hint}; or leave qd out of "
                                                "[data] columns, and q is differentiated")


def _check_units(raw: RawLog, robot: RobotSpec, source: DataSource | None) -> None:
    """Positions UNIT_FACTOR or more beyond a revolute joint's limits are not the robot's motion: a log
    in degrees read as radians, most likely. Refused, saying which unit would fit."""
    unit = source.units["q"] if source is not None else "rad"
    for j, joint in enumerate(robot.joints):
        lo, hi = (robot.limits or {}).get(joint.name, (-np.inf, np.inf))
        reach = max(abs(lo), abs(hi))
        if not joint.revolute or not np.isfinite(reach) or reach <= 0:
            continue
        largest = float(np.max(np.abs(raw.q[:, j])))
        if largest >= UNIT_FACTOR * reach:
            hint = ('a log in degrees read as radians? give units = { q = "deg", qd = "deg/s" }' if unit == "rad"
                    else "check the unit and the column")
            raise InputError(raw.file, "units.q", f"joint {joint.name!r} reaches {largest:.4g} rad (as {unit} read), "
                                                  f"{largest / reach:.3g} times its limit {reach:.4g} rad: {hint}, or "
                                                  "limits_check = false")


def condition(raw: RawLog, source: DataSource, robot: RobotSpec) -> JointLog:
    """Steps 1-5 of the module docstring, for a log taken whole (a validation file), cut at its gaps."""
    checked = check(raw, robot, source)
    notes: list[str] = []
    pieces = segments(checked.kept, split_step(source, checked.median_step))
    log = _conditioned(checked.kept, pieces, source, robot, checked.rate(source), checked, raw.file.name, notes)
    log.conditioning["warnings"] = log.conditioning["warnings"] + notes
    return log


def smooth(kept: RawLog, source: DataSource, robot: RobotSpec, rate: float, checks: dict,
           check_warnings: list[str]) -> JointLog:
    """Steps 2-5 of the module docstring on checked rows (`check`), whose record and warnings
    open the conditioning's."""
    from scipy.signal import butter, sosfiltfilt

    path, tk, raw = kept.file, kept.t, kept
    steps, warnings = [checks], list(check_warnings)
    # 2. uniform grid
    grid = tk[0] + np.arange(int(np.floor((tk[-1] - tk[0]) * rate)) + 1) / rate

    def resample(x: np.ndarray) -> np.ndarray:
        return sampled(tk, x, grid)

    q, tau = resample(raw.q), resample(raw.tau)
    qd = resample(raw.qd) if raw.qd is not None else None
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
            return sosfiltfilt(sos, x, axis=0)

        q, tau = lowpass(q), lowpass(tau)
        qd = lowpass(qd) if qd is not None else None
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
    steps.append({"step": "differentiate", "method": "central differences (numpy.gradient, second order) of the "
                  "filtered " + ("velocities" if raw.qd is not None else "positions (velocities) and velocities"),
                  "velocities": "measured" if raw.qd is not None else "differentiated"})
    # 5. trim and decimate
    trim = source.trim if source.trim is not None else (TRIM_PERIODS / source.cutoff if source.cutoff else 2 * h)
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
    return JointLog(grid[rows], tuple(robot.joint_names), q[rows], qd[rows], qdd[rows], tau[rows], conditioning)


def split_step(source: DataSource, median: float) -> float:
    """The longest step (s) the log is bridged across by interpolation; a longer one splits it. The
    scenario's `gap` median steps; by default GAP_SPLIT median steps, and with a low-pass filter at
    least a quarter period of its cut-off (interpolation over a shorter step changes nothing in the
    band the filter keeps: a 1 kHz log filtered at 10 Hz is bridged over 25 ms)."""
    if source.gap is not None:
        return source.gap * median
    return max(GAP_SPLIT * median, 0.25 / source.cutoff if source.cutoff else 0.0)


def room(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Seconds from each row of a conditioned log back to the start of its stretch and on to its end
    (a stretch: the rows between gaps, a gap a step over 1.5 median steps): how far a computation
    that reads around a row may reach without crossing a gap or an end."""
    dt = np.diff(t)
    cuts = np.flatnonzero(dt > 1.5 * np.median(dt)) + 1
    first = t[np.r_[0, cuts]]
    stretch = np.searchsorted(first, t, side="right") - 1
    return t - first[stretch], t[np.r_[cuts - 1, len(t) - 1]][stretch] - t


def segments(kept: RawLog, longest_step: float) -> list[np.ndarray]:
    """The rows of each stretch of the log without a step longer than `longest_step`, in time order."""
    cuts = np.flatnonzero(np.diff(kept.t) > longest_step) + 1
    return [np.asarray(r) for r in np.split(np.arange(len(kept.t)), cuts)]


def _reach(source: DataSource, rate: float) -> float:
    """How far a sample's conditioning reaches (s): the trim at each end of a conditioned stretch."""
    h = 1.0 / rate
    return source.trim if source.trim is not None else (TRIM_PERIODS / source.cutoff if source.cutoff else 2 * h)


def _conditioned(kept: RawLog, pieces: list[np.ndarray], source: DataSource, robot: RobotSpec, rate: float,
                 checked: Checked, label: str, notes: list[str]) -> JointLog:
    """Each stretch of rows conditioned on its own (steps 2-5), the stretches too short for the filter
    and the trim dropped (said in `notes`), the rest joined in time order."""
    reach = _reach(source, rate)
    pad = 3 * (2 * int(np.ceil(source.filter_order / 2)) + 1) if source.cutoff is not None else 0
    logs, dropped = [], []
    for rows in pieces:
        t0, t1 = kept.t[rows[0]], kept.t[rows[-1]]
        samples = int(np.floor((t1 - t0) * rate)) + 1
        if samples <= pad or samples - 2 * int(np.ceil(reach * rate)) < 10 * source.decimate:
            dropped.append((float(t0), float(t1)))
            continue
        logs.append(smooth(kept.span(np.isin(np.arange(len(kept.t)), rows)), source, robot, rate, checked.record,
                           checked.warnings))
    if dropped:
        notes.append(f"{label}: {len(dropped)} stretch(es) between gaps too short to filter and trim "
                     f"({', '.join(f'{a:.3g}-{b:.3g} s' for a, b in dropped[:4])}"
                     f"{' ...' if len(dropped) > 4 else ''}): dropped")
    if not logs:
        raise InputError(kept.file, "gap", f"{label}: no stretch between gaps is long enough to filter and trim "
                                           f"({2 * reach:.3g} s of trim and 10 samples at least)")
    if len(logs) == 1:
        return logs[0]
    joined = (np.concatenate([getattr(g, k) for g in logs]) for k in ("t", "q", "qd", "qdd", "tau"))
    t, q, qd, qdd, tau = joined
    conditioning = dict(logs[0].conditioning)
    conditioning["t_end"] = logs[-1].conditioning["t_end"]
    return JointLog(t, logs[0].joints, q, qd, qdd, tau, conditioning)


def _segment_record(kept: RawLog, pieces: list[np.ndarray], source: DataSource, median: float) -> dict:
    return {"split_at_steps_over_s": split_step(source, median),
            "definition": "a step over split_at_steps_over_s splits the log (the scenario's `gap` median steps; "
                          f"by default {GAP_SPLIT:g} median steps, with a low-pass filter at least a quarter period of "
                          "its cut-off): each stretch is resampled, filtered, differentiated and trimmed on its own",
            "stretches": [{"t_start": float(kept.t[r[0]]), "t_end": float(kept.t[r[-1]]), "rows": len(r)}
                          for r in pieces]}


def load(source: DataSource, robot: RobotSpec) -> tuple[JointLog, JointLog, JointLog | None]:
    """The conditioned log, its training span and its validation span (the last part by time, or
    another log): the identification never sees the validation data. The log is checked whole, then
    cut at every gap (a step over `gap` median steps) and, when split by time, at the split: each
    stretch is resampled, filtered, differentiated and trimmed on its own (on the whole file's grid
    rate), so that no filter or difference reaches across a gap or the split (the trim at both ends
    of each stretch is the guard band). `full` is then the spans one after the other (data.csv, the
    report); its conditioning record is the training span's, with the whole file's checks, the
    stretches and the split beside it."""
    raw = read_raw(source, robot)
    checked = check(raw, robot, source)
    kept, rate = checked.kept, checked.rate(source)
    pieces = segments(kept, split_step(source, checked.median_step))
    notes: list[str] = []
    if len(pieces) > 1:
        notes.append(f"{len(pieces) - 1} gap(s) over {split_step(source, checked.median_step):.3g} s (largest "
                     f"{float(np.max(np.diff(kept.t))):.3g} s): the log is conditioned in {len(pieces)} stretches, "
                     "nothing filtered across a gap")
    if source.validation_from is None:
        train = _conditioned(kept, pieces, source, robot, rate, checked, "log", notes)
        train.conditioning["segments"] = _segment_record(kept, pieces, source, checked.median_step)
        train.conditioning["warnings"] = train.conditioning["warnings"] + notes
        val = None
        if source.validation_file is not None:
            val = condition(read_raw(source, robot, source.validation_file), source, robot)
        return train, train, val
    t_split = kept.t[0] + source.validation_from * (kept.t[-1] - kept.t[0])
    before = kept.t < t_split
    if before.sum() < 10 or (~before).sum() < 10:
        raise InputError(source.file, "validation.from", f"splitting at {t_split:g} s leaves too few rows "
                                                         f"({int(before.sum())} and {int((~before).sum())})")
    spans = {name: [p[side[p]] for p in pieces if side[p].any()] for name, side in (("training", before),
                                                                                      ("validation", ~before))}
    train, val = (_conditioned(kept, spans[name], source, robot, rate, checked, f"{name} span", notes)
                  for name in ("training", "validation"))
    if not train.t[-1] < val.t[0]:
        raise InputError(source.file, "validation.from", f"the training span (to {train.t[-1]:g} s) and the "
                                                         f"validation span (from {val.t[0]:g} s) overlap")
    conditioning = dict(train.conditioning)
    conditioning["warnings"] = conditioning["warnings"] + notes
    conditioning["segments"] = _segment_record(kept, pieces, source, checked.median_step)
    conditioning["validation"] = {
        "from_fraction": source.validation_from, "t_split": float(t_split),
        "training_samples": len(train.t), "validation_samples": len(val.t),
        "guard_band_s": float(val.t[0] - train.t[-1]), "disjoint": True,
        "conditioned": "each span on its own (resampling, filter, derivatives, trim): nothing crosses the split",
        "training": {"t_start": train.conditioning["t_start"], "t_end": train.conditioning["t_end"]},
        "validation": {"t_start": val.conditioning["t_start"], "t_end": val.conditioning["t_end"]}}
    joined = (np.concatenate([getattr(train, k), getattr(val, k)]) for k in ("q", "qd", "qdd", "tau"))
    full = JointLog(np.concatenate([train.t, val.t]), train.joints, *joined, conditioning)
    return full, train, val
