"""The delay of each torque (or current) channel of a log behind its encoders.

A channel that lags by d measures tau_meas(t) = tau(t - d): the torque the joint state at t needs
arrives d later. For joint j and a candidate d, the measured torque read d later, tau_meas(t + d),
is fitted by least squares on the joint's own rows of the regressor, W_j(q, q', q'') theta (the
same columns as the identification: every link's ten parameters and every joint's friction and
rotor inertia); the delay is the d whose fit leaves the smallest residual. The residual is taken on
the same rows for every candidate (those at least the largest candidate from either end), on a grid
of STEP on a filtered log, of whole samples near STEP on an unfiltered one (`grid_step`: there a
candidate between samples would smooth the channel's noise and win for that), then refined by a
parabola through the best grid point and its neighbours. Linear interpolation reads tau_meas between
samples; nothing is read across a gap.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from harness.base.numerics import SHIFT_GAIN, column_scale, relative_residual, sample_step
from harness.base.series import STRETCH_BREAK, TimeSeries, room
from harness.identify.torque_id import SAMPLES_AT_A_TIME

LARGEST = 0.02  # s: the candidates span +-20 ms
STEP = 0.0005  # s
EDGE = 1  # a best candidate this many steps or fewer from an end of the search is at its edge: the parabola
# through it and its neighbours then leans on the end, and the curve may go on falling beyond it


@dataclass(frozen=True)
class Delays:
    """Per joint: the estimated delay (s, the torque channel behind the encoder when positive), the
    relative residual of the fit at it and at zero delay, and the candidates' residual curve."""

    delay: np.ndarray  # (n,)
    residual: np.ndarray  # (n,) ||W_j theta - tau_j(t + d)|| / ||tau_j|| at the delay
    residual_at_zero: np.ndarray  # (n,)
    candidates: np.ndarray  # (K,)
    curve: np.ndarray  # (n, K)
    at_edge: np.ndarray  # (n,) bool: the best candidate is within EDGE steps of an end (the delay may lie beyond)

    @property
    def found(self) -> np.ndarray:
        """(n,) bool: per joint, whether the delay is found: inside the search, and the fit clearly
        better for it (its residual at most SHIFT_GAIN times the residual at zero delay)."""
        return ~self.at_edge & (self.residual <= SHIFT_GAIN * self.residual_at_zero)


def _basis(Wj: np.ndarray) -> np.ndarray:
    """An orthonormal basis of the column space of the column-scaled Wj (its numerical rank's left
    singular vectors): the least-squares residual of any y is then y less its projection. Wj is
    scaled in place (the caller's own copy of a joint's rows: a long log's are hundreds of MiB)."""
    Wj /= column_scale(Wj)
    U, sv, _ = np.linalg.svd(Wj, full_matrices=False)
    return U[:, sv > sv[0] * max(Wj.shape) * np.finfo(float).eps] if sv.size and sv[0] > 0 else U[:, :0]


def _residual(U: np.ndarray, y: np.ndarray) -> float:
    return relative_residual(y - U @ (U.T @ y), y)


MIN_CANDIDATES = 4  # each side of zero: a coarse log's search reaches this many whole samples at least


def grid_step(t: np.ndarray, filtered: bool, step: float = STEP) -> float:
    """The candidates' spacing: `step` on a low-pass filtered log (smooth at that scale, so that linear
    interpolation between samples reads it faithfully); else a whole number of the log's median sample
    steps, the one nearest `step` (at least one). On an unfiltered log a candidate between two samples
    would read the channel by interpolation, which averages its noise (at half a step, white noise by
    1 / sqrt(2)): its residual would fall by the noise it smooths, and a log without any delay would
    seem to lag by a fraction of a sample (docs/identification.md gives the figure on a bench log)."""
    if filtered:
        return step
    dt = sample_step(t)
    return max(1, round(step / dt)) * dt


