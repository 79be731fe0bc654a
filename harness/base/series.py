"""TimeSeries: a robot's motion sampled in time, one row per sample, the one type for what the bench
records (paper section 3.1) and what a measured log gives (as mujoco.sysid's `TimeSeries`).

SI units; world components (frame W) unless a name says otherwise. Per joint J (in `joints` order): q,
q', q'' and the drive force or torque along the joint axis. What the bench also records, and a log
does not (None there): the wrench the inner body applies to the outer body across J, force F_W and
moment M_W about the joint point O_J; per massive body B its pose (orientation R_WB, the body's
principal axes as columns in world components, and centre of mass p_W), its twist (centre-of-mass
velocity v_W, angular velocity omega_W) and their rates (centre-of-mass acceleration a_W, angular
acceleration omegadot_W). A study derives what else it reads from these: orientation angles, the
accelerations of other points. `meta` says where the rows came from: the engine and its settings
(a recording), the file and its digest (a raw log, as read), or every step of the conditioning (a
conditioned log).

CSV columns (`columns`): t; q_J qd_J qdd_J tau_J; then, where recorded, B_x B_y B_z; B_vx B_vy B_vz;
B_R11 B_R12 B_R13 B_R21 ... B_R33 (R_WB row by row); B_ax B_ay B_az; B_wx B_wy B_wz; B_wdx B_wdy
B_wdz; J_Fx J_Fy J_Fz; J_Mx J_My J_Mz; a closed chain's loops' and a moving floating base's columns
(`TimeSeries.columns`). Floats are written with 17 significant digits, so a series read
back from CSV is bit-for-bit the one written.
"""

from __future__ import annotations

import dataclasses
import io
from dataclasses import dataclass, field, fields
from pathlib import Path

import numpy as np

from harness.base.tomlio import MAX_DATA_BYTES, InputError, read_bounded

XYZ = ("x", "y", "z")
ROTATION = tuple(f"R{i}{j}" for i in (1, 2, 3) for j in (1, 2, 3))  # R_WB row by row
JOINT_CHANNELS = ("q", "qd", "qdd", "tau")
WRENCH_CHANNELS = ("F_W", "M_W")
BODY_CHANNELS = ("p_W", "v_W", "R_WB", "a_W", "omega_W", "omegadot_W")
BASE_COLUMNS = {"base_pose": ("x", "y", "z", "qw", "qx", "qy", "qz"),
                "base_twist_W": ("vx", "vy", "vz", "wx", "wy", "wz"),
                "base_rate_W": ("ax", "ay", "az", "wdx", "wdy", "wdz"),
                "base_wrench_W": ("Fx", "Fy", "Fz", "Mx", "My", "Mz")}  # a moving base's CSV columns, base[<name>]
CONTACT_COLUMNS = {"contact_F_W": ("Fx", "Fy", "Fz"), "contact_M_W": ("Mx", "My", "Mz"), "contact_x_W": ("x", "y", "z"),
                   "contact_held": ("held",)}  # a contact's, contact[<name>][<column>]


@dataclass(frozen=True, eq=False)
class Drive:
    """How an engine drove a recording (harness/engines/mujoco.py): its integrator and step, and the
    torque it applied at every evaluation of every step, so that another model can be driven by exactly
    the same input; and the motion the drive was asked to follow at the recording's rows. Spec joint
    order, SI."""

    integrator: str  # "RK4", "Euler", ...
    timestep: float  # s: one engine step
    substeps: int  # engine steps per recorded row
    stages: np.ndarray  # (steps, evaluations per step, nj): the drive torque at each evaluation
    q_ref: np.ndarray  # (N, nj) the prescribed motion at the recording's rows
    qd_ref: np.ndarray  # (N, nj)
    qdd_ref: np.ndarray  # (N, nj)

    def rk4_stages(self) -> np.ndarray | None:
        """The torques at each RK4 step's four stages, (steps, 4, nj); None where it integrated otherwise."""
        return self.stages if self.integrator == "RK4" and self.stages.shape[1] == 4 else None


class SeriesError(ValueError):
    """A series' invariant broken: `field` names the array (t, q, tau, ...)."""

    def __init__(self, field: str, what: str):
        super().__init__(f"TimeSeries {field}: {what}")
        self.field, self.what = field, what


