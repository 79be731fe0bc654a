"""Measurement conditions, applied between the recording (the truth) and what consumes it.

`significant_digits`: every measured channel is rounded to N significant digits, the way the
paper's ADAMS output keeps seven (section 3.1). Time and the gimbal flags are not measurements.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from harness.recording import Recording
from harness.tomlio import Table

CHANNELS = ("q", "qd", "qdd", "tau", "F_W", "M_W", "p_W", "v_W", "theta", "a_W", "omega_W", "omegadot_W")


@dataclass(frozen=True)
class Measurement:
    significant_digits: int | None = None  # None: ideal, the engine's double precision

    @property
    def ideal(self) -> bool:
        return self.significant_digits is None

    @property
    def resolution(self) -> float:
        """Largest relative error of one measured value: half a unit in the last kept digit, or
        the double-precision unit round-off of the engine for ideal measurements."""
        if self.ideal:
            return float(np.finfo(float).eps)
        return 0.5 * 10.0 ** (1 - self.significant_digits)


def read_measurement(t: Table) -> Measurement:
    digits = t.integer("significant_digits", default=None, minimum=1) if t.has("significant_digits") \
        else None
    t.finish()
    return Measurement(digits)


def round_significant(x: np.ndarray, digits: int) -> np.ndarray:
    """Round to `digits` significant decimal digits (to within one unit in the last place)."""
    x = np.asarray(x, dtype=float)
    ax = np.abs(x)
    ok = np.isfinite(x) & (ax > 1e-290)  # below that the scale would overflow; leave it
    exponent = np.floor(np.log10(np.where(ok, ax, 1.0)))
    scale = 10.0 ** (digits - 1 - exponent)
    return np.where(ok, np.round(x * scale) / scale, x)


def measure(rec: Recording, m: Measurement) -> Recording:
    """What the test bench reports under the measurement conditions `m`."""
    if m.ideal:
        return rec
    rounded = {c: round_significant(getattr(rec, c), m.significant_digits) for c in CHANNELS}
    return dataclasses.replace(rec, R_WB=None, **rounded)


def dither(rec: Recording, resolution: float, rng: np.random.Generator) -> Recording:
    """A recording as different from `rec` as the measurement's resolution allows.

    Every value of a channel is moved by up to `resolution` times the largest value of that
    channel at that instant (the largest force over the joints, the largest acceleration over the
    bodies, ...), drawn uniformly: an engine computes every body's quantities together, and a
    component that is zero in exact arithmetic comes out as round-off of that size, not as zero.
    Rounding to N digits moves a value by at most `resolution` times itself, which is no more."""
    moved = {}
    for c in CHANNELS:
        x = getattr(rec, c)
        if x.ndim == 3:
            size = np.max(np.linalg.norm(x, axis=-1), axis=1)[:, None, None]
        else:
            size = np.max(np.abs(x), axis=1)[:, None]
        moved[c] = x + resolution * size * rng.uniform(-1.0, 1.0, x.shape)
    return dataclasses.replace(rec, R_WB=None, **moved)
