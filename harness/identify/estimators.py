"""Estimators of the base parameters from joint torques, tau = W_1 beta + e, with rows sample by
sample (n joints a sample), each returning the estimate with its standard deviation.

- `ols`: ordinary least squares.
- `wls`: weighted least squares, each joint's rows weighted by the inverse of its residual
  variance from a first, ordinary fit (Gautier and Poignet's per-joint weighting: a wrist's torque
  is read far more finely than a shoulder's).
- `irls`: iteratively reweighted least squares with Huber's weights (c = 1.345 robust standard
  deviations, the scale per joint from the median absolute residual): an outlier of the torque
  sensor gets the weight its residual deserves instead of pulling the fit.
- `iv`: instrumental variables (IDIM-IV, Janot, Vandanjon and Gautier 2014): the instruments are
  the regressor Z_1 of the noise-free motion the robot was asked to follow, simulated (on the bench
  the prescribed reference; on a robot the reference the controller tracked). Z_1 is correlated
  with W_1 but not with the noise of the measured positions, velocities and accelerations that W_1
  is built from, so beta = (Z_1^T W_1)^-1 Z_1^T tau is consistent where least squares with a noisy
  regressor is biased (the errors-in-variables bias that differentiated, filtered accelerations
  cause), as long as a column is linear in the noisy signals: the smooth Coulomb column
  tanh(q'/v_c) is not, and near its sign changes its mean is not tanh of the mean, which biased
  the estimate (measured in the README, "Estimators side by side"). Such columns (`nonlinear`) are
  therefore taken from the instruments themselves, the Coulomb shape of the reference velocity: for
  them the estimator is DIDIM's (the regressor of the simulated motion), for the rest IDIM-IV's.
  On a robot the reference velocity's sign differs from the actual one only for the tracking
  delay at a reversal. Chosen over total least squares, which assumes the same noise in every column (the
  columns of W_1 are products of q', q'' and trigonometric functions of q: their noise differs by
  orders of magnitude), and over DIDIM, which needs the closed-loop controller to simulate.

Every estimator is called as f(W1, tau, n, instruments, lags); the least-squares family reads no
instruments. `lags`: residuals of samples further apart
than `lags` are uncorrelated (a filter of w samples that differentiates the positions: lags = w - 1,
since two of its outputs share no input beyond that; 0: every sample's noise its own).

Standard deviations are robust to that correlation (the joints of one sample share the noise of the
state they are computed from; velocities and accelerations differentiated by a filter share noise
with their neighbours, partly negatively correlated: a differentiator's kernel sums to zero).
- Least-squares family: CR3 cluster-robust (harness/identify/lstsq.py) over clusters of 3 (lags + 1)
  consecutive samples (1 sample where lags = 0), which hold most of the correlated pairs.
- IV: the sandwich (Z^T W)^-1 S (W^T Z)^-1, S the covariance of the scores Z^T e. Where the
  sensors are specified (`Instruments.score_covariance`), S is propagated from their specification
  (harness/identify/propagation.py) and the interval takes the normal quantile. Otherwise S is estimated from
  the residuals by the truncated (Hansen) long-run covariance sum_t sum_{|l| <= lags} g_t g_{t+l}^T
  of the per-sample scores g_t = Z_t^T r_t, times rows / (rows - r), with Student's t on
  samples / (lags + 1) - 1 degrees of freedom: exact for noise correlated over `lags` samples, but
  an encoder's quantisation error on a slow joint stays correlated far longer. Measured on
  ur5_estimators, coverage by base parameter (300 trials): clusters of one sample 100 %; clusters of
  three filter windows (21 clusters for 58 parameters) 76 % to 100 %; truncated 75 % to 96 %;
  propagated from the sensors 91 % to 98 % (1000 trials: 93 % to 97 %, README).
The columns are scaled to unit norm before solving.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from harness.base.numerics import NORMAL_975, SideBySide, column_scale, triangle
from harness.identify.lstsq import Estimate, sandwich_std, t_quantile

HUBER_C = 1.345  # Huber's constant: 95 % efficiency under Gaussian noise
IRLS_ITERATIONS = 20
IRLS_TOL = 1e-6  # relative change of the scaled estimate that ends the iteration (far below its noise)


@dataclass(frozen=True, eq=False)
class Instruments:
    """What the instrumental-variable estimator reads beside the measured regressor."""

    Z1: np.ndarray  # (rows, r): the regressor of the reference motion
    nonlinear: np.ndarray | None = None  # (r,) bool: columns nonlinear in a measured signal, taken from Z1
    score_covariance: np.ndarray | None = None  # (r, r) Cov(Z1^T e) from the sensors (harness/identify/propagation.py)


def _weighted_fit(W1: np.ndarray, tau: np.ndarray, n: int, w: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, ...]:
    sw = np.sqrt(w)
    z, *_ = np.linalg.lstsq(W1 / s * sw[:, None], tau * sw, rcond=None)
    return z, tau - (W1 / s) @ z


def _reweighted(W1s: np.ndarray, tau: np.ndarray, w: np.ndarray) -> np.ndarray | None:
    """The weighted fit of an IRLS iteration from the normal equations G z = W^T w tau,
    G = W^T w W, with one step of iterative refinement: a fraction of an orthogonal factorisation's
    cost. Each step leaves about cond(G) eps of the error before it, so where cond(G) < 1e12 the
    fit is within 1e-8 of z, far inside the iteration's tolerance. None beyond that: the caller
    then factorises W itself."""
    G = W1s.T @ (w[:, None] * W1s)
    eig = np.linalg.eigvalsh(G)
    if not eig[0] > 1e-12 * eig[-1]:
        return None
    z = np.linalg.solve(G, W1s.T @ (w * tau))
    return z + np.linalg.solve(G, W1s.T @ (w * (tau - W1s @ z)))


def clusters(rows: int, n: int, block: int) -> np.ndarray:
    """(rows,) the cluster of each row: `block` consecutive samples of n joints each."""
    return np.arange(rows) // (n * block)


def _finish(W1s: np.ndarray | SideBySide, z: np.ndarray, r: np.ndarray, w: np.ndarray, n: int, s: np.ndarray,
            start: float, lags: int, svd: tuple[np.ndarray, np.ndarray] | None = None,
            scale: np.ndarray | None = None) -> Estimate:
    """The estimate z / s with its CR3 intervals (`sandwich_std`: W1s the scaled regressor, or the
    regressor over `scale`, read a chunk at a time; `svd` its singular values and vectors if known)."""
    std, half = sandwich_std(W1s, r, w, clusters(len(r), n, 3 * (lags + 1) if lags else 1), svd, scale)
    return Estimate(z / s, std / s, half / s, time.perf_counter() - start)


def ols(W1: np.ndarray | SideBySide, tau: np.ndarray, n: int, instruments: Instruments | None = None,
        lags: int = 0) -> Estimate:
    """From the column-scaled regressor's triangle (harness/base/numerics.py, `triangle`: QR of its
    rows a chunk at a time, where numpy's least squares and SVD of the whole copy it several times):
    the solution, with the cut-off numpy's least squares takes for the whole, and the SVD of R, which
    has the regressor's singular values and right singular vectors, for the sandwich, which reads the
    scaled rows a chunk at a time (`sandwich_std`). W1 an array or column blocks never joined
    (SideBySide)."""
    start = time.perf_counter()
    return ols_of(reduced(W1, tau), W1, tau, n, lags, start)


@dataclass(frozen=True, eq=False)
class Reduced:
    """A regressor reduced once (`reduced`): its column scale s, the triangle R and b = Q^T tau of W1 / s
    (harness/base/numerics.py, `triangle`), and R's singular values and right singular vectors (the scaled
    regressor's): what the least squares, its intervals and the sensitivities read."""

    s: np.ndarray
    R: np.ndarray
    b: np.ndarray
    sv: np.ndarray
    Vt: np.ndarray