def estimate(t: np.ndarray, tau: np.ndarray, W, largest: float = LARGEST, step: float = STEP,
             filtered: bool = True, offset: np.ndarray | None = None) -> Delays:
    """t (N,) s, uniform within each stretch of a log cut at its gaps; tau (N, n); W (N, n, p) the
    regressor's rows by joint, or a function of a range of samples (a, b) that gives theirs,
    (b - a, n, p) (harness/identify/span_rows.py: a long log's, made on demand); `filtered`, whether
    the log went through a low-pass (`grid_step`); `offset` (N, n), a part of each joint's row that other
    channels measure, on the encoders' clock (a floating base's contacts' J^T F: the row is the motor's
    torque plus it), added to the torque read d later. The
    rows used are those at least `largest` from a stretch's ends (at least MIN_CANDIDATES grid steps).
    The delay between candidates is the vertex of the parabola through the best candidate's squared
    residual and its neighbours' (a lag's residual is quadratic in the delay's error near its
    minimum), and its residual the parabola's at the vertex."""
    h = grid_step(t, filtered, step)
    largest = max(largest, MIN_CANDIDATES * h)
    candidates = np.arange(-np.floor(largest / h + 1e-9), np.floor(largest / h + 1e-9) + 1) * h
    largest = float(candidates[-1])
    back, ahead = room(t)
    rows = (back >= largest) & (ahead >= largest)
    samples = W if callable(W) else (lambda a, b: W[a:b])
    p = samples(0, 1).shape[2]
    n = tau.shape[1]
    at_rows = np.zeros((int(rows.sum()), n)) if offset is None else offset[rows]
    curve = np.empty((n, len(candidates)))
    for j in range(n):  # one joint's basis at a time: together they are the size of the regressor
        Wj = _joint_rows(samples, len(t), j, rows, p)
        held = int(np.count_nonzero(np.any(Wj != 0.0, axis=0)))  # the columns its rows hold (a joint's subtree's)
        if rows.sum() < 2 * held:
            raise ValueError(f"{int(rows.sum())} samples away from the ends: too few to estimate a delay of up to "
                             f"{largest * 1e3:g} ms ({held} columns in a joint's rows)")
        basis = _basis(Wj)
        for k, d in enumerate(candidates):
            curve[j, k] = _residual(basis, np.interp(t[rows] + d, t, tau[:, j]) + at_rows[:, j])
    best = np.argmin(curve, axis=1)
    delay = candidates[best].astype(float)
    residual = curve[np.arange(n), best].copy()
    at_edge = (best <= EDGE) | (best >= len(candidates) - 1 - EDGE)
    for j in np.flatnonzero((best > 0) & (best < len(candidates) - 1)):
        delay[j], residual[j] = vertex(curve[j, best[j] - 1: best[j] + 2], delay[j], h)
    zero = curve[:, np.argmin(np.abs(candidates))]
    return Delays(delay, residual, zero, candidates, curve, at_edge)


def vertex(residuals: np.ndarray, at: float, h: float) -> tuple[float, float]:
    """The vertex of the parabola through three squared residuals (the residuals at at - h, at, at + h,
    the middle the least): (its delay, the residual there); (at, the middle residual) where they do
    not curve upwards."""
    y0, y1, y2 = np.asarray(residuals, dtype=float) ** 2
    denominator = y0 - 2 * y1 + y2
    if not denominator > 0:
        return at, float(np.sqrt(y1))
    return at + 0.5 * h * (y0 - y2) / denominator, float(np.sqrt(max(y1 - (y0 - y2) ** 2 / (8 * denominator), 0.0)))


def _joint_rows(samples, N: int, j: int, rows: np.ndarray, p: int) -> np.ndarray:
    """(rows.sum(), p): joint j's regressor rows at the samples `rows` (N,) selects, read
    SAMPLES_AT_A_TIME samples at a time into one array."""
    out, at = np.empty((int(rows.sum()), p)), 0
    for a in range(0, N, SAMPLES_AT_A_TIME):
        piece = samples(a, a + SAMPLES_AT_A_TIME)[rows[a: a + SAMPLES_AT_A_TIME], j, :]
        out[at: at + len(piece)] = piece
        at += len(piece)
    return out


def shifted(t: np.ndarray, tau: np.ndarray, delay: np.ndarray, step: float) -> tuple[np.ndarray, np.ndarray]:
    """tau read `delay` later (tau_j(t + d_j), by linear interpolation) and the rows where that lies
    between two samples at most STRETCH_BREAK `step` apart (not across a gap, not beyond an end)."""
    out = np.empty_like(tau)
    keep = np.ones(len(t), dtype=bool)
    for j, d in enumerate(delay):
        at = t + d
        right = np.searchsorted(t, at)
        inside = (right > 0) & (right < len(t))
        close = np.zeros(len(t), dtype=bool)
        close[inside] = (t[right[inside]] - t[right[inside] - 1]) <= STRETCH_BREAK * step
        exact = np.isin(at, t)
        keep &= close | exact
        out[:, j] = np.interp(at, t, tau[:, j])
    return out, keep


def corrected(series: TimeSeries, lags: Delays, joints) -> TimeSeries:
    """The series with each joint's torque read its delay later where the delay is found (`found`;
    the others as they are), the rows where that falls across a gap or beyond an end dropped: a
    channel that lags by d is read at t + d, where it shows the torque of the state at t."""
    cols = [series.joint_index(j) for j in joints]
    step = sample_step(series.t)
    tau, keep = shifted(series.t, series.tau[:, cols], np.where(lags.found, lags.delay, 0.0), step)
    out = series.tau.copy()
    out[:, cols] = tau
    return dataclasses.replace(series, tau=out).span(keep)
