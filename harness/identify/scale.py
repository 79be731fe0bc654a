"""Torque constants from motor currents: each joint's factor between the torque its currents give
with the nominal constant and the torque it carries.

A log of currents read with nominal constants gives tau_nom = i k_nom N; the joint carries
f_j tau_nom,j, with f_j unknown. With g_j = 1 / f_j, the torques as read are, up to their noise,

    tau_nom,1 = g o (W_1 beta)                    (the log)
    tau_nom,2 = g o (W_2 beta + W_b,2 theta_p)     (a log of the robot carrying a known payload)

(o: each joint's rows times its g_j; W_b,2 theta_p the torques the payload's ten known parameters
add, on the columns of the body carrying it). The noise of the currents is on the left, where least
squares expects it: (beta, g) minimise the residual by Gauss-Newton, from the linear solution of
W beta - f o tau_nom = known (whose noisy tau_nom columns bias f towards zero by the noise's share of
the torque that W beta cannot explain; docs/identification.md gives the figure). The payload's
known torques fix the scale. Without them the log alone fixes (beta, g) only up to one common scale,
which the median ratio of the model's own base parameters to beta fixes (over those the model gives
a size), and said so: the factors are then as right as the model's parameters are on the median,
which no log of currents alone can check. Columns are scaled to unit norm (harness/base/numerics.py).

Each factor has a 95 % interval from a wild cluster bootstrap: each log cut into BLOCKS contiguous
blocks, the residual of each block flipped in sign at random (the motion kept: the intervals are for
this log's motion and new noise) and the fit linearised at its solution moved by it, the common scale
recomputed on each draw. The residuals of filtered data are correlated over a filter's memory, which
an interval from their variance alone would take for independent samples; a block holds them together.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from itertools import pairwise

import numpy as np

from harness.base.numerics import column_scale, finite_or_null, relative_residual
from harness.base.series import TimeSeries

SIZED = 1e-3  # of the largest: a model's base parameter below it gives no scale
BLOCKS = 40  # contiguous blocks of each log for the intervals (each far longer than a filter's memory)
RESAMPLES = 1000  # wild-bootstrap draws
LEVEL = 0.95
ITERATIONS = 30  # Gauss-Newton's at most; it stops when a step moves no parameter by more than TOLERANCE
TOLERANCE = 1e-12  # relative


@dataclass(frozen=True)
class TorqueScales:
    factor: np.ndarray  # (n,) the carried torque over the torque the nominal constant gives, per joint
    std: np.ndarray  # (n,) its standard deviation over the bootstrap draws
    ci95: np.ndarray  # (n, 2) its 95 % interval (the draws' 2.5 and 97.5 percentiles)
    fixed_by: str  # "payload" or "model"
    relative_residual: float  # ||tau_nom - g o (W beta + known)|| / ||tau_nom||
    scale: float  # the common scale the model's own parameters give (1 where a payload fixes it)
    scale_std: float  # its relative standard deviation over the draws (0 with a payload)
    resamples: int
    blocks: int


def _per_joint(tau: np.ndarray) -> np.ndarray:
    """(N n, n): row (k, j) holds tau[k, j] in column j."""
    N, n = tau.shape
    D = np.zeros((N * n, n))
    D[np.arange(N * n), np.tile(np.arange(n), N)] = tau.ravel()
    return D


def _model_scale(beta: np.ndarray, beta_model: np.ndarray) -> np.ndarray:
    """(...,) the median ratio of the model's base parameters to beta (..., r), over those the model
    gives a size (a friction term the model leaves at zero says nothing of the scale)."""
    sized = np.abs(beta_model) > SIZED * np.max(np.abs(beta_model))
    ratio = np.where(beta[..., sized] != 0, beta_model[sized] / np.where(beta[..., sized] != 0, beta[..., sized], 1.0),
                     np.nan)
    return np.nanmedian(ratio, axis=-1)


def _linear_start(W: np.ndarray, tau: np.ndarray, known: np.ndarray, n: int, homogeneous: bool) -> np.ndarray:
    """(beta, f) of W beta - f o tau = -known by linear least squares (its smallest right singular
    vector where nothing is known), column-scaled."""
    A = np.hstack([W, -_per_joint(tau.reshape(-1, n))])
    col = column_scale(A)
    if homogeneous:
        return np.linalg.svd(A / col, full_matrices=False)[2][-1] / col
    return np.linalg.lstsq(A / col, -known, rcond=None)[0] / col


def _jacobian(W: np.ndarray, y: np.ndarray, g: np.ndarray, n: int) -> np.ndarray:
    """d(g o y) / d(beta, g) at y = W beta + known: (N n, r + n)."""
    rows_g = np.tile(g, len(y) // n)
    return np.hstack([rows_g[:, None] * W, _per_joint(y.reshape(-1, n))])


def _gauss_newton(W: np.ndarray, tau: np.ndarray, known: np.ndarray, beta: np.ndarray, g: np.ndarray,
                  n: int) -> tuple[np.ndarray, np.ndarray]:
    """(beta, g) minimising ||g o (W beta + known) - tau|| (minimum-norm steps: without a known torque
    the common scale is free, and fixed afterwards)."""
    for _ in range(ITERATIONS):
        y = W @ beta + known
        J = _jacobian(W, y, g, n)
        col = column_scale(J)
        step = np.linalg.lstsq(J / col, tau - np.tile(g, len(y) // n) * y, rcond=None)[0] / col
        beta, g = beta + step[: len(beta)], g + step[len(beta):]
        if np.max(np.abs(step) / np.maximum(np.abs(np.concatenate([beta, g])), 1e-300)) <= TOLERANCE:
            break
    return beta, g


def _block_scores(J: np.ndarray, residual: np.ndarray, n: int, blocks: int) -> np.ndarray:
    """(blocks, p): J_b^T rho_b of each contiguous block of samples (n rows a sample)."""
    samples = len(J) // n
    edges = np.linspace(0, samples, min(blocks, samples) + 1).astype(int) * n
    return np.stack([J[a:e].T @ residual[a:e] for a, e in pairwise(edges)])


def _interval(draws: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    tail = 100 * (1 - LEVEL) / 2
    return draws.std(axis=0, ddof=1), np.percentile(draws, [tail, 100 - tail], axis=0).T


def torque_scales(W1: np.ndarray, tau1: np.ndarray, beta_model: np.ndarray, W2: np.ndarray | None = None,
                  tau2: np.ndarray | None = None, known2: np.ndarray | None = None,
                  resamples: int = RESAMPLES, blocks: int = BLOCKS, seed: int = 0) -> TorqueScales:
    """W1 (N1 n, r) the base regressor of the log and tau1 (N1, n) its torques at the nominal constants;
    with a payload log, W2, tau2 and known2 (N2, n), the torques the payload adds."""
    r, n = W1.shape[1], tau1.shape[1]
    logs = [(W1, tau1.ravel(), np.zeros(len(W1)))]
    if W2 is not None:
        logs.append((W2, tau2.ravel(), known2.ravel()))
    W, tau, known = (np.concatenate([log[k] for log in logs]) for k in range(3))
    x0 = _linear_start(W, tau, known, n, homogeneous=W2 is None)
    if W2 is None:
        x0 = x0 * _model_scale(x0[:r], beta_model)
    beta, g = _gauss_newton(W, tau, known, x0[:r], 1.0 / x0[r:], n)
    y = W @ beta + known
    residual = np.tile(g, len(y) // n) * y - tau
    J = _jacobian(W, y, g, n)
    col = column_scale(J)
    # the draws: x* = x - (J^T J)^+ sum_b s_b J_b^T rho_b, s_b = +-1 (minimum norm: the scale's direction
    # is free without a payload, and fixed on each draw as on the estimate)
    scores, start = [], 0
    for W_k, *_ in logs:
        rows = slice(start, start + len(W_k))
        scores.append(_block_scores(J[rows] / col, residual[rows], n, blocks))
        start += len(W_k)
    U = np.concatenate(scores)
    signs = np.random.default_rng(seed).choice([-1.0, 1.0], size=(resamples, len(U)))
    x = np.concatenate([beta, g])
    draws = x - (signs @ U) @ np.linalg.pinv((J / col).T @ (J / col)).T / col
    if W2 is None:
        alpha = _model_scale(draws[:, :r], beta_model)
        f, a0 = alpha[:, None] / draws[:, r:], float(_model_scale(beta, beta_model))
        factor, scale, scale_std = a0 / g, a0, float(np.std(alpha / a0, ddof=1))
    else:
        f, factor, scale, scale_std = 1.0 / draws[:, r:], 1.0 / g, 1.0, 0.0
    std, ci = _interval(f)
    return TorqueScales(factor, std, ci, "model" if W2 is None else "payload", relative_residual(residual, tau),
                        scale, scale_std, resamples, len(U))


def payload_parameters(mass: float, com_W: np.ndarray, inertia_c: np.ndarray, p_J: np.ndarray) -> np.ndarray:
    """(10,) a load's parameters in the joint frame of the body carrying it (at the joint point p_J,
    world axes at q = 0): m, m d, the inertia about p_J (harness/model/inertia.py's layout), from its
    mass, centre of mass and inertia about it [Ixx, Iyy, Izz, Ixy, Ixz, Iyz] in the world frame at q = 0."""
    from harness.model.inertia import parallel_axis

    xx, yy, zz, xy, xz, yz = inertia_c
    d = np.asarray(com_W, dtype=float) - np.asarray(p_J, dtype=float)
    I = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]]) + parallel_axis(mass, d)
    return np.array([mass, *(mass * d), I[0, 0], I[0, 1], I[1, 1], I[0, 2], I[1, 2], I[2, 2]])


def torque_constants(pm, base, W: np.ndarray, tau: np.ndarray, beta_model: np.ndarray, robot, payload=None,
                     loaded: TimeSeries | None = None, rows=None, channels: list[str] | None = None) -> TorqueScales:
    """Each joint's factor on its nominal torque constant, from the training span's regressor W (N n,
    14 n: harness/identify/torque_id.py, with friction) and torques tau (N, n) at the nominal
    constants: fixed by `loaded`, a log of the robot carrying `payload` (the scenario's
    `[data.payload]`, a harness.sources.log.KnownPayload, conditioned as the log), where given; else
    by the model's own base parameters `beta_model` (`base` the structural base parameters). Each torque
    channel's (the joints `channels`: every joint, a closed chain's actuated ones or an open tree's
    measured ones): `rows(q, q', q'')` their regressor as the log reads them (harness/stages/
    log_model.py), tau and the loaded log's torques theirs (the payload's known torque read alike)."""
    from harness.identify.torque_id import regressor

    if payload is None:
        return torque_scales(W[:, base.independent], tau, beta_model)
    joints = robot.joint_names
    q2, qd2, qdd2, tau2 = loaded.joint_data(joints)
    if rows is None:
        W2 = regressor(pm, q2, qd2, qdd2, with_friction=True)
    else:
        W2, tau2 = rows(q2, qd2, qdd2), tau2[:, [joints.index(a) for a in channels or joints]]
    k = joints.index(robot.inner_joint(payload.body).name)
    theta_p = payload_parameters(payload.mass, payload.com_W, payload.inertia, robot.joints[k].p_W0)
    known = (W2[:, 10 * k: 10 * k + 10] @ theta_p).reshape(tau2.shape)
    return torque_scales(W[:, base.independent], tau, beta_model, W2[:, base.independent], tau2, known)


def scaled(series: TimeSeries, factor: np.ndarray, joints) -> TimeSeries:
    """The series with each joint's torque times its factor (joints in `joints`' order)."""
    cols = [series.joint_index(j) for j in joints]
    tau = series.tau.copy()
    tau[:, cols] *= factor
    return dataclasses.replace(series, tau=tau)


def constants_table(joints: list[str], nominal, factor: np.ndarray, std: np.ndarray, interval: np.ndarray) -> dict:
    """results.json's per-joint torque constants (an arm's and a floating base's alike): each joint's nominal
    constant, its factor and std, the identified constant (factor x nominal) and its 95 % interval from the factor's
    (`interval` (m, 2)) times the nominal, written low to high (a constant may be signed)."""
    return {j: {"nominal": k, "factor": float(f), "identified": float(f * k), "factor_std": finite_or_null(float(sd)),
                "ci95": [finite_or_null(v) for v in sorted(float(x * k) for x in ci)]}
            for j, k, f, sd, ci in zip(joints, nominal, factor, std, interval, strict=True)}
