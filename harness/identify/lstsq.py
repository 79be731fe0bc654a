"""Least squares with an identifiability verdict for every parameter.

A parameter is reported as a number only when the data determine it:
1. Excitation: its regressor column must stand well above what the measurement's own resolution
   produces. `column_floor[c]` is the size of column c that measurement error alone accounts for
   (the pipeline obtains it by dithering the measured channels at their resolution); a column
   with ||K_c|| < SNR_MIN * column_floor[c] is not excited by the motion. (B1 of kr500 never
   accelerates along e2(0) and never turns about e2(1) or e3(1): its columns for m_e2, J22, J33
   are round-off, or rounding, and nothing else: SNR 0.1 to 4. Excited columns stand at 40 to
   100 under 1 % noise, and at 1e4 or more with exact or 7-digit data; 10 separates the two.)
2. Separability: the excited columns, each scaled to unit norm, must have
   sigma_min / sigma_max >= COLLINEAR; otherwise the parameters with a weight above 0.1 in the
   weakest right singular vectors are collinear and none of them is reported.
The remaining columns are solved by least squares on the column-scaled regressor (Eq. 56/64),
weighted by channel group: each row group (for one body: the force rows along x, y, z and the
moment rows about x, y, z) is weighted by the inverse of its residual variance from a first,
unweighted solve, since forces and moments are measured to different precision.

Uncertainty: the covariance of the estimate is the cluster-robust sandwich
(K^T W K)^-1 [sum_c K_c^T W r~_c r~_c^T W K_c] (K^T W K)^-1 over the G sample times (the rows of
one instant share noise through the joint forces and angles they are built from), with each
cluster's residuals corrected for its leverage, r~_c = (I - H_cc)^-1 r_c (the CR3 estimator,
which is exactly the sum of squared leave-one-cluster-out changes of the estimate, tested; the
uncorrected sandwich covered 93.5 % instead of 95 % in a 200-trial sweep of kr500_noise).
(K^T W K)^-1 comes from the SVD of W^1/2 K; a direction it leaves undetermined gets an infinite
standard deviation, and the variances are sums of squares, never negative. It does not trust a
noise model: the scatter of the residuals is the evidence. The 95 % interval is the estimate
+- t(0.975, G - 1) standard deviations.

Weak identifiability: an identifiable parameter can still be determined far worse than the others,
and an error of the data that the residual cannot show (a bias common to every sample, such as two
engines' round-off, 1e-13) then moves it by much more than its standard deviation. Its sensitivity
kappa_k = ||row k of (W^1/2 K)^+|| ||W^1/2 L|| / scale_k is the relative change of the parameter per
relative change of the data in the worst direction (scale_k: the parameter's magnitude in the
model's own values; the joint-torque paths take the estimate's where the model has it zero). A
parameter whose kappa is more than WEAK_RATIO times the median kappa is
reported as weakly identifiable (the essential-parameter criterion of Pham and Gautier, 1991, on
sensitivities instead of standard deviations, so that no noise model is assumed): its error is
kappa_k times the data's relative error, a thousand times the typical parameter's. so100's first
axis, tilted 3e-6 rad in its URDF, leaves the shoulder's m c_z such a column: kappa 4e7 against a
median 1e3, error 2e-6 where the rest are at 1e-12; the largest ratio over the Panda, UR5 and KR500
scenarios is 370.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from harness.base.numerics import ROWS_AT_A_TIME, SideBySide

T_LARGE_DOF = 1000  # beyond it the quantile is the Cornish-Fisher series (its next term under 1e-11 relative)


@functools.lru_cache(maxsize=256)
def t_quantile(dof: int, p: float = 0.975) -> float:
    """Student's t quantile, t with P(T <= t) = p for dof degrees of freedom.

    Written here, not taken from scipy.special.stdtrit: importing scipy.special costs 0.35 to 0.4 s,
    a fifth of the default run, which needs only this number. Abramowitz and Stegun: for dof above
    T_LARGE_DOF the Cornish-Fisher expansion 26.7.5 about the normal quantile x (four terms, the
    fifth of order x^11 / dof^5); below it, Newton's method on the exact distribution function of
    26.7.3 (a finite sum of powers of cos(atan(t / sqrt(dof)))), from that expansion. Agrees with
    scipy.special.stdtrit to 1e-12 relative for p up to 0.9995 and 1e-10 at 0.999999, dof 1 to 1e7
    (the bounds tests/test_weak_identifiability.py holds it to)."""
    if not 0.5 <= p < 1.0 or dof < 1:
        raise ValueError(f"t_quantile: needs 0.5 <= p < 1 and dof >= 1, got p = {p}, dof = {dof}")
    from statistics import NormalDist

    x = NormalDist().inv_cdf(p)
    nu = float(dof)
    t = x + ((x**3 + x) / 4 + ((5 * x**5 + 16 * x**3 + 3 * x) / 96
             + ((3 * x**7 + 19 * x**5 + 17 * x**3 - 15 * x) / 384
                + (79 * x**9 + 776 * x**7 + 1482 * x**5 - 1920 * x**3 - 945 * x) / 92160 / nu) / nu) / nu) / nu
    if dof > T_LARGE_DOF:
        return t
    if dof == 1:
        return math.tan(math.pi * (p - 0.5))  # the Cauchy distribution
    if dof == 2:
        return (2 * p - 1) * math.sqrt(2 / (4 * p * (1 - p)))
    log_norm = math.lgamma((nu + 1) / 2) - math.lgamma(nu / 2) - 0.5 * math.log(nu * math.pi)
    for _ in range(50):
        step = (_t_cdf(t, dof) - p) / math.exp(log_norm - (nu + 1) / 2 * math.log1p(t * t / nu))
        t -= step
        if abs(step) <= 1e-15 * abs(t):
            break
    return t


def _t_cdf(t: float, dof: int) -> float:
    """P(T <= t), t >= 0, for integer dof >= 3 (Abramowitz and Stegun 26.7.3): with theta = atan(t / sqrt(dof)),
    A = (2 / pi) (theta + sin(theta) sum_k c_k cos(theta)^(2k + 1)) for odd dof and
    A = sin(theta) sum_k c_k cos(theta)^(2k) for even dof, each c_k the previous times (2k) / (2k + 1)
    (odd) or (2k - 1) / (2k) (even); P = (1 + A) / 2."""
    theta = math.atan(t / math.sqrt(dof))
    c2 = math.cos(theta) ** 2
    if dof % 2:
        k = np.arange(1, (dof - 1) // 2)
        terms = np.cumprod(np.r_[math.cos(theta), c2 * (2 * k) / (2 * k + 1)])
        a = 2 / math.pi * (theta + math.sin(theta) * float(terms.sum()))
    else:
        k = np.arange(1, dof // 2)
        terms = np.cumprod(np.r_[1.0, c2 * (2 * k - 1) / (2 * k)])
        a = math.sin(theta) * float(terms.sum())
    return (1 + a) / 2


SNR_MIN = 10.0  # a column must be 10 times what measurement error alone produces
COLLINEAR = 1e-8  # scaled sigma_min / sigma_max below this: columns are not separable
WEAK_RATIO = 1e3  # sensitivity above this times the median: weakly identifiable


@dataclass(frozen=True, eq=False)
class Estimate:
    """A least-squares result, the one type every fit here returns: the estimators' OLS, WLS and IV
    (harness/identify/estimators.py), the log's base fit (torque_id.fit_base), the bench's per-body and
    whole-system solves (`solve`). The estimate, each entry's standard deviation and the half width of
    its 95 % interval; then what a fit knows beyond them, where it knows it (None or empty where not)."""

    beta: np.ndarray  # (p,) NaN where not identifiable
    std: np.ndarray  # (p,) NaN where not identifiable
    ci_half_width: np.ndarray  # (p,) of the 95 % interval
    seconds: float = float("nan")  # the fit's own time (the estimators' comparison)
    sensitivity: np.ndarray | None = None  # (p,) kappa, NaN where not identifiable or no scale was given
    weak: np.ndarray | None = None  # (p,) bool: identifiable, but kappa > WEAK_RATIO x median kappa
    condition_number: float | None = None  # of the column-scaled regressor
    # what `solve` says of each column: its name, whether it is identifiable and why not
    names: tuple[str, ...] = ()
    identifiable: np.ndarray | None = None  # (p,) bool
    reasons: tuple[str, ...] = ()  # "" where identifiable
    column_snr: np.ndarray | None = None  # (p,) ||K_c|| / column_floor[c]
    singular_values: np.ndarray | None = None  # of the scaled, excited columns
    residual_norm: float | None = None
    rows: int | None = None

    @property
    def ci_low(self) -> np.ndarray:
        return self.beta - self.ci_half_width

    @property
    def ci_high(self) -> np.ndarray:
        return self.beta + self.ci_half_width


def _weighted(Ks: np.ndarray, L: np.ndarray, group: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """Row weights 1/variance of each row group's residuals from an unweighted solve."""
    if group is None:
        return np.ones(len(L)), np.linalg.lstsq(Ks, L, rcond=None)[0]
    z, *_ = np.linalg.lstsq(Ks, L, rcond=None)
    r = L - Ks @ z
    w = np.ones(len(L))
    # a group that fits to round-off is the best measured: its variance is floored at the round-off
    # of the largest value solved for, which gives it the largest weight, never the smallest
    floor = max((np.finfo(float).eps * float(np.max(np.abs(L), initial=0.0))) ** 2, np.finfo(float).tiny)
    for g in np.unique(group):
        rows = group == g
        w[rows] = 1.0 / max(float(np.mean(r[rows] ** 2)), floor)
    w /= np.max(w)
    sw = np.sqrt(w)
    return w, np.linalg.lstsq(Ks * sw[:, None], L * sw, rcond=None)[0]