def rows_checked(t: np.ndarray, named: dict[str, np.ndarray | None], joints: int, increasing: bool = True) -> None:
    """The invariants of a series' rows: t one finite value per row (strictly increasing unless a raw
    log's, whose order its checks judge and name by row), every per-row array in `named` (None where
    not measured) N rows long and finite, and the joint channels among them (JOINT_CHANNELS) one
    column per joint of `joints`. A SeriesError (a ValueError) names the first broken one."""
    if np.ndim(t) != 1 or len(t) == 0:
        raise SeriesError("t", f"must be one time per row (shape {np.shape(t)})")
    if not np.all(np.isfinite(t)):
        raise SeriesError("t", f"not finite at row {int(np.flatnonzero(~np.isfinite(t))[0])}")
    if increasing and np.any(np.diff(t) <= 0):
        raise SeriesError("t", f"not strictly increasing at row {int(np.flatnonzero(np.diff(t) <= 0)[0]) + 1}")
    for name, x in named.items():
        if x is None:
            continue
        if np.shape(x)[:1] != (len(t),):
            raise SeriesError(name, f"{np.shape(x)[0] if np.ndim(x) else 0} rows where t has {len(t)}")
        if name in JOINT_CHANNELS and np.shape(x)[1:] != (joints,):
            raise SeriesError(name, f"shape {np.shape(x)} for {joints} joints")
        if np.asarray(x).dtype.kind == "f" and not np.all(np.isfinite(x)):
            raise SeriesError(name, f"not finite at row {int(np.argwhere(~np.isfinite(x))[0][0])}")


