"""The `[data]` table of a scenario (harness/sources/log/__init__.py has its layout), validated: the
file, its columns and units, the conditioning's settings, the split, and what the fit is asked to do
with the log (delays, torque constants, repeatability)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from harness.base.numerics import PREDICTION_TIMESTEP
from harness.base.tomlio import Table
from harness.model.spec import RobotSpec
from harness.sources.log.segments import GAP_FACTOR
from harness.sources.log.velocity import VELOCITY_CHOICES

MAX_FILTER_ORDER = 20
UNITS = {"q": ("rad", "deg"), "qd": ("rad/s", "deg/s"), "tau": ("N m", "current"), "t": ("s", "ms", "us", "ns")}
SI = {"q": "rad", "qd": "rad/s", "tau": "N m", "t": "s"}
SECONDS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}  # what one unit of a time column is
DELAY_CHOICES = ("estimate", "correct", "none")
TILT_CHOICES = ("chosen", "declared", "identified")  # harness/identify/gravity.py
MAX_REPEAT = 100


@dataclass(frozen=True)
class Prediction:
    """`[data] prediction = { starts, horizons }`: from how many measured states spread over the judged
    span each model is forward-simulated under the measured torques, and at which horizons (s, whole
    steps of the simulation, PREDICTION_TIMESTEP) its drift is read (harness/stages/log_judge.py). `starts = 0`
    makes none (said in the results)."""

    starts: int = 20
    horizons: tuple[float, ...] = (0.02, 0.05, 0.1, 0.2)


MAX_PREDICTION_STARTS = 1000
MAX_HORIZON = 10.0  # s: the longest rollout the prediction makes from each start


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
    torque_file: Path | None = None  # the torques (or currents) in a file of their own, row by row with `file`'s
    sample_rate: float | None = None  # Hz: a log without a time column, its rows 1 / sample_rate apart
    side: str = "joint"  # "motor": positions and torques at the motors, mapped through the model's drives
    window: tuple[float, float] | None = None  # s: the part of the log kept (the motion), by time
    decimate_given: bool = True  # False: `decimate` is the default, and a cutoff chosen by the data may set it
    joint_map: dict[str, str] = field(default_factory=dict)  # the log's name of a joint -> the model's
    velocities: str = "checked"  # logged velocities realigned where they lag the positions' rate ("used": kept)
    counterbalanced: tuple[str, ...] = ()  # joints whose channel carries no gravity (a spring or counterweight)
    unmeasured: tuple[str, ...] = ()  # joints without a torque channel: their motion in the model, no row of theirs
    joined: tuple[Path, ...] = ()  # a log in several files: the files after `file`, each with its own time
    # column, their rows joined on time to those of the file holding the positions (harness/sources/log/join.py)
    prediction: Prediction = field(default_factory=Prediction)  # the judging's forward simulation
    unmeasured_motors: tuple[str, ...] = ()  # a motor-side log's motors without a channel (`unmeasured`: the
    # joints they reach, `with_unmeasured_motors`)
    tilt: str = "chosen"  # gravity's direction in the base's axes: the torques' where they demand it
    # ("chosen"), always ("identified"), or as declared ("declared"; harness/identify/gravity.py)
    floating: Any = None  # a floating base's channels, [data.base] and [[data.contacts]]
    # (harness/sources/log/floating.py, FloatingLog); None for a fixed base

    @property
    def files(self) -> tuple[Path, ...]:
        """The log's files: `file`, and those joined to it on time."""
        return (self.file, *self.joined)

    def log_names(self, joints: list[str]) -> list[str]:
        """The log's name of each of the model's `joints` (`joint_map` read backwards; a joint it does
        not name keeps its own)."""
        back = {model: log for log, model in self.joint_map.items()}
        return [back.get(j, j) for j in joints]

    def describe(self) -> dict:
        return {"file": str(self.file), **({"joined_on_time": [str(f) for f in self.joined]} if self.joined else {}),
                "columns": {k: list(v) if isinstance(v, tuple) else v for k, v in self.columns.items()},
                "units": dict(self.units), "units_given": self.units_given,
                "torque_constant": list(self.torque_constant) if self.torque_constant else None,
                "gear_ratio": list(self.gear_ratio) if self.gear_ratio else None,
                "cutoff_hz": self.cutoff, "filter_order": self.filter_order, "rate_hz": self.rate,
                "decimate": self.decimate, "trim_s": self.trim, "gap_median_steps": self.gap,
                "validation_from": self.validation_from,
                "validation_file": str(self.validation_file) if self.validation_file else None,
                "truth": str(self.truth) if self.truth else None, "bag_topic": self.topic, "delay": self.delay,
                "tilt": self.tilt,
                "identify_torque_constants": self.identify_constants, "repeat_segments": self.repeat,
                "payload_log": None if self.payload is None else {
                    "file": str(self.payload.file), "body": self.payload.body, "mass": self.payload.mass,
                    "com": [float(x) for x in self.payload.com_W], "inertia": [float(x) for x in self.payload.inertia]},
                "torque_file": str(self.torque_file) if self.torque_file else None, "sample_rate_hz": self.sample_rate,
                "side": self.side, "window_s": list(self.window) if self.window else None,
                "joint_map": dict(self.joint_map), "velocities": self.velocities,
                "counterbalanced": list(self.counterbalanced), "unmeasured": list(self.unmeasured),
                **({"unmeasured_motors": list(self.unmeasured_motors)} if self.unmeasured_motors else {}),
                **({"floating_base": self.floating.describe()} if self.floating is not None else {}),
                "prediction": {"starts": self.prediction.starts, "horizons_s": list(self.prediction.horizons)}}

    def measured(self, joints: list[str]) -> list[str]:
        """The joints among `joints` whose torque channel the log holds (all but `unmeasured`)."""
        return [j for j in joints if j not in self.unmeasured]



