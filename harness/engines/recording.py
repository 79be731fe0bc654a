"""Recording: what the test bench measured, one row per output step (paper section 3.1).

SI units; world components (frame W) unless a name says otherwise. Per joint J (robot order): q,
q', q'' and the drive force or torque along the joint axis, and the wrench the inner body applies
to the outer body across J: force F_W and moment M_W about the joint point O_J. Per massive body
B: its pose (orientation R_WB, the body's principal axes as columns in world components, and
centre of mass p_W), its twist (centre-of-mass velocity v_W, angular velocity omega_W) and their
rates (centre-of-mass acceleration a_W, angular acceleration omegadot_W). A study derives what
else it reads from these: orientation angles, the accelerations of other points.

CSV columns (`to_frame`): t; q_J qd_J qdd_J tau_J; B_x B_y B_z; B_vx B_vy B_vz;
B_R11 B_R12 B_R13 B_R21 ... B_R33 (R_WB row by row); B_ax B_ay B_az; B_wx B_wy B_wz;
B_wdx B_wdy B_wdz; J_Fx J_Fy J_Fz; J_Mx J_My J_Mz. Floats are written with 17 significant digits, so a
recording read back from CSV is bit-for-bit the one written.
"""

from __future__ import annotations

import io
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from harness.base.tomlio import MAX_DATA_BYTES, InputError, read_bounded

if TYPE_CHECKING:  # imported where a CSV is read or written
    import pandas as pd

XYZ = ("x", "y", "z")
ROTATION = tuple(f"R{i}{j}" for i in (1, 2, 3) for j in (1, 2, 3))  # R_WB row by row


@dataclass(frozen=True, eq=False)
class Recording:
    t: np.ndarray  # (n,)
    joints: tuple[str, ...]
    bodies: tuple[str, ...]
    q: np.ndarray  # (n, nj)
    qd: np.ndarray
    qdd: np.ndarray
    tau: np.ndarray  # (n, nj) drive force (prismatic) or torque (revolute) along the axis
    F_W: np.ndarray  # (n, nj, 3) force of the inner body on the outer body at O_J
    M_W: np.ndarray  # (n, nj, 3) moment of the inner body on the outer body about O_J
    p_W: np.ndarray  # (n, nb, 3) centre of mass
    v_W: np.ndarray  # (n, nb, 3) centre-of-mass velocity
    R_WB: np.ndarray  # (n, nb, 3, 3) orientation: the body's axes in world components
    a_W: np.ndarray  # (n, nb, 3) centre-of-mass acceleration
    omega_W: np.ndarray  # (n, nb, 3)
    omegadot_W: np.ndarray  # (n, nb, 3)
    meta: dict = field(default_factory=dict)

    def joint_index(self, name: str) -> int:
        return self.joints.index(name)

    def body_index(self, name: str) -> int:
        return self.bodies.index(name)

    def columns(self) -> dict[str, np.ndarray]:
        """The CSV's columns in order, {name: (N,) values}."""
        cols: dict[str, np.ndarray] = {"t": self.t}
        for j, name in enumerate(self.joints):
            cols[f"q_{name}"] = self.q[:, j]
            cols[f"qd_{name}"] = self.qd[:, j]
            cols[f"qdd_{name}"] = self.qdd[:, j]
            cols[f"tau_{name}"] = self.tau[:, j]
        R = self.R_WB.reshape(len(self.t), len(self.bodies), 9)
        for b, name in enumerate(self.bodies):
            for groups in ((self.p_W, XYZ, ""), (self.v_W, XYZ, "v"), (R, ROTATION, ""),
                           (self.a_W, XYZ, "a"), (self.omega_W, XYZ, "w"), (self.omegadot_W, XYZ, "wd")):
                arr, suffixes, prefix = groups
                for k, s in enumerate(suffixes):
                    cols[f"{name}_{prefix}{s}"] = arr[:, b, k]
        for j, name in enumerate(self.joints):
            for k, s in enumerate(XYZ):
                cols[f"{name}_F{s}"] = self.F_W[:, j, k]
            for k, s in enumerate(XYZ):
                cols[f"{name}_M{s}"] = self.M_W[:, j, k]
        return cols

    def to_frame(self) -> pd.DataFrame:
        import pandas as pd

        return pd.DataFrame(self.columns())

    def write_csv(self, path: Path) -> None:
        """Every value to 17 significant digits (a double read back is the same double). Written with
        numpy's printf formatting, as pandas' float_format="%.17g" writes it, without importing pandas."""
        cols = self.columns()
        fmt = ["%d" if v.dtype.kind in "iub" else "%.17g" for v in cols.values()]
        data = np.column_stack(list(cols.values())).astype(float)  # '%d' % 1.0 is '1'
        with open(path, "w", newline="") as f:
            f.write(",".join(cols) + "\n")
            np.savetxt(f, data, fmt=fmt, delimiter=",")


