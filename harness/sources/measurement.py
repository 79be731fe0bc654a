"""Measurement conditions, applied between the recording (the truth) and what consumes it.

A scenario's `[measurement]` table, every key optional:

    significant_digits = 7          # round every measured channel (the paper's ADAMS output)
    encoder_resolution = 2e-5       # joint positions read in counts of this size (rad or m), the
                                    #   counts' zero drawn within a count per measurement
    seed = 1                        # noise is drawn from this seed: the same seed, the same data
    every = 1                       # measure every k-th output step only
    differentiate = false           # accelerations from measured positions and angles (below)
    filter_window = 7               # Savitzky-Golay window (odd number of samples), cubic
    [measurement.noise.forces]      # Gaussian, per group: forces, moments, accelerations,
    relative = 0.01                 #   angular_velocities, angular_accelerations, angles,
    absolute = 0.0                  #   positions, joints (q, q', q'', tau), joint_torques (tau
                                    #   alone; it replaces what joints gives tau), base_wrench (the
                                    #   world's wrench on a floating base the bench moves),
                                    #   contact_wrenches (each [[contacts]]'s force and moment)

Noise on a value x has standard deviation sqrt(absolute^2 + (relative |x|)^2), independently per
component and sample; angles and positions take absolute noise only (their zero is arbitrary).
Order, as on a bench: sampling (`every`), then noise and rounding of each reading, then
differentiation of what was read. With `differentiate`, the joint velocities and accelerations
are re-derived from the measured joint positions (as a controller reads its encoders) and the
centre-of-mass accelerations from the measured positions, by a cubic Savitzky-Golay filter over
`filter_window` samples (`savgol`): exact for cubic motion, and smoothing noise. Angular
velocities and accelerations are read as a gyroscope reads them. Orientations (R_WB) are passed
on as recorded: the `angles` group is for a study that reads the bodies' orientation as angles
and measures them itself (with what it derives from them, from a stream of its own,
`study_stream`). Time is not a measurement.
"""

from __future__ import annotations

import dataclasses
import zlib
from dataclasses import dataclass, field

import numpy as np

from harness.base.series import TimeSeries
from harness.base.tomlio import Table

CHANNELS = ("q", "qd", "qdd", "tau", "F_W", "M_W", "p_W", "v_W", "a_W", "omega_W", "omegadot_W", "base_wrench_W",
            "contact_F_W", "contact_M_W")
GROUPS = {
    "forces": ("F_W",), "moments": ("M_W",), "accelerations": ("a_W",), "angular_velocities": ("omega_W",),
    "angular_accelerations": ("omegadot_W",), "angles": (), "positions": ("p_W", "v_W"),
    "joints": ("q", "qd", "qdd", "tau"), "joint_torques": ("tau",), "base_wrench": ("base_wrench_W",),
    "contact_wrenches": ("contact_F_W", "contact_M_W"),
}

ABSOLUTE_ONLY = ("angles", "positions")  # their size says nothing of how well they are read


@dataclass(frozen=True)
class Noise:
    relative: float = 0.0
    absolute: float = 0.0


@dataclass(frozen=True)
class Measurement:
    significant_digits: int | None = None  # None: the engine's double precision
    encoder_resolution: float | None = None  # joint positions quantised to this count (rad or m)
    noise: dict[str, Noise] = field(default_factory=dict)  # group -> noise
    seed: int = 0
    every: int = 1
    differentiate: bool = False
    filter_window: int = 7

    @property
    def ideal(self) -> bool:
        return (self.significant_digits is None and not any(n.relative or n.absolute for n in self.noise.values())
                and self.every == 1 and not self.differentiate and self.encoder_resolution is None)

    @property
    def resolution(self) -> float:
        """Largest relative error of one value from rounding: half a unit in the last kept digit,
        or the double-precision unit round-off of the engine."""
        if self.significant_digits is None:
            return float(np.finfo(float).eps)
        return 0.5 * 10.0 ** (1 - self.significant_digits)

    def with_seed(self, seed: int) -> Measurement:
        return dataclasses.replace(self, seed=seed)

    def scaled(self, factor: float) -> Measurement:
        """The same conditions with every noise level multiplied by `factor`."""
        return dataclasses.replace(self, noise={g: Noise(n.relative * factor, n.absolute * factor)
                                                for g, n in self.noise.items()})

    def describe(self) -> dict:
        return {"significant_digits": self.significant_digits, "encoder_resolution": self.encoder_resolution,
                "seed": self.seed, "every": self.every,
                "differentiate": self.differentiate, "filter_window": self.filter_window,
                "noise": {g: {"relative": n.relative, "absolute": n.absolute} for g, n in self.noise.items()}}


def read_measurement(t: Table) -> Measurement:
    digits = t.integer("significant_digits", minimum=1) if t.has("significant_digits") else None
    noise = {}
    if t.has("noise"):
        nt = t.table("noise")
        for group in list(nt.data):
            if group not in GROUPS:
                raise nt.error(group, f"unknown channel group (groups: {', '.join(GROUPS)})")
            g = nt.table(group)
            if group in ABSOLUTE_ONLY and g.has("relative"):
                raise g.error("relative", f"{group} take absolute noise only: an error relative to an angle or a "
                                          "position depends on where its zero is (a body turned by 17 rad is read "
                                          "no worse than one at rest)")
            noise[group] = Noise(g.number("relative", default=0.0, nonnegative=True),
                                 g.number("absolute", default=0.0, nonnegative=True))
            g.finish()
        nt.finish()
    encoder = t.number("encoder_resolution", positive=True) if t.has("encoder_resolution") else None
    m = Measurement(digits, encoder, noise, t.integer("seed", default=0, minimum=0),
                    t.integer("every", default=1, minimum=1), t.boolean("differentiate", default=False),
                    t.integer("filter_window", default=7, minimum=5))
    if m.filter_window % 2 == 0:
        raise t.error("filter_window", f"must be odd, got {m.filter_window}")
    t.finish()
    return m


