"""A closed chain's friction law from its log: viscous and Coulomb friction at every joint, passive ones
included, f_v q' + f_c tanh(q'/v_c) + f_o, with one smoothing velocity v_c for all of them, chosen by
the blocked cross-validation an open chain's law search uses (harness/identify/friction_law.py).

Why one v_c and no family search: a closed chain's torques are its actuated joints', G^T (Y theta + f),
and G (harness/model/closure.py) changes with the configuration, so a joint's friction columns reach
every actuated row with a weight that changes from sample to sample; the open chain's search, which
replaces one joint's columns in normal equations kept per joint (or per motor, through a constant
coupling), does not apply. Here the regressor G^T Y is made once, and a candidate v_c rewrites every
joint's Coulomb column on it, G[:, j, :] tanh(q'_j / v_c); each candidate's held-out error is that of
least squares of the base parameters fitted on the folds' complements."""

from __future__ import annotations

import numpy as np
from scipy.optimize import minimize_scalar

from harness.base.numerics import blocked_folds, column_scale, fit_residual, relative_residual_of_sums, sample_step
from harness.identify import filtered
from harness.identify.friction_law import VELOCITY_GRID, FrictionChoice
from harness.identify.laws import Law
from harness.identify.torque_id import drive_column, links_weights
from harness.model import friction

FAMILY = "viscous_coulomb"
REFINE_TOLERANCE = 0.02  # in log(v_c): the bounded search around the best grid point stops at 2 %


def _with_velocity(W3: np.ndarray, G: np.ndarray, qd: np.ndarray, v, columns=None, t=None) -> np.ndarray:
    """W3 (N, m, p), a closed chain's regressor G^T Y by sample, with every joint's Coulomb column at
    v_c = v (one for all, or (n,) per joint); on a filtered span (`columns` at its times t), the shape
    filtered as the torques were (harness/identify/filtered.py) before G carries it."""
    n = qd.shape[1]
    v = np.broadcast_to(np.asarray(v, dtype=float), (n,))
    s = friction.coulomb_shape(qd, v) if columns is None else filtered.coulomb(
        columns, t, tuple(Law(FAMILY, float(x)) for x in v), None)  # (N, n)
    out = W3.copy()
    for j in range(n):
        out[:, :, drive_column(n, j, "coulomb")] = G[:, j, :] * s[:, j, None]
    return out


def _scaled_lstsq(A: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Least squares of A x = y on A's columns scaled to unit norm (harness/base/numerics.py,
    column_scale: a column that is not live left as it is)."""
    scale = column_scale(A)
    return np.linalg.lstsq(A / scale, y, rcond=None)[0] / scale


def choose(W: np.ndarray, G: np.ndarray, qd: np.ndarray, tau: np.ndarray, independent: np.ndarray,
           link_part: tuple[np.ndarray, np.ndarray], t: np.ndarray, folds: int, reach_s: float,
           model_velocity: np.ndarray, columns=None) -> FrictionChoice:
    """The smoothing velocity of every joint of a closed chain: W (N m, 14 n) its regressor G^T Y with
    friction on the training span, G (N, n, m), qd (N, n) every joint's, tau (N, m) the actuated
    torques, `independent` the base parameters' columns (`link_part`: BaseParameters.link_part).
    v_c is estimated with the parameters: the least-squares residual over the training span as a
    function of v_c (variable projection), over a sharp sign (0) and VELOCITY_GRID, the best refined
    between its grid neighbours. One scalar beside the linear parameters: its residual is no model
    choice to guard, where a cross-validated choice on a short span of one or two actuated channels
    follows its folds' extrapolation (the four-bar's crank log of tests/test_closed_chain_log_laws.py,
    which holds the figures). The blocked cross-validation (`folds` consecutive
    parts, each predicted by the fit on the others less their rows within `reach_s` of it) reports the
    held-out error of the chosen law and of the model's own velocities (n,). `columns`: a filtered
    span's (every joint's velocities at the full rate: harness/sources/log/closed.py)."""
    N, m = tau.shape
    step = sample_step(t)
    split = blocked_folds(N, folds, int(np.ceil(reach_s / step - 1e-9)) if reach_s > 0 and step > 0 else 0)
    W3 = W.reshape(N, m, -1)
    total = float(np.sum(tau**2))
    piece_of = np.empty(N, dtype=int)
    for i, piece in enumerate(split.pieces):
        piece_of[piece] = i

    def rows(v) -> np.ndarray:
        return _with_velocity(W3, G, qd, v, columns, t)[:, :, independent]

    def residual(v) -> float:  # read off the QR of the scaled rows, as the judging's floor is
        A = rows(v).reshape(N * m, -1)
        return fit_residual(A, tau.ravel()) / np.sqrt(total)

    def held_out(v) -> float:
        A, sse = rows(v), 0.0
        for k, fold in enumerate(split.folds):
            fitted = split.left_out[k][piece_of] == 0  # the samples this fold's fit reads
            x = _scaled_lstsq(A[fitted].reshape(-1, A.shape[2]), tau[fitted].ravel())
            sse += float(np.sum((A[fold].reshape(-1, A.shape[2]) @ x - tau[fold].ravel()) ** 2))
        return relative_residual_of_sums(sse, total)

    scores = {float(v): residual(float(v)) for v in np.concatenate([[0.0], VELOCITY_GRID])}
    best = min(scores, key=scores.get)
    if best > 0:  # refined between its neighbours on the grid, in log v_c
        k = int(np.searchsorted(VELOCITY_GRID, best))
        lo, hi = VELOCITY_GRID[max(k - 1, 0)], VELOCITY_GRID[min(k + 1, len(VELOCITY_GRID) - 1)]
        found = minimize_scalar(lambda x: residual(float(np.exp(x))), bounds=(np.log(lo), np.log(hi)),
                                method="bounded", options={"xatol": REFINE_TOLERANCE})
        if found.fun < scores[best]:
            best = float(np.exp(found.x))
    chosen_error = held_out(best)
    n = qd.shape[1]
    score = {FAMILY: {"held_out_rel_error": chosen_error, "coulomb_velocity": best}}
    A = rows(best).reshape(N * m, -1)
    beta = np.linalg.lstsq(A, tau.ravel(), rcond=None)[0]
    return FrictionChoice(tuple(Law(FAMILY, best) for _ in range(n)), tuple(score for _ in range(n)),
                          held_out(model_velocity), chosen_error, folds,
                          (A @ links_weights(beta, link_part)).reshape(N, m), split.guard * step)