def solve(K: np.ndarray, L: np.ndarray, names: Sequence[str], column_floor: np.ndarray,
          cluster: np.ndarray | None = None, group: np.ndarray | None = None,
          scale: np.ndarray | None = None) -> Estimate:
    """cluster: (rows,) the sample each row belongs to; group: (rows,) its channel group;
    scale: (p,) each parameter's magnitude in the model's own values, for the sensitivities."""
    p = K.shape[1]
    norms = np.linalg.norm(K, axis=0)
    # no column is known better than its own double-precision round-off
    floor = np.maximum(column_floor, np.finfo(float).eps * norms)
    with np.errstate(divide="ignore", invalid="ignore"):
        snr = np.where(norms > 0, norms / floor, 0.0)
    reasons = ["" if s >= SNR_MIN else
               f"not excited: regressor column is {s:.1f} times what measurement error alone "
               f"produces (needs {SNR_MIN:g})" for s in snr]
    excited = [c for c in range(p) if not reasons[c]]
    sv = np.array([])
    if excited:
        Ks = K[:, excited] / norms[excited]
        _, sv, Vt = np.linalg.svd(Ks, full_matrices=False)
        weak = sv < COLLINEAR * sv[0]
        if weak.any():
            involved = np.any(np.abs(Vt[weak]) > 0.1, axis=0)
            partners = [names[c] for c, inv in zip(excited, involved, strict=True) if inv]
            for c, inv in zip(excited, involved, strict=True):
                if inv:
                    reasons[c] = (f"not separable: columns of {', '.join(partners)} are collinear "
                                  f"(sigma_min/sigma_max = {sv[-1] / sv[0]:.1e})")
    ok = np.array([not r for r in reasons])
    x, std, half, kappa = (np.full(p, np.nan) for _ in range(4))
    residual = float(np.linalg.norm(L))
    if ok.any():
        cols = np.flatnonzero(ok)
        Ks = K[:, cols] / norms[cols]
        w, z = _weighted(Ks, L, group)
        x[cols] = z / norms[cols]
        r = L - Ks @ z
        residual = float(np.linalg.norm(r))
        std[cols], half[cols] = sandwich_std(Ks, r, w, cluster)
        std[cols] /= norms[cols]
        half[cols] /= norms[cols]
        if scale is not None:
            size = norms[cols] * scale[cols]  # a parameter of no magnitude has no relative sensitivity
            kappa[cols] = np.where(size > 0, sensitivity(Ks * np.sqrt(w)[:, None], L * np.sqrt(w))
                                   / np.where(size > 0, size, 1.0), np.nan)
    return Estimate(x, std, half, sensitivity=kappa, weak=weakly_identifiable(kappa), names=tuple(names),
                    identifiable=ok, reasons=tuple(reasons), column_snr=snr, singular_values=sv,
                    residual_norm=residual, rows=K.shape[0])