def read_source(t: Table, scenario_file: Path, joints: int | None = None,
                joint_names: list[str] | None = None, motor_names: list[str] | None = None) -> DataSource:
    """The `[data]` table, validated (the file must exist and be inside reach of the scenario);
    `joints`, the model's number of joints, checks explicit column lists and per-joint constants;
    `joint_names`, the model's joints, the values of `joint_map`."""
    topic = None
    joint_map = _joint_map(t, joint_names) if t.has("joint_map") else {}
    at_motors = t.data.get("side") == "motor" and motor_names is not None  # its channels are the motors'
    unmeasured = _unmeasured(t, motor_names if at_motors else joint_names)
    if t.either("file", "bag", "file (a CSV log) or bag (a ROS bag: a rosbag2 folder or a ROS 1 .bag file)") == "bag":
        file = (scenario_file.parent / t.string("bag")).resolve()
        if not file.exists():
            raise t.error("bag", f"no bag {t.data['bag']!r} (looked for {file})")
        topic = t.string("topic")
        if t.has("columns"):
            raise t.error("columns", "a bag's JointState messages name their joints: no columns to give")
        columns: dict[str, str | tuple[str, ...]] = {}
        ct, joined = None, ()
    else:
        file, joined = _files(t, scenario_file)
        ct = t.table("columns")
        columns = _columns(ct, joints, len(unmeasured))
        if joined and "t" not in columns:
            raise ct.error("t", "missing: a log in several files joins them on each file's time column")
        if "names" in columns and (joined or t.has("torque_file")):
            raise ct.error("names", "a log whose messages name their joints is read from one file")
    torque_file, sample_rate, side, window = _layout(t, ct, scenario_file, topic)
    units, units_given = dict(SI), t.has("units")
    if units_given:
        ut = t.table("units")
        for k, choices in UNITS.items():
            if ut.has(k):
                units[k] = ut.string(k, choices=choices)
        ut.finish()
    constant = ratio = None
    if units["tau"] == "current" and side == "motor":  # each motor's current times its constant: its torque
        if t.has("gear_ratio"):
            raise t.error("gear_ratio", "with side = \"motor\" the model's drives hold the ratios ([drives])")
        constant = _per_joint(t, "torque_constant", joints)
    elif units["tau"] == "current":
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
    tilt = t.string("tilt", default="chosen", choices=TILT_CHOICES)
    payload = None
    if t.has("payload"):
        if t.has("torque_file") or joined:
            raise t.error("payload", "a payload log beside a torque file or a log in several files is not "
                                     "supported: one file per log")
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
    decimate_given = t.has("decimate")
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
            if t.has("torque_file") or joined:
                raise vt.error("file", f"with {'torque_file' if t.has('torque_file') else 'a log in several files'}"
                                       ", the validation span is a part of the log: validation = { from = ... }")
        vt.finish()
    velocities = t.string("velocities", default="checked", choices=VELOCITY_CHOICES)
    counterbalanced = _counterbalanced(t, joint_names, () if at_motors else unmeasured)
    if unmeasured and side == "motor" and not at_motors:
        raise t.error("unmeasured", "a motor-side log's channels are its motors': the model states none ([drives])")
    unmeasured, unmeasured_motors = ((), unmeasured) if side == "motor" else (unmeasured, ())
    prediction = _prediction(t.table("prediction")) if t.has("prediction") else Prediction()
    t.finish()
    return DataSource(file, columns, cutoff, order, rate, decimate, trim, v_from, v_file, units, units_given, constant,
                      ratio, gap, limits_check, truth, topic, delay, payload, identify_constants, repeat, torque_file,
                      sample_rate, side, window, decimate_given, joint_map, velocities, counterbalanced, unmeasured,
                      joined, prediction, unmeasured_motors, tilt=tilt)


