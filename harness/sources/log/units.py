"""A log's values in SI units, and the checks that catch a unit, time-base or sign mistake before
anything is fitted: degrees of revolute joints to radians, motor currents to joint torques; values no
robot of the model's size can produce (a corrupt cell: 1e30), positions far beyond the joint limits
(degrees read as radians?), velocities that are not the positions' rate of change (t in milliseconds?
q' in deg/s? a column of the other sign?)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from harness.base.tomlio import InputError
from harness.model.spec import RobotSpec
from harness.sources.log.raw import RawLog
from harness.sources.log.schema import column_names

if TYPE_CHECKING:
    from harness.sources.log.schema import DataSource

UNIT_FACTOR = 3.0  # positions beyond the joint limits by this factor or more look like a unit mistake
VELOCITY_FACTOR = 3.0  # the positions' rate of change and the logged velocities this far apart: a unit mistake
TRACKING = 0.5  # a joint whose logged velocity follows its positions' changes this closely (cosine) moves
DEAD_TRAVEL = 10  # positions ranging over this many of their median step move (an encoder's jitter: 1 or 2)
TIME_UNITS = ((1e-3, "milliseconds"), (1e-6, "microseconds"), (1e-9, "nanoseconds"))
TIME_SYMBOL = {"milliseconds": "ms", "microseconds": "us", "nanoseconds": "ns"}
ABSURD = 1e3  # a value this many times beyond what the model's size allows (`plausible`) is no measurement
UNLIMITED_POSITION = 1e3  # rad or m: a joint without limits reaches at most ABSURD times this (160,000 turns)
DEFAULT_SPEED = 10.0  # rad/s or m/s: a joint without a velocity limit moves at most ABSURD times this
STANDARD_GRAVITY = 9.80665


def to_si(source: DataSource, robot: RobotSpec, q: np.ndarray, qd: np.ndarray | None,
          tau: np.ndarray) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
    """The log's q, q', tau in SI units: degrees of revolute joints to radians; motor currents to
    joint torques, tau = i k_t r (torque constant k_t in N m/A on the motor side, gear ratio r, each signed:
    a motor wired the other way, a reversing gear), or on a motor-side log (`side = "motor"`) to motor
    torques i k_t, which the model's drives take to the joints."""
    revolute = np.array([j.revolute for j in robot.joints])
    if source.units["q"] == "deg":
        q = np.where(revolute, np.radians(q), q)
    if qd is not None and source.units["qd"] == "deg/s":
        qd = np.where(revolute, np.radians(qd), qd)
    if source.units["tau"] == "current":
        ratio = 1.0 if source.side == "motor" else np.asarray(source.gear_ratio)
        tau = tau * np.asarray(source.torque_constant) * ratio
    return q, qd, tau


def plausible(robot: RobotSpec, source: DataSource | None = None) -> dict[str, np.ndarray]:
    """Per column of a log (a joint's, or on a motor-side log a motor's), the largest |q|, |q'| and |tau|
    (SI) the model's size allows, before ABSURD. At a joint: a position its limits' extent (at least
    1 rad or m; UNLIMITED_POSITION without limits), a velocity its limit (DEFAULT_SPEED without one), a
    torque its effort limit where given and at least the weight of every
    body at the robot's extent, g m_total max(d, 1 m), d the largest distance between its joint points
    and centres of mass at q = 0 (no joint's gravity torque is larger; a slide's force: g m_total). At a
    motor, through the drives: |N| times the joints' (and |offset|) for a position and a velocity,
    |N^-1|^T times theirs for a torque."""
    limits, drive = robot.limits or {}, robot.drive_limits or {}
    points = np.array([j.p_W0 for j in robot.joints] + [b.p_W_com0 for b in robot.bodies])
    extent = max(float(np.max(np.linalg.norm(points[:, None] - points[None], axis=-1))), 1.0)
    weight = STANDARD_GRAVITY * max(sum(b.mass for b in robot.bodies), 1.0)
    q, qd, tau = (np.empty(len(robot.joints)) for _ in range(3))
    for k, j in enumerate(robot.joints):
        lo, hi = limits.get(j.name, (-np.inf, np.inf))
        q[k] = max(abs(lo), abs(hi), hi - lo, 1.0) if np.isfinite(lo) and np.isfinite(hi) else UNLIMITED_POSITION
        qd[k] = drive.get(j.name, {}).get("velocity") or DEFAULT_SPEED
        tau[k] = max(drive.get(j.name, {}).get("effort") or 0.0, weight * (extent if j.revolute else 1.0))
    out = {"q": q, "qd": qd, "tau": tau}
    if source is not None and source.side == "motor":  # q_m = N q + o, q'_m = N q', tau_m = N^-T tau
        t = robot.transmission
        out = {"q": np.abs(t.N) @ q + np.abs(t.offset), "qd": np.abs(t.N) @ qd, "tau": np.abs(t.N_inv).T @ tau}
    return out


def refuse_absurd(kind: str, values: np.ndarray, bound: np.ndarray, path, names: list[str], row_of,
                  revolute: np.ndarray, converted: bool) -> None:
    """Refuse the first value of `values` (rows, columns; SI, at the log's side) beyond ABSURD times its
    column's `bound` (`plausible`): InputError naming the file, the column and the row (`row_of(i)`: how
    the file numbers row i). `converted`: the log's own unit was not SI (said with the value)."""
    over = np.abs(values) > ABSURD * bound
    if not over.any():
        return
    i, c = (int(x[0]) for x in np.nonzero(over))
    what = {"q": "position", "qd": "velocity", "tau": "torque" if revolute[c] else "force"}[kind]
    unit = {"q": ("m", "rad"), "qd": ("m/s", "rad/s"), "tau": ("N", "N m")}[kind][bool(revolute[c])]
    count = int(over.sum())
    raise InputError(path, names[c], f"{row_of(i)} is {values[i, c]:.4g} {unit}{' (in SI)' if converted else ''}: "
                                     f"over {ABSURD:g} times the largest {what} the model allows there "
                                     f"({bound[c]:.3g} {unit}), which no robot of its size measures: a corrupt "
                                     f"value ({count} such value{'s' if count > 1 else ''} in the column)")


