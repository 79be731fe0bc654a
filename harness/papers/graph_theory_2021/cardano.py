"""Cardano angles of the paper (section 2.2): x-y-z sequence, A(0i) = Rx(alpha) Ry(beta) Rz(gamma).

theta = (alpha, beta, gamma); A(0i) maps body components to world components (its columns are
e1(i), e2(i), e3(i) in e(0)). The body-frame angular velocity is omega_B = D theta' (Eq. 33).

Gimbal lock: where cos(beta) = 0 only alpha + gamma (sin beta = +1) or gamma - alpha
(sin beta = -1) is determined, and D is singular. `angles_from_rotation` returns angles that are
continuous along a time series; at a locked row it keeps alpha equal to its value at the nearest
unlocked row (the previous one, or the next one for leading rows) and gives gamma from the
determined combination, which is the limit of the continuous solution when the body passes
through the lock at finite rate. Beta is not confined to [-pi/2, pi/2]: a body spinning about
the vertical (B1 of kr500) passes through cos(beta) = 0 with beta growing through pi/2, and the
branch (alpha + pi, pi - beta, gamma + pi) that keeps the series continuous is chosen.
"""

from __future__ import annotations

import math

import numpy as np

# Eq. (29) A(0i) = Rx(alpha) Ry(beta) Rz(gamma) (A_0i, and component-major A_0i_components), Eq. (33)
# omega^(i) = D theta' and Eq. (34) D' (whose printed last entry 1 is the derivative of the constant
# D[2, 2] = 1: 0 here), written once in the core, where a ball joint's coordinates are these angles
from harness.model.cardano import rate_matrix as D
from harness.model.cardano import rate_matrix_dot as D_dot  # noqa: F401  (this module's name for it)
from harness.model.cardano import rotation as A_0i  # noqa: F401  (this module's name for it)
from harness.model.cardano import rotation_components as A_0i_components  # noqa: F401  (this module's name for it)

LOCK_COS_BETA = 1e-10  # |cos beta| below which alpha and gamma are not separable at all
GIMBAL_COND_D = 100.0  # rows with cond(D) above this are flagged as near gimbal lock


def D_from_rotations(theta: np.ndarray) -> np.ndarray:
    """D of Eq. (33) computed independently, with a rotation library (Pinocchio's exponential map
    exp3, not Eq. 29's closed form): for A = Rx(alpha) Ry(beta) Rz(gamma), A^T A' = (omega^(i))~
    gives omega^(i) = alpha' (Ry Rz)^T e_x + beta' Rz^T e_y + gamma' e_z, so the columns of D are
    those three vectors. (..., 3) -> (..., 3, 3). One call per orientation (Pinocchio's exp3 takes
    one rotation vector); scipy.spatial, batched, took 0.25 to 0.6 s to import, more than the check."""
    import pinocchio as pin

    theta = np.asarray(theta, dtype=float)
    flat = theta.reshape(-1, 3)
    e_y, e_z = np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0])
    out = np.empty((len(flat), 3, 3))
    for k, (_, beta, gamma) in enumerate(flat):
        Rz = pin.exp3(gamma * e_z)
        Ry_Rz = pin.exp3(beta * e_y) @ Rz
        out[k] = np.column_stack([Ry_Rz[0], Rz[1], e_z])  # rows of R are the columns of R^T
    return out.reshape(theta.shape[:-1] + (3, 3))


def cond_D(theta: np.ndarray) -> np.ndarray:
    """2-norm condition number of D along a series, inf where D is singular."""
    s = np.linalg.svd(D(theta), compute_uv=False)
    with np.errstate(divide="ignore"):
        return np.where(s[..., -1] > 0.0, s[..., 0] / s[..., -1], np.inf)


def angles_from_rotation(R: np.ndarray, reference: np.ndarray | None = None) -> np.ndarray:
    """Continuous Cardano angles of a time series of rotation matrices, (n, 3, 3) -> (n, 3).

    `reference`: angles the first row is to be continuous with (the row before the series)."""
    R = np.asarray(R, dtype=float)
    sb = np.clip(R[:, 0, 2], -1.0, 1.0)
    cb = np.hypot(R[:, 0, 0], R[:, 0, 1])
    beta = np.arctan2(sb, cb)
    alpha = np.arctan2(-R[:, 1, 2], R[:, 2, 2])
    gamma = np.arctan2(-R[:, 0, 1], R[:, 0, 0])
    locked = cb < LOCK_COS_BETA
    # In lock: sin beta = +1 fixes alpha + gamma = atan2(R10, R11); -1 fixes gamma - alpha.
    combo = np.arctan2(R[:, 1, 0], R[:, 1, 1])

    # The branch at each row depends on the row before (its 2 pi turns and branch), so the rows are
    # walked in order; the walk is on Python floats (a row's three angles), the arithmetic the same
    # as numpy's on the same doubles: round() is numpy's round half to even, and the squared
    # distance is summed in the same order.
    alpha_k, beta_k, gamma_k, combo_k = alpha.tolist(), beta.tolist(), gamma.tolist(), combo.tolist()
    up_k, locked_k = (sb > 0).tolist(), locked.tolist()
    free = np.flatnonzero(~locked)
    prev = None if reference is None else tuple(float(x) for x in np.asarray(reference, dtype=float))
    turn = 2.0 * np.pi
    out = []
    for k in range(len(R)):
        if locked_k[k]:
            if prev is not None:
                a = prev[0]
            elif len(free):
                a = alpha_k[free[0]]  # leading locked rows: the limit from the first free row
            else:
                a = 0.0
            g = combo_k[k] - a if up_k[k] else combo_k[k] + a
            candidates = [(a, beta_k[k], g)]
        else:
            a, b, g = alpha_k[k], beta_k[k], gamma_k[k]
            candidates = [(a, b, g), (a + np.pi, b + (np.pi - 2.0 * b), g + np.pi)]
        if prev is None and not locked_k[k]:
            best = candidates[0]
        else:
            ref = prev if prev is not None else candidates[0]
            best, closest = None, None
            for c in candidates:  # the first of the nearest, each shifted by whole turns towards ref
                c = tuple(ci + turn * _rint((ri - ci) / turn) for ci, ri in zip(c, ref, strict=True))
                d = [ci - ri for ci, ri in zip(c, ref, strict=True)]
                distance = d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
                if closest is None or distance < closest:
                    best, closest = c, distance
        out.append(best)
        prev = best
    return np.array(out, dtype=float).reshape(len(R), 3)


def _rint(x: float) -> float:
    """numpy's round half to even of one float, NaN and infinities kept (round() raises on them)."""
    return round(x) if math.isfinite(x) else x


def body_angles(R_WB: np.ndarray) -> np.ndarray:
    """Continuous Cardano angles of every body along a run, (n, nb, 3, 3) -> (n, nb, 3)."""
    return np.stack([angles_from_rotation(R_WB[:, b]) for b in range(R_WB.shape[1])], axis=1)


def gimbal_flags(theta: np.ndarray) -> np.ndarray:
    """Rows near gimbal lock along a series, (n, ..., 3) -> (n, ...) bool.

    A row is flagged where cond(D) > GIMBAL_COND_D (angle rates derived from omega lose more than
    two digits there), or where cos(beta) changes sign between it and a neighbouring row (the body
    passed through the lock between the two samples).
    """
    cb = np.cos(np.asarray(theta)[..., 1])
    flags = cond_D(theta) > GIMBAL_COND_D
    crossed = np.signbit(cb[1:]) != np.signbit(cb[:-1])
    flags[1:] |= crossed
    flags[:-1] |= crossed
    return flags
