"""A log's velocity columns against its positions' rate of change: how far each lags.

A robot's tools often log a velocity that is not the positions' rate of change at the same instant:
an estimate filtered causally on the controller, a value from another loop, a topic stamped on
arrival. Such a column is late by tens to hundreds of milliseconds (a mobile manipulator's published
velocities lag its positions by 140 to 180 ms), while its scale is right, so the scale check
(harness/sources/log/units.py, `check_velocities`) passes it. Used as measured, it shifts every
velocity-dependent term: friction is fitted against where the joint was, not where it is.

Per joint, the lag tau maximising the normalised cross-correlation of the logged q'(t + tau) with
the positions' rate of change (q[i+1] - q[i]) / (t[i+1] - t[i]) at the midpoints, both on a uniform
grid at the median step, the rate over the grid's central window and the velocity over that window
moved by tau (each lag's sum over as many rows), over |tau| <= MAX_LAG (at most a tenth of the log)
(scipy.signal.correlate, by FFT), then refined within a step of the grid's best by least squares of
the logged q' against the rate at the log's own samples (`_refined`). A joint
whose two do not follow each other (the peak's correlation under TRACKING: it hardly moves) says
nothing. A column that lags by more than LAG_STEPS median steps, and whose lag explains its disagreement with
the rate (the sum of squares at the lag at most SHIFT_GAIN of that at zero, as a torque channel's delay is
found: harness/identify/delay.py), is realigned by its lag (`judged`). A lag that explains less is the
rate's noise's doing: the Panda's positions, differenced at a jittering 1 kHz clock, disagree with its
logged velocities by a fifth of their size, and the lags of 2 to 9 ms found there leave 99.8 % of it."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from harness.base.numerics import SHIFT_GAIN

MAX_LAG = 0.5  # s: the lags searched, either way
LAG_STEPS = 3.0  # median steps: a logged velocity further off the positions' rate than this is realigned
TRACKING = 0.5  # the peak's correlation under which a joint's velocity and rate say nothing of a lag


@dataclass(frozen=True)
class VelocityLags:
    """Per joint: the lag (s; positive, the logged velocity is late), the peak's correlation, whether
    the joint moves enough to tell (`judged`), and the sum of squares of the rate less the logged velocity
    read at the lag over that at zero (`residual_ratio`: 1 where nothing could be read)."""

    lag_s: np.ndarray
    correlation: np.ndarray
    judged: np.ndarray
    median_step: float
    residual_ratio: np.ndarray

    @property
    def late(self) -> np.ndarray:
        """(n,) the joints whose velocity column lags beyond LAG_STEPS median steps, by a lag that explains
        its disagreement with the rate (residual ratio at most SHIFT_GAIN)."""
        return self.judged & (np.abs(self.lag_s) > LAG_STEPS * self.median_step) & (self.residual_ratio <= SHIFT_GAIN)


def lags(t: np.ndarray, q: np.ndarray, qd: np.ndarray) -> VelocityLags:
    """The lag of each velocity column (N, n) behind the rate of change of its positions (N, n) at
    times t (N,), strictly increasing (module docstring)."""
    from scipy.signal import correlate

    h = float(np.median(np.diff(t)))
    n = q.shape[1]
    lag, peak, ratio = np.zeros(n), np.zeros(n), np.ones(n)
    grid = np.arange(t[0] + h, t[-1] - h, h)
    K = int(min(MAX_LAG, (t[-1] - t[0]) / 10.0) / h)
    if K < 1 or len(grid) < 4 * K + 3:
        return VelocityLags(lag, peak, np.zeros(n, dtype=bool), h, ratio)
    midpoints = 0.5 * (t[1:] + t[:-1])
    dt = np.diff(t)
    inner = (midpoints >= grid[K]) & (midpoints <= grid[len(grid) - 1 - K])  # every lag searched reaches them
    for j in range(n):  # joint by joint: a long log's grids are not made for all joints at once
        differences = np.diff(q[:, j]) / dt
        rate = np.interp(grid, midpoints, differences)[K:len(grid) - K]  # the central window
        logged = np.interp(grid, t, qd[:, j])
        # w[k] = sum_i logged[i + k] rate[i] over the window moved by k - K, normalised by both norms there
        energy = np.concatenate([[0.0], np.cumsum(logged**2)])
        window = np.sqrt(energy[len(rate):] - energy[:-len(rate)])
        norm = np.sqrt(rate @ rate) * window
        if not np.all(norm > 0):
            continue
        w = correlate(logged, rate, mode="valid", method="fft") / norm
        k = int(np.argmax(w))
        lag[j], ratio[j] = _refined(t, qd[:, j], midpoints[inner], differences[inner], (k - K) * h, h)
        peak[j] = w[k]
    return VelocityLags(lag, peak, peak >= TRACKING, h, ratio)


def _refined(t: np.ndarray, qd: np.ndarray, at: np.ndarray, rate: np.ndarray, lag: float, h: float
             ) -> tuple[float, float]:
    """The lag within a step of the grid's best, `lag`, that minimises sum (rate - q'(at + lag))^2, q'
    interpolated linearly between its samples (Brent's bounded search, scipy.optimize.minimize_scalar, to
    1e-6 of a step): the grid's peak alone is a step's resolution, and a parabola through it is biased by
    the peak's shape (a 5 ms grid gave 0.08 ms where this gives 5 us). And that sum at the lag over the
    sum at zero (1 where the rate and the velocity both vanish)."""
    from scipy.optimize import minimize_scalar

    def squares(x: float) -> float:
        return float(np.sum((rate - np.interp(at + x, t, qd)) ** 2))

    found = minimize_scalar(squares, bounds=(lag - h, lag + h), method="bounded", options={"xatol": 1e-6 * h})
    at_zero = squares(0.0)
    return float(found.x), (squares(float(found.x)) / at_zero if at_zero > 0 else 1.0)


VELOCITY_CHOICES = ("checked", "used")  # [data] velocities: realigned where they lag (default), or used as logged


def judged(kept, training, joints: list[str], choice: str = "checked"):
    """The log `kept` (a RawLog) with each velocity column that lags beyond LAG_STEPS median steps on
    the training rows `training` realigned by its lag, q'(t) read at t + lag (what the data decide, they
    decide from the training rows alone), the rows at either end that a realigned column cannot reach
    dropped; `choice` "used" keeps the columns as logged. The log, the record (None for a log without
    velocities) and the line the terminal says (None where nothing was done)."""
    import dataclasses

    if kept.qd is None:
        return kept, None, None
    found = lags(training.t, training.q, training.qd)
    late = [k for k in range(len(joints)) if found.late[k]]
    record = {"definition": "per joint the lag (s; positive: the logged q' is late) maximising the normalised "
                            "cross-correlation of the logged q'(t + lag) with the positions' rate of change, on "
                            f"the training rows; the column of a joint that moves (correlation at least {TRACKING:g}) "
                            f"lagging by more than {LAG_STEPS:g} median steps, by a lag that explains the "
                            f"disagreement (residual_ratio, the sum of squares of the rate less q'(t + lag) over that "
                            f"at zero lag, at most {SHIFT_GAIN:g}), is realigned, q'(t) read at t + lag",
              "median_step_s": found.median_step, "choice": choice,
              "per_joint": {j: {"lag_s": float(found.lag_s[k]), "correlation": float(found.correlation[k]),
                                "judged": bool(found.judged[k]), "residual_ratio": float(found.residual_ratio[k])}
                            for k, j in enumerate(joints)},
              "late_joints": [joints[k] for k in late], "realigned": bool(late) and choice == "checked"}
    if not late:
        return kept, record, None
    said = ", ".join(f"{joints[k]} {found.lag_s[k] * 1e3:.3g} ms" for k in late[:4]) + (" ..." if len(late) > 4 else "")
    if choice == "used":
        return kept, record, (f"the logged velocities lag the positions' rate of change ({said}): used as logged "
                              "(velocities = \"used\")")
    shift = found.lag_s[late]
    reach = (kept.t + shift.min() >= kept.t[0]) & (kept.t + shift.max() <= kept.t[-1])
    qd = kept.qd.copy()
    for k, tau in zip(late, shift, strict=True):
        qd[:, k] = np.interp(kept.t + tau, kept.t, kept.qd[:, k])
    record["rows_dropped"] = int(np.sum(~reach))
    return dataclasses.replace(kept, qd=qd).span(reach), record, (
        f"the logged velocities lag the positions' rate of change ({said}): realigned by their lags, "
        f"{int(np.sum(~reach))} rows at the ends dropped (velocities = \"used\" keeps them as logged)")