def _prediction(t: Table) -> Prediction:
    """`prediction = { starts = 20, horizons = [0.02, 0.05, 0.1, 0.2] }`, validated: a count of starts
    (0: no forward simulation) and strictly increasing horizons, each a whole number of the simulation's
    steps up to MAX_HORIZON."""
    starts = t.integer("starts", default=Prediction.starts, minimum=0)
    if starts > MAX_PREDICTION_STARTS:
        raise t.error("starts", f"{starts}: at most {MAX_PREDICTION_STARTS}")
    horizons = tuple(float(h) for h in t.vector("horizons", length=None, default=list(Prediction.horizons)))
    if not horizons:
        raise t.error("horizons", "empty: at least one horizon (s), or starts = 0 for no forward simulation")
    steps = np.asarray(horizons) / PREDICTION_TIMESTEP
    if np.any(steps < 1.0) or np.any(steps > MAX_HORIZON / PREDICTION_TIMESTEP) or np.any(
            np.abs(steps - np.round(steps)) > 1e-9 * steps):
        raise t.error("horizons", f"{list(horizons)}: each a whole number of the simulation's "
                                  f"{PREDICTION_TIMESTEP:g} s steps, up to {MAX_HORIZON:g} s")
    if np.any(np.diff(steps) <= 0):
        raise t.error("horizons", f"{list(horizons)}: strictly increasing")
    t.finish()
    return Prediction(starts, horizons)


def _counterbalanced(t: Table, joint_names: list[str] | None, unmeasured: tuple[str, ...]) -> tuple[str, ...]:
    """`counterbalanced = [...]`: the joints whose channel carries no gravity, none of them unmeasured."""
    counterbalanced = t.strings("counterbalanced", choices=joint_names) if t.has("counterbalanced") else ()
    both = [j for j in counterbalanced if j in unmeasured]
    if both:
        raise t.error("counterbalanced", f"{both[0]!r} is unmeasured: it has no channel to be without gravity")
    return counterbalanced


def _unmeasured(t: Table, joint_names: list[str] | None) -> tuple[str, ...]:
    """`unmeasured = [...]`: the joints whose torque the log does not measure (no column, or a channel that
    reads nothing; of a motor-side log, its motors): each a joint (motor) of the model, once, and at least
    one left measured."""
    if not t.has("unmeasured"):
        return ()
    names = t.strings("unmeasured", choices=joint_names)
    if len(set(names)) < len(names):
        raise t.error("unmeasured", "a joint is named twice")
    if joint_names is not None and len(names) >= len(joint_names):
        raise t.error("unmeasured", "every joint named: a log without one torque channel identifies nothing")
    return tuple(names)


def _files(t: Table, scenario_file: Path) -> tuple[Path, tuple[Path, ...]]:
    """`file`: one CSV, or a list of CSVs, each with its own time column, holding the quantities
    between them (the positions in one, the velocities in another, the torques in a third, as a
    robot's tools export one file per topic or quantity): the first and the rest."""
    if not isinstance(t.data.get("file"), list):
        return _file(t, "file", scenario_file), ()
    names = t.strings("file", choices=None)
    paths = [(scenario_file.parent / name).resolve() for name in names]
    for name, path in zip(names, paths, strict=True):
        if not path.is_file():
            raise t.error("file", f"file {name!r} not found (looked for {path})")
    if len(set(paths)) < len(paths):
        raise t.error("file", "a file is named twice")
    if t.has("torque_file"):
        raise t.error("torque_file", "a log in several files names every file in `file`")
    if t.has("sample_rate"):
        raise t.error("sample_rate", "a log in several files is joined on its files' time columns")
    return paths[0], tuple(paths[1:])