def check_velocities(kept: RawLog, robot: RobotSpec, source: DataSource | None) -> None:
    """The logged velocities against the positions' rate of change, joint by joint: k, the
    least-squares slope of (q[i+1] - q[i]) / (t[i+1] - t[i]) on (q'[i] + q'[i+1]) / 2 over the kept
    rows (1.02 on every joint of the real Panda log of scenarios/panda_gaz2019.toml, 1.000 on a bench
    log), judged where the two follow each other (their cosine at least TRACKING: the joint moves). A
    k beyond VELOCITY_FACTOR either way, or negative, is a unit, time-base or sign mistake: refused,
    naming the likeliest one (t in milliseconds gives k = 1e-3 on every joint; q' in deg/s read as
    rad/s, k = 1/57.3). A velocity column that reads one value on every row (0: a channel that measures
    nothing) while its joint's positions range over DEAD_TRAVEL of their median step or more is refused
    too: its joint moves, and no slope or cosine can be read off a constant."""
    if kept.qd is None or len(kept.t) < 3:
        return
    step = np.diff(kept.t)
    dv, vv, dd = (np.empty(kept.q.shape[1]) for _ in range(3))
    for j in range(kept.q.shape[1]):  # joint by joint: a long log's differences are not made for all at once
        d = np.diff(kept.q[:, j]) / step
        v = 0.5 * (kept.qd[1:, j] + kept.qd[:-1, j])
        dv[j], vv[j], dd[j] = d @ v, v @ v, d @ d
    with np.errstate(invalid="ignore", divide="ignore"):
        k, cosine = dv / vv, dv / np.sqrt(vv * dd)
    moves = np.isfinite(cosine) & (np.abs(cosine) >= TRACKING)
    off = moves & ~((k >= 1.0 / VELOCITY_FACTOR) & (k <= VELOCITY_FACTOR))
    dead = _dead_velocities(kept)
    if not off.any() and not dead.any():
        return
    columns = source is not None and source.topic is None and "qd" in source.columns
    names = column_names(source, robot) if columns else {"t": ["t"], "qd": list(robot.joint_names)}
    if dead.any():
        j = int(np.flatnonzero(dead)[0])
        raise InputError(kept.file, names["qd"][j], f"joint {robot.joint_names[j]!r}: the logged q' is "
                                                    f"{kept.qd[0, j]:g} on every row while q ranges over "
                                                    f"{np.ptp(kept.q[:, j]):.3g}: a velocity channel that "
                                                    "measures nothing; leave qd out of [data] columns, and q is "
                                                    "differentiated")
    j = int(np.flatnonzero(off)[0])

    def near(x: float, to: float) -> bool:
        return x > 0 and abs(np.log(x / to)) < np.log(1.5)

    how = "the least-squares slope of the differences of q over those of t on q'; 1 in a consistent log"
    path = kept.file
    every = off.sum() == moves.sum()
    time_base = [unit for factor, unit in TIME_UNITS if every and all(near(x, factor) for x in k[off])]
    if time_base:
        median = float(np.median(k[off]))
        raise InputError(path, names["t"][0], f"on every joint that moves, q changes {median:.3g} times as fast "
                                              f"as the logged q' says ({how}): t in {time_base[0]}? give its unit, "
                                              f"units = {{ t = \"{TIME_SYMBOL[time_base[0]]}\" }}")
    hint = ("q' in deg/s read as rad/s? units = { qd = \"deg/s\" }" if near(k[j], np.pi / 180) else
            "q in degrees with q' in radians? give both units" if near(k[j], 180 / np.pi) else
            "q' has the opposite sign to q's changes" if near(-k[j], 1.0) else
            "q' is not the rate of change of q in the units given")
    raise InputError(path, names["qd"][j], f"joint {robot.joint_names[j]!r}: q changes {k[j]:.3g} times as "
                                           f"fast as the logged q' says ({how}): {hint}; or leave qd out of "
                                           "[data] columns, and q is differentiated")


def _dead_velocities(kept: RawLog) -> np.ndarray:
    """(n,) bool: the joints whose logged velocity is one value on every row while their positions range
    over DEAD_TRAVEL median steps (of those that change) or more."""
    dead = np.zeros(kept.q.shape[1], dtype=bool)
    for j in np.flatnonzero(np.all(kept.qd == kept.qd[0], axis=0)):
        steps = np.abs(np.diff(kept.q[:, j]))
        steps = steps[steps > 0]
        dead[j] = len(steps) > 0 and np.ptp(kept.q[:, j]) >= DEAD_TRAVEL * np.median(steps)
    return dead


def check_positions(raw: RawLog, robot: RobotSpec, source: DataSource | None) -> None:
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
            if robot.transmission is not None and (source is None or source.side == "joint"):
                hint = ('motor angles read as joint angles? side = "motor" maps them through the model\'s drives; '
                        f"or {hint}")
            raise InputError(raw.file, "units.q", f"joint {joint.name!r} reaches {largest:.4g} rad (as {unit} "
                                                  f"read), {largest / reach:.3g} times its limit {reach:.4g} "
                                                  f"rad: {hint}, or limits_check = false")
