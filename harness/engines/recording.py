"""Recording: what the test bench measured, one row per output step (paper section 3.1).

SI units; world components (frame W = e(0)) unless a name says otherwise. Per joint J (robot
order): q, q', q'' and the drive force or torque along the joint axis, and the wrench the inner
body applies to the outer body across J: force F_W and moment M_W about the joint point O_J.
Per massive body B: centre of mass p_W and its velocity v_W, orientation R_WB with its Cardano
angles theta (see harness.model.cardano), centre-of-mass acceleration a_W, angular velocity omega_W and angular
acceleration omegadot_W.

CSV columns (`to_frame`): t; q_J qd_J qdd_J tau_J; B_x B_y B_z; B_vx B_vy B_vz; B_alpha B_beta B_gamma;
B_ax B_ay B_az; B_aOx B_aOy B_aOz (the inner joint point); B_wx B_wy B_wz; B_wdx B_wdy B_wdz;
B_gimbal (1 where cond(D) > GIMBAL_COND_D);
J_Fx J_Fy J_Fz; J_Mx J_My J_Mz. Floats are written with 17 significant digits, so a recording
read back from CSV is bit-for-bit the one written.
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
ANGLES = ("alpha", "beta", "gamma")


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
    theta: np.ndarray  # (n, nb, 3) Cardano angles (alpha, beta, gamma)
    a_W: np.ndarray  # (n, nb, 3) centre-of-mass acceleration
    aO_W: np.ndarray  # (n, nb, 3) acceleration of the body's inner joint point (a sensor at a known point)
    omega_W: np.ndarray  # (n, nb, 3)
    omegadot_W: np.ndarray  # (n, nb, 3)
    gimbal: np.ndarray  # (n, nb) bool: near Cardano gimbal lock
    R_WB: np.ndarray | None = None  # (n, nb, 3, 3) as the engine reported it, when available
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
        for b, name in enumerate(self.bodies):
            for groups in ((self.p_W, XYZ, ""), (self.v_W, XYZ, "v"), (self.theta, ANGLES, ""),
                           (self.a_W, XYZ, "a"), (self.aO_W, XYZ, "aO"),
                           (self.omega_W, XYZ, "w"), (self.omegadot_W, XYZ, "wd")):
                arr, suffixes, prefix = groups
                for k, s in enumerate(suffixes):
                    cols[f"{name}_{prefix}{s}"] = arr[:, b, k]
            cols[f"{name}_gimbal"] = self.gimbal[:, b].astype(int)
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
    """Read a recording back from CSV: joints from the q_ columns, bodies from the _alpha ones.
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
    bodies = tuple(c[: -len("_alpha")] for c in df.columns if c.endswith("_alpha"))

    def per_joint(prefix: str) -> np.ndarray:
        return df[[f"{prefix}_{j}" for j in joints]].to_numpy()

    def vec(names: tuple[str, ...], fmt: str) -> np.ndarray:
        return np.stack([df[[fmt.format(n=n, s=s) for s in XYZ]].to_numpy() for n in names], axis=1)

    def angles() -> np.ndarray:
        return np.stack([df[[f"{b}_{a}" for a in ANGLES]].to_numpy() for b in bodies], axis=1)

    expected = ["t", *(f"{k}_{j}" for j in joints for k in ("q", "qd", "qdd", "tau")),
                *(f"{j}_{k}{a}" for j in joints for k in ("F", "M") for a in XYZ),
                *(f"{b}_{k}{a}" for b in bodies for k in ("", "v", "a", "aO", "w", "wd") for a in XYZ),
                *(f"{b}_{a}" for b in bodies for a in (*ANGLES, "gimbal"))]
    missing = [c for c in expected if c not in df.columns]
    if missing:
        raise InputError(path, missing[0], "column missing: not a complete recording.csv")
    return Recording(
        t=df["t"].to_numpy(), joints=joints, bodies=bodies,
        q=per_joint("q"), qd=per_joint("qd"), qdd=per_joint("qdd"), tau=per_joint("tau"),
        F_W=vec(joints, "{n}_F{s}"), M_W=vec(joints, "{n}_M{s}"),
        p_W=vec(bodies, "{n}_{s}"), v_W=vec(bodies, "{n}_v{s}"), theta=angles(), a_W=vec(bodies, "{n}_a{s}"),
        aO_W=vec(bodies, "{n}_aO{s}"),
        omega_W=vec(bodies, "{n}_w{s}"), omegadot_W=vec(bodies, "{n}_wd{s}"),
        gimbal=df[[f"{b}_gimbal" for b in bodies]].to_numpy().astype(bool),
    )