def round_significant(x: np.ndarray, digits: int) -> np.ndarray:
    """Round to `digits` significant decimal digits (to within one unit in the last place)."""
    x = np.asarray(x, dtype=float)
    ax = np.abs(x)
    ok = np.isfinite(x) & (ax > 1e-290)  # below that the scale would overflow; leave it
    exponent = np.floor(np.log10(np.where(ok, ax, 1.0)))
    scale = 10.0 ** (digits - 1 - exponent)
    return np.where(ok, np.round(x * scale) / scale, x)


def read_encoders(q: np.ndarray, resolution: float, rng: np.random.Generator) -> np.ndarray:
    """Joint positions read in counts of `resolution`: an encoder's zero falls anywhere within a
    count (drawn per joint and measurement), so two measurements of one motion differ in their
    quantisation error as two robots would."""
    zero = rng.uniform(0.0, resolution, q.shape[-1])
    return np.round((q - zero) / resolution) * resolution + zero


def channels(rec: TimeSeries) -> dict[str, np.ndarray]:
    """The measured channels `rec` has (CHANNELS; a floating base's wrench only where the bench moved it, its
    contacts' where it stands on them)."""
    return {c: getattr(rec, c) for c in CHANNELS if getattr(rec, c) is not None}


def add_noise(rec: TimeSeries, noise: dict[str, Noise], rng: np.random.Generator) -> dict[str, np.ndarray]:
    """Each channel of `rec` that a noise group names, with its noise drawn from `rng`."""
    return add_noise_to(channels(rec), GROUPS, noise, rng)


def add_noise_to(values: dict[str, np.ndarray], groups: dict[str, tuple[str, ...]], noise: dict[str, Noise],
                 rng: np.random.Generator) -> dict[str, np.ndarray]:
    """`values` (channel -> array) with the noise of each group in `noise` added to the channels
    `groups` gives it, in the order of `noise` (the scenario's): standard deviation
    sqrt(absolute^2 + (relative |x|)^2), independently per component and sample."""
    out = {}
    for group, n in noise.items():
        for c in (c for c in groups.get(group, ()) if c in values):
            x = values[c]
            std = np.sqrt(n.absolute**2 + (n.relative * x) ** 2)
            out[c] = x + std * rng.standard_normal(x.shape)
    return out


def savgol(x: np.ndarray, t: np.ndarray, window: int, deriv: int) -> np.ndarray:
    """The cubic Savitzky-Golay filter over `window` samples (its `deriv`-th derivative), along
    time: the one differentiator of every measured channel."""
    from scipy.signal import savgol_filter

    return savgol_filter(x, window, 3, deriv=deriv, delta=float(t[1] - t[0]), axis=0, mode="interp")


def differentiate(t: np.ndarray, q: np.ndarray, p_W: np.ndarray, window: int) -> dict[str, np.ndarray]:
    """qd, qdd from joint positions; a_W from centre-of-mass positions (cubic Savitzky-Golay)."""
    return {"qd": savgol(q, t, window, 1), "qdd": savgol(q, t, window, 2), "a_W": savgol(p_W, t, window, 2)}


def study_stream(m: Measurement, name: str) -> np.random.Generator:
    """The random stream of the readings a study measures itself (`name` tells them apart): drawn
    from the measurement's seed, apart from the bench's own stream, so that what the study reads
    leaves what the core reads as it is."""
    return np.random.default_rng([m.seed, zlib.crc32(name.encode())])


def measure(rec: TimeSeries, m: Measurement) -> TimeSeries:
    """What the test bench reports under the measurement conditions `m` (deterministic in m.seed)."""
    if m.ideal:
        return rec
    rng = np.random.default_rng(m.seed)
    # the bench samples; each reading then carries its noise and its resolution; derivatives come
    # from what was read
    rows = np.arange(0, len(rec.t), m.every)
    sampled = rec.span(rows)
    values = channels(sampled)
    values.update(add_noise(sampled, m.noise, rng))
    if m.significant_digits is not None:
        values = {c: round_significant(v, m.significant_digits) for c, v in values.items()}
    if m.encoder_resolution is not None:
        values["q"] = read_encoders(values["q"], m.encoder_resolution, rng)
    if m.differentiate:
        values.update(differentiate(sampled.t, values["q"], values["p_W"], m.filter_window))
    return dataclasses.replace(sampled, **values)


def dither(rec: TimeSeries, m: Measurement, rng: np.random.Generator) -> TimeSeries:
    """A recording as different from `rec` as the measurement allows: its noise drawn afresh, and
    every value moved by up to the rounding resolution times the largest value of its channel at
    that instant (an engine computes every body's quantities together, and a component that is zero
    in exact arithmetic comes out as round-off of that size, not as zero)."""
    values = channels(rec)
    values.update(add_noise(rec, m.noise, rng))
    return dataclasses.replace(rec, **moved_by_resolution(values, m.resolution, rng))


def moved_by_resolution(values: dict[str, np.ndarray], resolution: float,
                        rng: np.random.Generator) -> dict[str, np.ndarray]:
    """Each channel (N, n) or (N, n, 3) moved by up to `resolution` times its largest value (or
    vector norm) at each instant, uniformly."""
    out = {}
    for c, x in values.items():
        if x.ndim == 3:
            size = np.max(np.linalg.norm(x, axis=-1), axis=1)[:, None, None]
        else:
            size = np.max(np.abs(x), axis=1)[:, None]
        out[c] = x + resolution * size * rng.uniform(-1.0, 1.0, x.shape)
    return out
