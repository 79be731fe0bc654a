"""The identification form generalised to all 10 inertial parameters of each body.

The paper's form (section 2.3, Eq. 49) writes each body's Newton-Euler equations at its centre of
mass, in its principal axes, with m and J11, J22, J33 unknown: it presumes the centre of mass
and the principal axes known. Here they are unknown too. Each body's equations are written at a
stated point O (the body's inner joint point, where an accelerometer sits) and in the body's
joint frame J (world-aligned at the initial pose, turning with the body), with the parameters
x = (m, m c, I_O) = (m, mcx, mcy, mcz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz), c the centre of mass from O
and I_O the inertia tensor about O, both in J:

    f   = m (a_O - g) + (w'~ + w~ w~) (m c)
    n_O = (m c) x (a_O - g) + I_O w' + w x (I_O w)

with f the resultant joint force on the body and n_O the resultant joint moment about O
(Eqs. 17, 20 with the joint points measured from O), all in J. The paper's form is the special
case c = 0 with J the principal axes. These are the parameters of Pinocchio's joint frames, so
Pinocchio's dynamic parameters are the true values.
"""

from __future__ import annotations

import numpy as np

from harness.base.series import TimeSeries
from harness.model.kinematics import cross, skew
from harness.model.spec import RobotSpec
from harness.papers.graph_theory_2021.cardano import A_0i
from harness.papers.graph_theory_2021.dynamics import GraphModel

FULL_PARAMETERS = ("m", "mcx", "mcy", "mcz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")
GROUPS = ((0,), (1, 2, 3), (4, 5, 6, 7, 8, 9))


def _L(v: np.ndarray) -> np.ndarray:
    """I v = L(v) (Ixx, Ixy, Iyy, Ixz, Iyz, Izz): (..., 3) -> (..., 3, 6)."""
    x, y, z = np.moveaxis(v, -1, 0)
    o = np.zeros_like(x)
    return np.stack([np.stack([x, y, o, z, o, o], -1), np.stack([o, x, y, o, z, o], -1),
                     np.stack([o, o, o, x, y, z], -1)], -2)


def full_form(spec: RobotSpec, model: GraphModel, rec: TimeSeries, rows: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray]:
    """Y (N, n, 6, 10) and Z (N, n, 6) with Y x = Z for every body and sample."""
    top = model.topology
    b = [rec.body_index(x) for x in top.bodies]
    j = [rec.joint_index(x) for x in top.joints]
    A = A_0i(rec.theta[rows][:, b])  # (N, n, 3, 3) principal frames
    R0 = np.stack([spec.body(x).R_WB0 for x in top.bodies])  # (n, 3, 3)
    R_J = A @ np.swapaxes(R0, -1, -2)[None]  # joint frames in the world
    to_J = lambda v: np.einsum("niba,nib->nia", R_J, v)  # noqa: E731  world -> J components
    F, M = rec.F_W[rows][:, j], rec.M_W[rows][:, j]
    q = rec.q[rows][:, j]
    # joint points relative to each body's own inner joint point O, in the world
    own = top.c_B[np.arange(top.n), np.arange(top.n)]  # O_i from the centre of mass, body components
    rel_B = top.c_B + top.slide_B * q[:, None, :, None] - own[None, :, None, :]  # (N, n, n, 3)
    rel_W = np.einsum("nilm,nikm->nikl", A, rel_B)
    f = -np.einsum("ik,nkl->nil", top.S.astype(float), F)
    n_O = -(np.einsum("ik,nkl->nil", top.S.astype(float), M)
            + np.einsum("ik,nikl->nil", top.S.astype(float), cross(rel_W, F[:, None])))
    a, w, wd = to_J(rec.aO_W[rows][:, b] - model.g_W), to_J(rec.omega_W[rows][:, b]), to_J(rec.omegadot_W[rows][:, b])
    N, n = a.shape[:2]
    Y = np.zeros((N, n, 6, 10))
    Y[..., :3, 0] = a
    Y[..., :3, 1:4] = skew(wd) + skew(w) @ skew(w)
    Y[..., 3:, 1:4] = -skew(a)
    Y[..., 3:, 4:] = _L(wd) + skew(w) @ _L(w)
    return Y, np.concatenate([to_J(f), to_J(n_O)], axis=-1)
