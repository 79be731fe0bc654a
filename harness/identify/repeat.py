"""Repeatability: the base parameters fitted again on K disjoint, consecutive segments of the training
span (each by harness/identify/torque_id.py's least squares, with its own 95 % intervals).

Per base parameter: the mean and the standard deviation over the segments, the coefficient of
variation (their ratio, in absolute value), and whether the K intervals share a common point (the
largest lower end at most the smallest upper end). A parameter whose intervals share none moved
between segments more than each fit said it could: listed. What a single fit's interval assumes (the
same robot, noise that is what the fit takes it to be) is thereby checked on the log itself.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from harness.base.numerics import consecutive_blocks
from harness.identify.torque_id import fit_base

MIN_SAMPLES_PER_PARAMETER = 3  # a segment needs at least three samples (each n torques) per base parameter


@dataclass(frozen=True)
class Repeatability:
    segments: int
    beta: np.ndarray  # (K, r)
    ci_half_width: np.ndarray  # (K, r)

    @property
    def mean(self) -> np.ndarray:
        return self.beta.mean(axis=0)

    @property
    def spread(self) -> np.ndarray:
        return self.beta.std(axis=0, ddof=1)

    @property
    def variation(self) -> np.ndarray:
        """|standard deviation / mean| over the segments (inf where the mean is zero)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.abs(self.spread / self.mean)

    @property
    def overlap(self) -> np.ndarray:
        """(r,) bool: the K 95 % intervals share a common point."""
        return np.max(self.beta - self.ci_half_width, axis=0) <= np.min(self.beta + self.ci_half_width, axis=0)


def repeat(W1: np.ndarray, tau: np.ndarray, beta_model: np.ndarray, segments: int) -> Repeatability:
    """W1 (N n, r) the base regressor of the training span in sample order, tau (N, n); the fit on
    each of `segments` consecutive parts of equal length."""
    N, n = tau.shape
    r = W1.shape[1]
    if N // segments < MIN_SAMPLES_PER_PARAMETER * r:
        raise ValueError(f"{segments} segments of {N // segments} samples: each needs {MIN_SAMPLES_PER_PARAMETER * r} "
                         f"at least ({MIN_SAMPLES_PER_PARAMETER} per base parameter)")
    fits = [fit_base(W1[b.start * n: b.stop * n], tau[b], beta_model) for b in consecutive_blocks(N, segments)]
    return Repeatability(segments, np.stack([f.beta for f in fits]), np.stack([f.ci_half_width for f in fits]))