def reduced(W1: np.ndarray | SideBySide, tau: np.ndarray) -> Reduced:
    s = column_scale(W1)
    R, b, _ = triangle(W1, tau, s)
    _, sv, Vt = np.linalg.svd(R, full_matrices=False)
    return Reduced(s, R, b, sv, Vt)


def ols_of(red: Reduced, W1: np.ndarray | SideBySide, tau: np.ndarray, n: int, lags: int = 0,
           start: float | None = None) -> Estimate:
    """`ols` from its regressor's reduction (`reduced`), made once by a caller that reads it too."""
    start = time.perf_counter() if start is None else start
    z = np.linalg.lstsq(red.R, red.b, rcond=np.finfo(float).eps * max(W1.shape))[0]
    r = tau - W1 @ (z / red.s)
    return _finish(W1, z, r, np.ones(len(tau)), n, red.s, start, lags, (red.sv, red.Vt), red.s)


def row_variance(W1: np.ndarray, tau: np.ndarray, n: int, weights: np.ndarray | None = None) -> np.ndarray:
    """(n,) the residual variance of each of a sample's n rows (a joint's torque, a wrench's component) after an
    ordinary fit (the first pass of `wls`, whose weights are its inverse), or after the fit weighted by
    `weights` (n,), each sample's row i by weights[i]."""
    s = column_scale(W1)
    w = np.ones(len(tau)) if weights is None else np.tile(weights, len(tau) // n)
    _, r0 = _weighted_fit(W1, tau, n, w, s)
    return _per_joint_variance(r0, n, W1.shape[1])


def _per_joint_variance(r: np.ndarray, n: int, dof: int) -> np.ndarray:
    """(n,) residual variance of each joint's rows; a joint fitted to round-off gets the smallest
    positive variance of the others (its rows are the best read, never the worst weighted)."""
    var = np.sum(r.reshape(-1, n) ** 2, axis=0) / max(len(r) // n - dof / n, 1.0)
    positive = var[var > 0]
    floor = positive.min() if len(positive) else 1.0
    return np.where(var > 0, var, floor)


def wls(W1: np.ndarray, tau: np.ndarray, n: int, instruments: Instruments | None = None,
        lags: int = 0) -> Estimate:
    start = time.perf_counter()
    s = column_scale(W1)
    w = np.tile(1.0 / row_variance(W1, tau, n), len(tau) // n)
    w /= w.max()
    z, r = _weighted_fit(W1, tau, n, w, s)
    return _finish(W1 / s, z, r, w, n, s, start, lags)


def irls(W1: np.ndarray, tau: np.ndarray, n: int, instruments: Instruments | None = None,
        lags: int = 0) -> Estimate:
    """The iterations solve the normal equations (_reweighted); the converged weights' fit, the one
    returned, is an orthogonal factorisation's, as in ols and wls."""
    start = time.perf_counter()
    s = column_scale(W1)
    W1s = W1 / s
    w = np.ones(len(tau))
    z, r = _weighted_fit(W1, tau, n, w, s)
    for _ in range(IRLS_ITERATIONS):
        R = r.reshape(-1, n)
        scale = 1.4826 * np.median(np.abs(R - np.median(R, axis=0)), axis=0)  # robust std per joint
        scale = np.where(scale > 0, scale, np.max(scale, initial=0.0) or 1.0)
        u = np.abs(R) / (HUBER_C * scale)
        w = (np.minimum(1.0, 1.0 / np.where(u > 0, u, 1.0)) / scale**2).ravel()
        w /= w.max()
        z_new = _reweighted(W1s, tau, w)
        if z_new is None:
            z_new, r = _weighted_fit(W1, tau, n, w, s)
        else:
            r = tau - W1s @ z_new
        done = np.linalg.norm(z_new - z) <= IRLS_TOL * np.linalg.norm(z_new)
        z = z_new
        if done:
            break
    z, r = _weighted_fit(W1, tau, n, w, s)
    return _finish(W1s, z, r, w, n, s, start, lags)


def iv(W1: np.ndarray, tau: np.ndarray, n: int, instruments: Instruments | None = None,
       lags: int = 0) -> Estimate:
    if instruments is None:
        raise ValueError("the instrumental-variable estimator needs its instruments")
    start = time.perf_counter()
    Z1, nonlinear = instruments.Z1, instruments.nonlinear
    if nonlinear is not None and np.any(nonlinear):
        W1 = np.where(nonlinear, Z1, W1)
    s = column_scale(W1)
    W1s, Z1s = W1 / s, Z1 / s
    A = Z1s.T @ W1s
    z = np.linalg.solve(A, Z1s.T @ tau)
    B = np.linalg.inv(A)
    if instruments.score_covariance is not None:  # from the sensors' specification: known, not estimated
        var = np.einsum("ij,jk,ik->i", B, instruments.score_covariance / np.outer(s, s), B)
        std = np.sqrt(np.maximum(var, 0.0))
        return Estimate(z / s, std / s, NORMAL_975 * std / s, time.perf_counter() - start)
    r = tau - W1s @ z
    N, p = len(tau) // n, W1.shape[1]
    u = (Z1s * r[:, None]).reshape(N, n, p).sum(axis=1) @ B.T  # (N, p): B g_t
    var = np.sum(u * u, axis=0)
    for lag in range(1, min(lags, N - 1) + 1):
        var += 2 * np.sum(u[lag:] * u[:-lag], axis=0)
    # the truncated form can come out negative where the true variance is far below its noise: it
    # is then not estimable from these data, and the interval says so
    var *= len(tau) / max(len(tau) - p, 1)
    std = np.sqrt(np.where(var > 0, var, np.inf))
    half = t_quantile(max(N // (lags + 1) - 1, 1)) * std
    return Estimate(z / s, std / s, half / s, time.perf_counter() - start)


ESTIMATORS: dict[str, Callable[..., Estimate]] = {"ols": ols, "wls": wls, "irls": irls, "iv": iv}
DESCRIPTIONS = {
    "ols": "ordinary least squares",
    "wls": "weighted least squares, per-joint residual variance",
    "irls": f"iteratively reweighted least squares, Huber c = {HUBER_C}",
    "iv": "instrumental variables, instruments from the reference motion (IDIM-IV)",
}
