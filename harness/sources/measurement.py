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
                                    #   alone; it replaces what joints gives tau)

Noise on a value x has standard deviation sqrt(absolute^2 + (relative |x|)^2), independently per
component and sample; angles and positions take absolute noise only (their zero is arbitrary).
Order, as on a bench: sampling (`every`), then noise and rounding of each reading, then
differentiation of what was read. With `differentiate`, every acceleration channel is re-derived:
the joint velocities and accelerations from the measured joint positions (as a controller reads
its encoders), the centre-of-mass accelerations from the measured positions, the accelerations of the inner joint
points from the points' positions p_W + A(theta) r_B (measured position and angles, r_B the body-
fixed arm from the centre of mass to the point, known from the model as a sensor's place on a
bench is), and the angular velocities and accelerations from the measured Cardano angles
(omega^(i) = D theta', omega'^(i) = D theta'' + D' theta', Eq. 33, which needs no inverse of D and
so passes gimbal lock), all by a cubic Savitzky-Golay filter over `filter_window` samples: exact
for cubic motion, and smoothing noise. On kr500_rail the error falls at second order with the step
(3 to 4 times per halving). Near gimbal lock of a body whose alpha and gamma then change fast (not
B1 of kr500_rail, whose angles stay smooth), its angle rates are large and the filter loses
accuracy: sample finer there.
Time and the gimbal flags are not measurements.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from harness.base.tomlio import Table
from harness.engines.recording import Recording
from harness.model.cardano import A_0i, D, D_dot

CHANNELS = ("q", "qd", "qdd", "tau", "F_W", "M_W", "p_W", "v_W", "theta", "a_W", "aO_W", "omega_W",
            "omegadot_W")
GROUPS = {
    "forces": ("F_W",), "moments": ("M_W",), "accelerations": ("a_W", "aO_W"), "angular_velocities": ("omega_W",),
    "angular_accelerations": ("omegadot_W",), "angles": ("theta",), "positions": ("p_W", "v_W"),
    "joints": ("q", "qd", "qdd", "tau"), "joint_torques": ("tau",),
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


def add_noise(rec: Recording, noise: dict[str, Noise], rng: np.random.Generator) -> dict[str, np.ndarray]:
    out = {}
    for group, n in noise.items():
        for c in GROUPS[group]:
            x = getattr(rec, c)
            std = np.sqrt(n.absolute**2 + (n.relative * x) ** 2)
            out[c] = x + std * rng.standard_normal(x.shape)
    return out


def savgol(x: np.ndarray, t: np.ndarray, window: int, deriv: int) -> np.ndarray:
    """The cubic Savitzky-Golay filter over `window` samples (its `deriv`-th derivative), along
    time: the one differentiator of every measured channel."""
    from scipy.signal import savgol_filter

    return savgol_filter(x, window, 3, deriv=deriv, delta=float(t[1] - t[0]), axis=0, mode="interp")


def differentiate(t: np.ndarray, q: np.ndarray, p_W: np.ndarray, theta: np.ndarray, window: int,
                  arm_O_B: np.ndarray) -> dict[str, np.ndarray]:
    """qd, qdd from joint positions; a_W, aO_W, omega_W, omegadot_W from positions and Cardano
    angles (cubic Savitzky-Golay). arm_O_B: (nb, 3) each body's arm from its centre of mass to its
    inner joint point O."""
    def sg(x: np.ndarray, k: int) -> np.ndarray:
        return savgol(x, t, window, k)

    theta_d, theta_dd = sg(theta, 1), sg(theta, 2)
    th = sg(theta, 0)
    Dm = D(th)
    omega_B = np.einsum("...ab,...b->...a", Dm, theta_d)
    omegadot_B = (np.einsum("...ab,...b->...a", Dm, theta_dd)
                  + np.einsum("...ab,...b->...a", D_dot(th, theta_d), theta_d))
    A = A_0i(th)
    pO_W = p_W + np.einsum("...ab,...b->...a", A_0i(theta), arm_O_B)  # the point where it was read
    return {"qd": sg(q, 1), "qdd": sg(q, 2), "a_W": sg(p_W, 2), "aO_W": sg(pO_W, 2),
            "omega_W": np.einsum("...ab,...b->...a", A, omega_B),
            "omegadot_W": np.einsum("...ab,...b->...a", A, omegadot_B)}


def measure(rec: Recording, m: Measurement, arm_O_B: np.ndarray | None = None) -> Recording:
    """What the test bench reports under the measurement conditions `m` (deterministic in m.seed).
    arm_O_B: (nb, 3) the arms of the inner joint points (RobotSpec.inner_joint_arms_B), needed to
    re-derive their accelerations when `m.differentiate`."""
    if m.ideal:
        return rec
    rng = np.random.default_rng(m.seed)
    # the bench samples; each reading then carries its noise and its resolution; derivatives come
    # from what was read
    rows = np.arange(0, len(rec.t), m.every)
    sampled = dataclasses.replace(rec, t=rec.t[rows], gimbal=rec.gimbal[rows], R_WB=None,
                                  **{c: getattr(rec, c)[rows] for c in CHANNELS})
    values = {c: getattr(sampled, c) for c in CHANNELS}
    values.update(add_noise(sampled, m.noise, rng))
    if m.significant_digits is not None:
        values = {c: round_significant(v, m.significant_digits) for c, v in values.items()}
    if m.encoder_resolution is not None:
        values["q"] = read_encoders(values["q"], m.encoder_resolution, rng)
    if m.differentiate:
        if arm_O_B is None:
            raise ValueError("measure: differentiating needs the arms of the inner joint points")
        values.update(differentiate(sampled.t, values["q"], values["p_W"], values["theta"], m.filter_window,
                                    arm_O_B))
    return dataclasses.replace(sampled, **values)


def dither(rec: Recording, m: Measurement, rng: np.random.Generator) -> Recording:
    """A recording as different from `rec` as the measurement allows: its noise drawn afresh, and
    every value moved by up to the rounding resolution times the largest value of its channel at
    that instant (an engine computes every body's quantities together, and a component that is zero
    in exact arithmetic comes out as round-off of that size, not as zero)."""
    values = {c: getattr(rec, c) for c in CHANNELS}
    values.update(add_noise(rec, m.noise, rng))
    for c, x in values.items():
        if x.ndim == 3:
            size = np.max(np.linalg.norm(x, axis=-1), axis=1)[:, None, None]
        else:
            size = np.max(np.abs(x), axis=1)[:, None]
        values[c] = x + m.resolution * size * rng.uniform(-1.0, 1.0, x.shape)
    return dataclasses.replace(rec, R_WB=None, **values)
