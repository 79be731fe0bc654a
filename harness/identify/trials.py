"""An estimator judged over repeated trials (a Monte Carlo over the measurement noise): bias, spread,
whether the bias is real, the coverage of its 95 % intervals and the RMS error, per parameter."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class OverTrials:
    """Errors of estimates over Monte Carlo trials, per base parameter (the trials' axis reduced)."""

    bias: np.ndarray  # mean error
    spread: np.ndarray  # the errors' standard deviation over the trials
    bias_in_sd: np.ndarray  # |bias| / spread
    significant: np.ndarray  # |bias| beyond 3 standard errors of the mean
    coverage: np.ndarray | None  # how often the 95 % interval holds the true value
    rms_rel_error: np.ndarray  # RMS error / the parameter's scale
    binomial: float  # the standard error of a calibrated interval's coverage over these trials

    @property
    def band(self) -> tuple[float, float]:
        """A calibrated 95 % interval's coverage falls within 3 binomial standard errors of 0.95 but for
        0.27 % of the parameters."""
        return 0.95 - 3 * self.binomial, 0.95 + 3 * self.binomial


def over_trials(err: np.ndarray, half: np.ndarray | None, scale: np.ndarray) -> OverTrials:
    """err (..., trials, r): estimate - truth; half: the 95 % intervals' half widths (same shape), or None."""
    T = err.shape[-2]
    bias = err.mean(axis=-2)
    spread = err.std(axis=-2, ddof=1) if T > 1 else np.full_like(bias, np.nan)
    # the mean of T errors has a standard error spread / sqrt(T): beyond 3 of them a bias is real
    return OverTrials(bias, spread, np.abs(bias) / spread, np.abs(bias) > 3 * spread / np.sqrt(T),
                      (np.abs(err) <= half).mean(axis=-2) if half is not None else None,
                      np.sqrt(np.mean(err**2, axis=-2)) / scale, float(np.sqrt(0.95 * 0.05 / T)))
