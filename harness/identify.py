"""Least squares with an identifiability verdict for every parameter.

A parameter is reported as a number only when the data determine it:
1. Excitation: its regressor column must stand well above what the measurement's own resolution
   produces. `column_floor[c]` is the size of column c that measurement error alone accounts for
   (the pipeline obtains it by dithering the measured channels at their resolution); a column
   with ||K_c|| < SNR_MIN * column_floor[c] is not excited by the motion. (B1 of kr500 never
   accelerates along e2(0) and never turns about e2(1) or e3(1): its columns for m_e2, J22, J33
   are round-off, or rounding, and nothing else.)
2. Separability: the excited columns, each scaled to unit norm, must have
   sigma_min / sigma_max >= COLLINEAR; otherwise the parameters with a weight above 0.1 in the
   weakest right singular vectors are collinear and none of them is reported.
The remaining columns are solved by least squares on the column-scaled regressor (Eq. 56/64).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

SNR_MIN = 100.0  # a column must be 100 times what measurement error alone produces
COLLINEAR = 1e-8  # scaled sigma_min / sigma_max below this: columns are not separable


@dataclass(frozen=True, eq=False)
class LeastSquares:
    names: tuple[str, ...]
    x: np.ndarray  # (p,) NaN where not identifiable
    identifiable: np.ndarray  # (p,) bool
    reasons: tuple[str, ...]  # "" where identifiable
    column_snr: np.ndarray  # (p,) ||K_c|| / column_floor[c]
    singular_values: np.ndarray  # of the scaled, excited columns
    residual_norm: float
    rows: int


def solve(K: np.ndarray, L: np.ndarray, names: Sequence[str], column_floor: np.ndarray
          ) -> LeastSquares:
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
    x = np.full(p, np.nan)
    residual = float(np.linalg.norm(L))
    if ok.any():
        cols = np.flatnonzero(ok)
        z, *_ = np.linalg.lstsq(K[:, cols] / norms[cols], L, rcond=None)
        x[cols] = z / norms[cols]
        residual = float(np.linalg.norm(K[:, cols] @ x[cols] - L))
    return LeastSquares(tuple(names), x, ok, tuple(reasons), snr, sv, residual, K.shape[0])