def _joint_map(t: Table, joint_names: list[str] | None) -> dict[str, str]:
    """`joint_map = { "log name" = "model name", ... }`: each value one of the model's joints, once."""
    mt = t.table("joint_map")
    out = {log: mt.string(log) for log in list(mt.data)}
    mt.finish()
    for log, model in out.items():
        if joint_names is not None and model not in joint_names:
            raise t.error("joint_map", f"{log!r} is mapped to {model!r}, which is not a joint of the model "
                                       f"({', '.join(joint_names)})")
    twice = sorted({m for m in out.values() if list(out.values()).count(m) > 1})
    if twice:
        raise t.error("joint_map", f"{twice[0]!r} is the image of more than one of the log's names")
    unmapped = [j for j in joint_names or () if j in out and out[j] != j and j not in out.values()]
    if unmapped:  # the log's name of another joint, and the model's joint of that name left to find its own
        raise t.error("joint_map", f"{unmapped[0]!r} is the log's name of {out[unmapped[0]]!r} and a joint of the "
                                   "model the map gives no name in the log")
    return out


SIDES = ("joint", "motor")


def _layout(t: Table, ct: Table | None, scenario_file: Path, topic: str | None
            ) -> tuple[Path | None, float | None, str, tuple[float, float] | None]:
    """How the log is laid out: `torque_file` (the torques in a file of their own, row by row with
    `file`), `sample_rate` (Hz, where the log has no time column), `side` ("joint", or "motor": q and tau
    of the motors, mapped through the model's drives) and `window` ([t0, t1] s, the part kept)."""
    torque_file = None
    if t.has("torque_file"):
        if topic is not None:
            raise t.error("torque_file", "a bag's messages carry their efforts: no torque file to give")
        torque_file = _file(t, "torque_file", scenario_file)
    sample_rate = t.number("sample_rate", positive=True) if t.has("sample_rate") else None
    if ct is not None and ct.has("t") == (sample_rate is not None):
        raise (t.error("sample_rate", "the log has a time column (columns.t): its times are read, not made")
               if sample_rate is not None else
               ct.error("t", "missing: name the time column, or give sample_rate (Hz) for a log without one"))
    if topic is not None and sample_rate is not None:
        raise t.error("sample_rate", "a bag's messages carry their times")
    side = t.string("side", default="joint", choices=SIDES)
    window = None
    if t.has("window"):
        w = t.vector("window", length=2)
        if not 0.0 <= w[0] < w[1]:
            raise t.error("window", f"[{w[0]:g}, {w[1]:g}] s is no part of a log: [start, end] with 0 <= start < end")
        window = (float(w[0]), float(w[1]))
    return torque_file, sample_rate, side, window