@dataclass(frozen=True, eq=False)
class TimeSeries:
    t: np.ndarray  # (N,) s
    joints: tuple[str, ...]
    q: np.ndarray  # (N, nj)
    qd: np.ndarray | None  # None where not measured (a raw log without velocities)
    qdd: np.ndarray | None  # None where not measured (a raw log: accelerations come from its conditioning)
    tau: np.ndarray  # (N, nj) drive force (prismatic) or torque (revolute) along the axis
    bodies: tuple[str, ...] = ()
    F_W: np.ndarray | None = None  # (N, nj, 3) force of the inner body on the outer body at O_J
    M_W: np.ndarray | None = None  # (N, nj, 3) moment of the inner body on the outer body about O_J
    p_W: np.ndarray | None = None  # (N, nb, 3) centre of mass
    v_W: np.ndarray | None = None  # (N, nb, 3) centre-of-mass velocity
    R_WB: np.ndarray | None = None  # (N, nb, 3, 3) orientation: the body's axes in world components
    a_W: np.ndarray | None = None  # (N, nb, 3) centre-of-mass acceleration
    omega_W: np.ndarray | None = None  # (N, nb, 3)
    omegadot_W: np.ndarray | None = None  # (N, nb, 3)
    loops: tuple[str, ...] = ()  # a closed chain's loops (harness/model/loops.py)
    loop_gap: np.ndarray | None = None  # (N, n_loops) m: how far each loop's joined points are apart (a coupling's
    # |q_f - r q_l - o|, rad or m as its follower moves)
    loop_F_W: np.ndarray | None = None  # (N, nb, 3) the loops' force on each body (a closed chain's)
    loop_M_W: np.ndarray | None = None  # (N, nb, 3) and their moment about its centre of mass
    loop_tau: np.ndarray | None = None  # (N, nj) the loops' generalised force on each joint (MuJoCo's
    # qfrc_constraint): J^T lambda, a coupling's torque pair included, which acts on no body from outside
    # a floating base moved by the bench (harness/model/floating.py, BaseMotion.rows; world axes):
    base_pose: np.ndarray | None = None  # (N, 7) the base frame's origin p_W and quaternion w x y z
    base_twist_W: np.ndarray | None = None  # (N, 6) its origin's velocity v_W and angular velocity omega_W
    base_rate_W: np.ndarray | None = None  # (N, 6) their rates a_W, alpha_W
    base_wrench_W: np.ndarray | None = None  # (N, 6) the world's wrench on the base, F_W and M_W about its origin
    # (besides its contacts'); a floating base standing on contacts (harness/model/contacts.py; world axes):
    contacts: tuple[str, ...] = ()
    contact_F_W: np.ndarray | None = None  # (N, k, 3) each contact's force on its body (0 while released)
    contact_M_W: np.ndarray | None = None  # (N, k, 3) and moment about its point (0 for a point contact)
    contact_x_W: np.ndarray | None = None  # (N, k, 3) the point
    contact_held: np.ndarray | None = None  # (N, k) whether it holds
    drive: Drive | None = None  # a recording's: how the engine drove it (None for a log, or read from CSV)
    meta: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        """Strictly increasing finite times; every per-row array N rows and finite; q and tau (and q',
        q'' where given) one column per joint (SeriesError otherwise)."""
        rows_checked(self.t, {f.name: getattr(self, f.name) for f in fields(self)
                              if f.name != "t" and isinstance(getattr(self, f.name), np.ndarray)}, len(self.joints))

    def joint_index(self, name: str) -> int:
        return self.joints.index(name)

    def body_index(self, name: str) -> int:
        return self.bodies.index(name)

    def joint_data(self, joints) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(q, q', q'', tau) in the given joint order, each (N, n)."""
        cols = [self.joint_index(j) for j in joints]
        return self.q[:, cols], self.qd[:, cols], self.qdd[:, cols], self.tau[:, cols]

    def span(self, rows: np.ndarray | slice) -> TimeSeries:
        """The rows `rows` (indices, a boolean mask or a slice) of every per-row array; `meta` kept."""
        return dataclasses.replace(self, **{k: x[rows] for k, x in TimeSeries.per_row(self).items()})

    @staticmethod
    def per_row(series: TimeSeries) -> dict[str, np.ndarray]:
        """Every per-row array of `series` (the joints', and a floating base's, its contacts', the bodies')."""
        return {f.name: getattr(series, f.name) for f in fields(series)
                if isinstance(getattr(series, f.name), np.ndarray)}

    def columns(self) -> dict[str, np.ndarray]:
        """The CSV's columns in order, {name: (N,) values}: the joints', then the bodies' and the joint
        wrenches where they are recorded, then a closed chain's loop gaps (`gap[<loop>]`, m, or rad for a
        coupling of hinges), the loops' force and moment on each body (`loopFx[<body>]` .. `loopMz[<body>]`)
        and their generalised force on each joint (`loopTau[<joint>]`); a moving floating base's pose,
        twist, their rate and the world's wrench on it (`base[x]` .. `base[Mz]`, BASE_COLUMNS)."""
        cols: dict[str, np.ndarray] = {"t": self.t}
        for j, name in enumerate(self.joints):
            for k in JOINT_CHANNELS:
                cols[f"{k}_{name}"] = getattr(self, k)[:, j]
        if self.R_WB is not None:
            R = self.R_WB.reshape(len(self.t), len(self.bodies), 9)
            for b, name in enumerate(self.bodies):
                for arr, suffixes, prefix in ((self.p_W, XYZ, ""), (self.v_W, XYZ, "v"), (R, ROTATION, ""),
                                              (self.a_W, XYZ, "a"), (self.omega_W, XYZ, "w"),
                                              (self.omegadot_W, XYZ, "wd")):
                    for k, s in enumerate(suffixes):
                        cols[f"{name}_{prefix}{s}"] = arr[:, b, k]
        if self.F_W is not None:
            for j, name in enumerate(self.joints):
                for k, s in enumerate(XYZ):
                    cols[f"{name}_F{s}"] = self.F_W[:, j, k]
                for k, s in enumerate(XYZ):
                    cols[f"{name}_M{s}"] = self.M_W[:, j, k]
        for k, name in enumerate(self.loops if self.loop_gap is not None else ()):
            cols[f"gap[{name}]"] = self.loop_gap[:, k]
        if self.loop_F_W is not None:
            for b, name in enumerate(self.bodies):
                for arr, kind in ((self.loop_F_W, "F"), (self.loop_M_W, "M")):
                    for k, s in enumerate(XYZ):
                        cols[f"loop{kind}{s}[{name}]"] = arr[:, b, k]
        if self.loop_tau is not None:
            for j, name in enumerate(self.joints):
                cols[f"loopTau[{name}]"] = self.loop_tau[:, j]
        if self.base_pose is not None:
            for field_name, names in BASE_COLUMNS.items():
                if getattr(self, field_name) is None:  # a log's base: the world's wrench on it is not read
                    continue
                for k, c in enumerate(names):
                    cols[f"base[{c}]"] = getattr(self, field_name)[:, k]
        for c, name in enumerate(self.contacts):
            for field_name, names in CONTACT_COLUMNS.items():
                if getattr(self, field_name) is None:  # a log's contacts: whether each held is not read
                    continue
                values = getattr(self, field_name)[:, c]
                for k, s in enumerate(names):
                    cols[f"contact[{name}][{s}]"] = values[:, k] if values.ndim == 2 else values.astype(int)
        return cols

    def write_csv(self, path: Path) -> None:
        """Every value to 17 significant digits (a double read back is the same double; a NaN as "nan"):
        harness/base/csvtext.py."""
        from harness.base.csvtext import csv_text

        with open(path, "w", newline="") as f:
            f.write(csv_text(self.columns()))


def read_csv(path: Path | str, bodies: bool = True) -> TimeSeries:
    """A series written by `TimeSeries.write_csv`, read back: joints from the q_ columns, and with
    `bodies` (a recording) the bodies from the _R11 ones and every joint's wrench; without (a log) the
    joints alone. A missing column, an empty or unparsable cell (a truncated file) is an InputError."""
    import pandas as pd

    kind = "recording" if bodies else "conditioned log"
    try:
        df = pd.read_csv(io.BytesIO(read_bounded(path, MAX_DATA_BYTES)))
    except (ValueError, pd.errors.ParserError) as exc:
        raise InputError(path, "", f"cannot read the {kind} ({str(exc).splitlines()[0]})") from None
    bad = [c for c in df.columns if not pd.api.types.is_numeric_dtype(df[c]) or df[c].isna().any()]
    if bad or "t" not in df.columns:
        raise InputError(path, bad[0] if bad else "t", f"missing, empty or not a number in some row (a truncated or "
                                                         f"edited {kind})")
    joints = tuple(c[2:] for c in df.columns if c.startswith("q_"))
    names = tuple(c[: -len("_R11")] for c in df.columns if c.endswith("_R11")) if bodies else ()
    if not joints or (bodies and not names):
        raise InputError(path, "q_<joint>" if not joints else "<body>_R11",
                         "column missing: a recording.csv holds every joint's q_ and every body's orientation "
                         "R11 .. R33 (a file of another layout, or of an earlier version, cannot be read)")
    expected = ["t", *(f"{k}_{j}" for j in joints for k in JOINT_CHANNELS)]
    if bodies:
        expected += [*(f"{j}_{k}{a}" for j in joints for k in ("F", "M") for a in XYZ),
                     *(f"{b}_{k}{a}" for b in names for k in ("", "v", "a", "w", "wd") for a in XYZ),
                     *(f"{b}_{r}" for b in names for r in ROTATION)]
        if any(c.startswith("base[") for c in df.columns):  # a moving floating base's, all of them
            expected += [f"base[{c}]" for columns in BASE_COLUMNS.values() for c in columns]
        expected += [f"contact[{n}][{s}]" for n in _contact_names(df.columns) for columns in CONTACT_COLUMNS.values()
                     for s in columns]
    missing = [c for c in expected if c not in df.columns]
    if missing:
        raise InputError(path, missing[0], f"column missing: not a complete {kind}")

    def per_joint(prefix: str) -> np.ndarray:
        return df[[f"{prefix}_{j}" for j in joints]].to_numpy()

    series = dict(t=df["t"].to_numpy(), joints=joints, **{k: per_joint(k) for k in JOINT_CHANNELS})
    try:
        return TimeSeries(**series) if not bodies else _with_bodies(df, series, joints)
    except SeriesError as exc:  # finite numbers, but not a series (times out of order, an edited file)
        column = "t" if exc.field == "t" else next((c for c in df.columns if not np.all(np.isfinite(df[c]))), exc.field)
        raise InputError(path, column, f"{exc.what} (a {kind} is strictly increasing in t, every value "
                                       "finite)") from None


def every_row(parts: list[TimeSeries]) -> dict[str, np.ndarray]:
    """Every per-row array the parts hold (TimeSeries.per_row), joined in the parts' order: a log's stretches
    between gaps, or its training and validation spans."""
    return {k: np.concatenate([getattr(p, k) for p in parts]) for k in TimeSeries.per_row(parts[0])}


def _contact_names(columns) -> tuple[str, ...]:
    """The contacts a recording's columns name (`contact[<name>][...]`), in their order."""
    return tuple(dict.fromkeys(c[len("contact["):].split("]")[0] for c in columns if c.startswith("contact[")))


def _with_bodies(df, series: dict, joints: tuple[str, ...]) -> TimeSeries:
    """A recording's series: the joints' `series` and, from the frame `df`, the bodies' and wrenches'."""
    names = tuple(c[: -len("_R11")] for c in df.columns if c.endswith("_R11"))

    def vec(of: tuple[str, ...], fmt: str) -> np.ndarray:
        return np.stack([df[[fmt.format(n=n, s=s) for s in XYZ]].to_numpy() for n in of], axis=1)

    R = np.stack([df[[f"{b}_{r}" for r in ROTATION]].to_numpy() for b in names], axis=1)
    loops = tuple(c[len("gap["):-1] for c in df.columns if c.startswith("gap[") and c.endswith("]"))
    if loops:
        series.update(loops=loops, loop_gap=df[[f"gap[{n}]" for n in loops]].to_numpy())
    if all(f"loopFx[{b}]" in df.columns for b in names) and names:
        series.update({f"loop_{kind}_W": np.stack([df[[f"loop{kind}{s}[{b}]" for s in XYZ]].to_numpy() for b in names],
                                                  axis=1) for kind in ("F", "M")})
    if all(f"loopTau[{j}]" in df.columns for j in joints):
        series["loop_tau"] = df[[f"loopTau[{j}]" for j in joints]].to_numpy()
    if any(c.startswith("base[") for c in df.columns):
        for field_name, columns in BASE_COLUMNS.items():  # every one there (read_csv)
            series[field_name] = df[[f"base[{c}]" for c in columns]].to_numpy()
    contacts = _contact_names(df.columns)
    if contacts:
        series["contacts"] = contacts
        for field_name, columns in CONTACT_COLUMNS.items():
            series[field_name] = np.stack([df[[f"contact[{n}][{s}]" for s in columns]].to_numpy() for n in contacts],
                                          axis=1)
        series["contact_held"] = series["contact_held"][..., 0] > 0.5
    return TimeSeries(**series, bodies=names, F_W=vec(joints, "{n}_F{s}"), M_W=vec(joints, "{n}_M{s}"),
                      p_W=vec(names, "{n}_{s}"), v_W=vec(names, "{n}_v{s}"), R_WB=R.reshape(len(df), len(names), 3, 3),
                      a_W=vec(names, "{n}_a{s}"), omega_W=vec(names, "{n}_w{s}"), omegadot_W=vec(names, "{n}_wd{s}"))


STRETCH_BREAK = 1.5  # a conditioned log is on a uniform grid within each stretch: a step over 1.5 of its median
# step is a gap or the split between its spans (what a raw log counts as a gap: harness/sources/log/segments.py)


def stretch_starts(t: np.ndarray) -> np.ndarray:
    """The rows of a conditioned series (times t, uniform within each stretch) where a stretch
    begins after a gap, the first row left out."""
    dt = np.diff(t)
    return np.flatnonzero(dt > STRETCH_BREAK * np.median(dt)) + 1


def room(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Seconds from each row of a conditioned series back to the start of its stretch and on to its
    end: how far a computation that reads around a row may reach without crossing a gap or an end."""
    cuts = stretch_starts(t)
    first = t[np.r_[0, cuts]]
    stretch = np.searchsorted(first, t, side="right") - 1
    return t - first[stretch], t[np.r_[cuts - 1, len(t) - 1]][stretch] - t