def sensitivity(K: np.ndarray, L: np.ndarray, svd: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """||row k of K^+|| ||L||: the change of parameter k per unit relative change of L in the worst
    direction (divide by the parameter's magnitude for the relative change). From the SVD of K:
    K^+ = V S^-1 U^T, whose row norms are those of V S^-1. Infinite along undetermined directions.
    `svd`: K's singular values and right singular vectors where they are known (those of its triangle R,
    K = Q R: harness/base/numerics.py, `triangle`)."""
    S, Vt = svd if svd is not None else np.linalg.svd(K, full_matrices=False)[1:]
    determined = S > S[0] * np.finfo(float).eps * max(K.shape)
    out = np.sqrt(np.sum((Vt[determined].T / S[determined]) ** 2, axis=1)) * np.linalg.norm(L)
    return np.where(np.any(np.abs(Vt[~determined]) > 1e-8, axis=0), np.inf, out)


def weakly_identifiable(kappa: np.ndarray) -> np.ndarray:
    """kappa more than WEAK_RATIO times the median of the finite, positive kappas."""
    good = np.isfinite(kappa) & (kappa > 0)
    if not good.any():
        return np.zeros(len(kappa), bool)
    with np.errstate(invalid="ignore"):
        return (kappa > WEAK_RATIO * np.median(kappa[good])) & ~np.isnan(kappa)


def sandwich_std(Ks: np.ndarray | SideBySide, r: np.ndarray, w: np.ndarray, cluster: np.ndarray | None,
                 svd: tuple[np.ndarray, np.ndarray] | None = None, scale: np.ndarray | None = None
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Standard deviation and 95 % half width of the weighted least-squares estimate z of
    W^1/2 Ks z = W^1/2 L with residuals r: the CR3 cluster-robust sandwich (module docstring).
    Infinite along directions the data leave undetermined; NaN with fewer than two clusters. `svd`:
    W^1/2 Ks's singular values and right singular vectors where they are known (`sensitivity`).
    `scale`: Ks is the regressor given (an array or harness/base/numerics.py's SideBySide) over
    `scale`, read a chunk of clusters at a time and never scaled whole."""
    p = Ks.shape[1]
    cluster = np.arange(len(r)) if cluster is None else cluster
    if svd is None:
        # (K^T W K)^-1 from the SVD of W^1/2 K, not by inverting K^T W K (which squares its
        # condition number); a direction the data do not determine has infinite variance
        svd = np.linalg.svd(_scaled(Ks, scale, slice(None)) * np.sqrt(w)[:, None], full_matrices=False)[1:]
    S, Vt = svd
    determined = S > S[0] * np.finfo(float).eps * max(Ks.shape)
    bread = (Vt[determined].T / S[determined] ** 2) @ Vt[determined]
    undetermined = np.any(np.abs(Vt[~determined]) > 1e-8, axis=0)
    ids, counts = np.unique(cluster, return_counts=True)
    if np.all(counts == counts[0]) and np.array_equal(cluster, np.repeat(ids, counts[0])):
        # equal, contiguous clusters (one sample each): a chunk of clusters at a time
        k = counts[0]
        step = max(1, ROWS_AT_A_TIME // k) * k
        scores = np.concatenate([_cluster_scores(_scaled(Ks, scale, slice(a, a + step)), w[a: a + step],
                                                 r[a: a + step], k, bread) for a in range(0, len(r), step)])
    else:
        Ks = _scaled(Ks, scale, slice(None))
        Xw = Ks * w[:, None]
        scores = []
        for c in ids:
            rows = cluster == c
            H = Ks[rows] @ bread @ Xw[rows].T
            r_adj = np.linalg.lstsq(np.eye(len(H)) - H, r[rows], rcond=None)[0]
            scores.append(Xw[rows].T @ r_adj)
        scores = np.array(scores)
    G = len(scores)
    if G < 2:  # one cluster alone gives no spread to estimate
        return np.full(p, np.nan), np.full(p, np.nan)
    # diag(B S^T S B) as a sum of squares: never negative, nothing to clip
    var = np.sum((np.asarray(scores) @ bread) ** 2, axis=0)
    std = np.where(undetermined, np.inf, np.sqrt(var))
    return std, t_quantile(G - 1) * std


def _scaled(K, scale: np.ndarray | None, rows: slice) -> np.ndarray:
    """Rows `rows` of K / scale (K itself where scale is None), as an array."""
    chunk = K[rows]
    return chunk if scale is None else chunk / scale


def _cluster_scores(Ks: np.ndarray, w: np.ndarray, r: np.ndarray, k: int, bread: np.ndarray) -> np.ndarray:
    """(clusters, p): the scores X_c^T (1 - H_cc)^-1 r_c of consecutive clusters of k rows (CR3)."""
    p = Ks.shape[1]
    Xw = Ks if np.all(w == 1.0) else Ks * w[:, None]  # K^T W r = (W K)^T r
    G = len(r) // k
    Kc, Xc, rc = Ks.reshape(G, k, -1), Xw.reshape(G, k, -1), r.reshape(G, k)
    r_adj = None
    if p < k:
        # (1 - K_c B X_c^T)^-1 r_c = r_c + K_c B (1 - X_c^T K_c B)^-1 X_c^T r_c (Woodbury): p x p
        # systems instead of k x k, the same numbers where both are regular
        XtK_B = np.swapaxes(Xc, 1, 2) @ Kc @ bread
        Xtr = np.einsum("gkp,gk->gp", Xc, rc)
        inner_matrix = np.eye(p) - XtK_B
        if np.all(np.linalg.cond(inner_matrix) < 1e10):  # else a cluster with leverage 1: the k x k form
            r_adj = rc + (Kc @ (bread @ np.linalg.solve(inner_matrix, Xtr[..., None])))[..., 0]
    if r_adj is None:
        H = Kc @ bread @ np.swapaxes(Xc, 1, 2)  # leverage of each cluster on its own fit
        # a cluster that alone determines a direction has leverage 1: pinv leaves that direction out
        r_adj = (np.linalg.pinv(np.eye(k) - H) @ rc[..., None])[..., 0]
    return np.einsum("gkp,gk->gp", Xc, r_adj)