def _columns(ct: Table, joints: int | None, unmeasured: int = 0) -> dict[str, str | tuple[str, ...]]:
    """`columns`: t (where the log has a time column), q, qd (optional) and tau, each a template with
    {j} or {name}, or a list of column names in the model's joint order (tau's: of every joint, or of the
    measured joints alone where `unmeasured` joints have no channel); or, with `names` (a template
    with {index}: the columns that name each message's joints, as a ROS joint_states export writes
    `field.name0`, `field.name1`, ...), templates with {index}, the place of a joint's name among them
    (harness/sources/log/indexed.py)."""
    columns: dict[str, str | tuple[str, ...]] = {"t": ct.string("t")} if ct.has("t") else {}
    indexed = ct.has("names")
    if indexed:
        columns["names"] = ct.string("names")
        if "{index}" not in columns["names"]:
            raise ct.error("names", f"{columns['names']!r}: the columns of the joints' names need {{index}}")
    fields = "{index}" if indexed else "{j} or {name}"
    for k in ("q", "qd", "tau"):
        if k == "qd" and not ct.has("qd"):
            continue
        if isinstance(ct.data.get(k), list) and not indexed:
            names = ct.strings(k, choices=None)
            if joints is not None and len(names) != joints and not (k == "tau" and unmeasured
                                                                    and len(names) == joints - unmeasured):
                raise ct.error(k, f"{len(names)} columns for a model of {joints} joints (one per joint, in the "
                                  "model's joint order" + (f"; or tau's {joints - unmeasured}, one per measured joint"
                                                           if k == "tau" and unmeasured else "") + ")")
            columns[k] = names
            continue
        v = ct.string(k)
        if indexed and "{index}" not in v:
            raise ct.error(k, f"with names, a per-joint column needs {{index}} (the joint's place among the names), "
                              f"got {v!r}")
        if not indexed and "{j}" not in v and "{name}" not in v:
            raise ct.error(k, f"a per-joint column needs {{j}} (1..n in the model's joint order) or {{name}} (the "
                              f"joint's name), or a list of the columns in joint order, got {v!r}")
        try:
            v.format(index=0) if indexed else v.format(j=1, name="joint")
        except (KeyError, IndexError, ValueError):
            raise ct.error(k, f"{v!r}: only {fields} may stand in braces") from None
        columns[k] = v
    ct.finish()
    return columns


def _per_joint(t: Table, key: str, joints: int | None) -> tuple[float, ...]:
    """A nonzero number per joint (a list in the model's joint order), or one for every joint: a torque
    constant's or a gear ratio's sign states which way the motor's current or the gear turns the joint
    (a motor wired the other way, a gear that reverses), as its maker publishes it."""
    values = t.vector(key, length=joints) if isinstance(t.data.get(key), list) else np.full(joints or 1, t.number(key))
    if not np.all(np.isfinite(values) & (values != 0)):
        raise t.error(key, "every value must be a nonzero number (its sign the motor's or the gear's direction)")
    return tuple(float(v) for v in values)


def _file(t: Table, key: str, scenario_file: Path, bag: bool = False) -> Path:
    """A file named relative to the scenario; a bag may be a folder (rosbag2)."""
    path = (scenario_file.parent / t.string(key)).resolve()
    if not (path.exists() if bag else path.is_file()):
        raise t.error(key, f"file {t.data[key]!r} not found (looked for {path})")
    return path



def column_names(source: DataSource, robot: RobotSpec) -> dict[str, list[str]]:
    """The log's column of each quantity and joint: {j} is 1..n in the model's joint order, {name}
    the joint's name in the log (`joint_map`); a log whose messages name their joints (`names`) once its
    {index} templates are made lists (harness/sources/log/indexed.py)."""
    if "names" in source.columns:
        raise ValueError("a log whose messages name their joints is read through sources.log.indexed.resolved")
    out = {k: [v] if k == "t" else list(v) if isinstance(v, tuple) else
           [v.format(j=j + 1, name=name) for j, name in enumerate(source.log_names(robot.joint_names))]
           for k, v in source.columns.items()}
    if source.unmeasured and len(out["tau"]) == len(robot.joint_names):  # the measured joints' channels alone
        out["tau"] = [c for c, j in zip(out["tau"], robot.joint_names, strict=True) if j not in source.unmeasured]
    if source.floating is not None:  # the base's and the contacts' columns (harness/sources/log/floating.py)
        out.update(source.floating.columns())
    return out


def with_unmeasured_motors(source: DataSource, t: Table, transmission, joint_names: list[str]) -> DataSource:
    """A motor-side log's unmeasured motors (`[data]` table t) as the joints whose torque it cannot give:
    tau_J = N^T tau_m needs every motor k with N[k, j] != 0, so each joint an unmeasured motor turns is
    unmeasured (harness/model/drives.py); refused where that leaves no joint measured."""
    if not source.unmeasured_motors or transmission is None:
        return source
    rows = [transmission.motors.index(m) for m in source.unmeasured_motors]
    reached = np.any(transmission.N[rows] != 0, axis=0)
    if reached.all():
        raise t.error("unmeasured", f"{', '.join(source.unmeasured_motors)} turn every joint: no joint's torque is "
                                    "left to read (tau_J = N^T tau_m needs each motor that turns the joint)")
    return dataclasses.replace(source, unmeasured=tuple(j for j, r in zip(joint_names, reached, strict=True) if r))
