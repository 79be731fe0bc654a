"""Conditioning the data decide where the scenario does not: a low-pass cut-off where the accelerations
would carry noise (a quantised encoder, a noisy sensor, a clock that jitters), and the decimation that
goes with it.

Differentiating positions twice multiplies their noise by (2 pi f)^2 per derivative: a quantised encoder
at 5 kHz, differentiated unfiltered, gives accelerations of noise. Too low a cut-off is as wrong: the
torques are filtered with the positions, and a torque that turns sharply (Coulomb friction changing sign
with the velocity) smeared over 1 / f_c no longer matches the model at the filtered states (a bench arm
whose joints move below 1 Hz, with a Coulomb law over 0.02 rad/s: 6.7 % off its truth's torques held
out at a 3 Hz cut-off, 2.4 % at 20 Hz, 0.7 % at 50 Hz). So the cut-off is the highest the positions'
noise allows. On the uniform grid of the checked log (the training span's rows), per joint, from Welch's
spectra (scipy.signal.welch) of the velocities the accelerations are the differences of (the logged
velocities where the log has them, as the conditioning differentiates them; else the positions' first
differences) and of their differences:
- the motion's band f_m, the frequency below which BAND_ENERGY of the velocity's energy lies;
- the noise's level: the median of |the velocity high-passed at NOISE_BAND x f_m| over the velocity's
  RMS. A median, so that a single kink (a gap bridged by interpolation) does not count: noise is there
  at every sample (a bench log of exact positions: 2e-10 to 9e-10, with a 50 ms gap bridged the same;
  the Staubli TX40's quantised encoders: 0.009 to 0.013);
- the accelerations' noise level: the median of |the accelerations (the velocity's differences)
  high-passed at NOISE_BAND x f_m|, over GAUSSIAN_MEDIAN (the RMS of Gaussian noise of that median), over
  the RMS of the rest (the motion's accelerations); a median for the same reason;
- the noise's cut-off: the highest frequency f_c at which the acceleration's energy between NOISE_BAND x
  f_m and f_c (noise: the motion has none there) stays within ACCELERATION_NOISE^2 of the acceleration's
  energy below NOISE_BAND x f_m (the motion's), i.e. a filter at f_c lets through accelerations of noise
  of at most ACCELERATION_NOISE of the motion's RMS (measured, not modelled: the spectrum is read where
  it lies).
Where no cut-off is given and some joint's unfiltered accelerations carry noise (its level over NOISY, or
its accelerations' noise level over ACCELERATION_NOISE: a slow motion's accelerations carry more of a
small velocity noise than a fast one's), the cut-off is the lowest joint's noise cut-off, at least
CUTOFF_FACTOR x the largest f_m and at most MAX_CUTOFF of the grid's rate (the TX40 over its motion: 15
Hz; its whole run: 30 Hz; the bench arm above read through a 16-bit motor encoder: 49 Hz) and, where no
decimation is given either, the filtered grid keeps about SAMPLES_PER_CUTOFF samples per second per hertz
of cut-off (decimate = rate // (SAMPLES_PER_CUTOFF x cut-off)). A log whose accelerations carry no noise is left
unfiltered. Either way the choice is recorded and said. The Panda's log (a 1 kHz clock that jitters by
0.3 ms: its positions' differences are noise from 250 Hz up; its logged velocities' noise level 0.004 to
0.007) gets 5 Hz and every 9th sample: held out, 1.36 % (the data's README's 10 Hz: 1.37 %; unfiltered,
its accelerations differences of unfiltered velocities, 14.8 %; all judged on one conditioning of the
same rows, benchmarks/panda.py).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from harness.base.numerics import sampled
from harness.sources.log.raw import RawLog

BAND_ENERGY = 0.99  # the motion's band holds this share of the velocity's energy
NOISE_BAND = 10.0  # beyond this many times the motion's band, a velocity's energy is noise
NOISY = 1e-4  # a joint whose high-passed velocity's median is over this share of its RMS carries noise
ACCELERATION_NOISE = 0.01  # the default cut-off lets through accelerations of noise of this share of the motion's
CUTOFF_FACTOR = 3.0  # the default cut-off is at least this many times the motion's band
MAX_CUTOFF = 0.4  # and at most this share of the grid's rate
SAMPLES_PER_CUTOFF = 20.0  # the default decimation keeps this many samples per second per hertz of cut-off
WELCH_SECONDS = 4.0  # Welch's segments
GAUSSIAN_MEDIAN = 0.6745  # the median of |x| for x ~ N(0, 1): a median of |noise| over it is the noise's RMS


@dataclass(frozen=True)
class Spectra:
    """Per joint, what the positions say of their motion and their noise (the module's docstring)."""

    band: np.ndarray  # (n,) Hz, the motion's band f_m
    level: np.ndarray  # (n,) the noise's level
    acceleration_level: np.ndarray  # (n,) the unfiltered accelerations' noise over their motion's RMS
    noise_cutoff: np.ndarray  # (n,) Hz, the highest cut-off the noise allows (the grid's Nyquist if none)


def spectra(kept: RawLog, rate: float) -> Spectra:
    """The module's docstring, on the log's rows resampled to `rate`."""
    from scipy.signal import butter, sosfiltfilt, welch

    grid = kept.t[0] + np.arange(int(np.floor((kept.t[-1] - kept.t[0]) * rate)) + 1) / rate
    v = sampled(kept.t, kept.qd, grid) if kept.qd is not None else np.diff(sampled(kept.t, kept.q, grid), axis=0) * rate
    n = kept.q.shape[1]
    if len(v) < 64:
        return Spectra(np.zeros(n), np.zeros(n), np.zeros(n), np.full(n, rate / 2))
    segment = min(len(v) - 1, int(WELCH_SECONDS * rate))
    f, P = welch(v, fs=rate, nperseg=segment, detrend="linear", axis=0)
    total = np.maximum(P.sum(axis=0), np.finfo(float).tiny)
    band = f[np.minimum(np.argmax(np.cumsum(P, axis=0) / total >= BAND_ENERGY, axis=0), len(f) - 1)]
    level, acceleration_level = np.zeros(n), np.zeros(n)
    rms = np.sqrt(np.mean(v**2, axis=0))
    a = np.diff(v, axis=0) * rate
    for j in np.flatnonzero((band > 0) & (NOISE_BAND * band < 0.45 * rate) & (rms > 0)):
        sos = butter(4, NOISE_BAND * band[j], btype="highpass", fs=rate, output="sos")
        level[j] = np.median(np.abs(sosfiltfilt(sos, v[:, j]))) / rms[j]
        noise = sosfiltfilt(sos, a[:, j])
        motion_rms = np.sqrt(np.mean((a[:, j] - noise) ** 2))
        if motion_rms > 0:
            acceleration_level[j] = np.median(np.abs(noise)) / GAUSSIAN_MEDIAN / motion_rms
    _, Pa = welch(a, fs=rate, nperseg=segment, detrend="linear", axis=0)
    motion = f[:, None] <= NOISE_BAND * band
    allowed = ACCELERATION_NOISE**2 * np.sum(np.where(motion, Pa, 0.0), axis=0)
    passed = np.cumsum(np.where(motion, 0.0, Pa), axis=0)  # the noise a cut-off at f lets through
    noise_cutoff = np.array([f[passed[:, j] <= allowed[j]].max() for j in range(n)])
    return Spectra(band, level, acceleration_level, noise_cutoff)


def noisy(s: Spectra) -> bool:
    """Whether some joint's unfiltered accelerations carry noise (the module's docstring)."""
    return bool(np.any(s.level > NOISY) or np.any(s.acceleration_level > ACCELERATION_NOISE))


def resolve(source, kept: RawLog, rate: float):
    """The scenario's `[data]` with the conditioning the data decide (the module's docstring), and the
    record of the choice (None where the scenario's own stands). `kept`: the rows it may read (a log
    split by time: the training span's alone)."""
    if source.cutoff is not None:
        return source, None
    s = spectra(kept, rate)
    if not noisy(s):
        return source, None
    cutoff = float(min(max(np.min(s.noise_cutoff), CUTOFF_FACTOR * np.max(s.band)), MAX_CUTOFF * rate))
    decimate = source.decimate if source.decimate_given else max(1, int(rate // (SAMPLES_PER_CUTOFF * cutoff)))
    differentiated = "logged velocities" if kept.qd is not None else "positions' differences"
    record = {"cutoff_hz": cutoff, "decimate": decimate,
              "definition": f"no cutoff given, and the accelerations (differences of the {differentiated}) carry "
                            f"noise on some joint: the median of its velocity high-passed at {NOISE_BAND:g} x the "
                            f"motion's band, where {BAND_ENERGY:.0%} of its energy lies, over {NOISY:g} of its RMS, "
                            f"or the same of its accelerations (over {GAUSSIAN_MEDIAN:g}: an RMS) over "
                            f"{ACCELERATION_NOISE:g} of the RMS of the rest. The cutoff is the highest at which, on "
                            f"every joint, the accelerations' energy beyond {NOISE_BAND:g} x the band let through "
                            f"stays within ({ACCELERATION_NOISE:g})^2 of the energy below it, at least "
                            f"{CUTOFF_FACTOR:g} x the largest band and at most {MAX_CUTOFF:g} x the rate"
                            + ("" if source.decimate_given else
                               f"; the grid kept at about {SAMPLES_PER_CUTOFF:g} samples per second per hertz of "
                               "cutoff"),
              "differentiated": differentiated,
              "motion_band_hz": [float(b) for b in s.band], "noise_level": [float(x) for x in s.level],
              "acceleration_noise_level": [float(x) for x in s.acceleration_level],
              "noise_cutoff_hz": [float(x) for x in s.noise_cutoff],
              "read_from": {"t_start": float(kept.t[0]), "t_end": float(kept.t[-1])}}
    return dataclasses.replace(source, cutoff=cutoff, decimate=decimate), record