def read_csv(path: Path | str) -> Recording:
    """Read a recording back from CSV: joints from the q_ columns, bodies from the _R11 ones.
    A missing column, an empty or unparsable cell (a truncated file) is an InputError."""
    import pandas as pd

    try:
        df = pd.read_csv(io.BytesIO(read_bounded(path, MAX_DATA_BYTES)))
    except (ValueError, pd.errors.ParserError) as exc:
        raise InputError(path, "", f"cannot read the recording ({str(exc).splitlines()[0]})") from None
    bad = [c for c in df.columns if not pd.api.types.is_numeric_dtype(df[c]) or df[c].isna().any()]
    if bad or "t" not in df.columns:
        raise InputError(path, bad[0] if bad else "t", "missing, empty or not a number in some row "
                                                         "(a truncated or edited recording)")
    joints = tuple(c[2:] for c in df.columns if c.startswith("q_"))
    bodies = tuple(c[: -len("_R11")] for c in df.columns if c.endswith("_R11"))
    if not joints or not bodies:
        raise InputError(path, "q_<joint>" if not joints else "<body>_R11",
                         "column missing: a recording.csv holds every joint's q_ and every body's orientation "
                         "R11 .. R33 (a file of another layout, or of an earlier version, cannot be read)")

    def per_joint(prefix: str) -> np.ndarray:
        return df[[f"{prefix}_{j}" for j in joints]].to_numpy()

    def vec(names: tuple[str, ...], fmt: str) -> np.ndarray:
        return np.stack([df[[fmt.format(n=n, s=s) for s in XYZ]].to_numpy() for n in names], axis=1)

    def rotations() -> np.ndarray:
        R = np.stack([df[[f"{b}_{r}" for r in ROTATION]].to_numpy() for b in bodies], axis=1)
        return R.reshape(len(df), len(bodies), 3, 3)

    expected = ["t", *(f"{k}_{j}" for j in joints for k in ("q", "qd", "qdd", "tau")),
                *(f"{j}_{k}{a}" for j in joints for k in ("F", "M") for a in XYZ),
                *(f"{b}_{k}{a}" for b in bodies for k in ("", "v", "a", "w", "wd") for a in XYZ),
                *(f"{b}_{r}" for b in bodies for r in ROTATION)]
    missing = [c for c in expected if c not in df.columns]
    if missing:
        raise InputError(path, missing[0], "column missing: not a complete recording.csv")
    return Recording(
        t=df["t"].to_numpy(), joints=joints, bodies=bodies,
        q=per_joint("q"), qd=per_joint("qd"), qdd=per_joint("qdd"), tau=per_joint("tau"),
        F_W=vec(joints, "{n}_F{s}"), M_W=vec(joints, "{n}_M{s}"),
        p_W=vec(bodies, "{n}_{s}"), v_W=vec(bodies, "{n}_v{s}"), R_WB=rotations(), a_W=vec(bodies, "{n}_a{s}"),
        omega_W=vec(bodies, "{n}_w{s}"), omegadot_W=vec(bodies, "{n}_wd{s}"),
    )
