"""Conditioning the data decide where the scenario does not: a low-pass cut-off for positions that carry
noise (a quantised encoder, a noisy sensor), and the decimation that goes with it.

Differentiating positions twice multiplies their noise by (2 pi f)^2 per derivative: a quantised encoder
at 5 kHz, differentiated unfiltered, gives accelerations of noise. The motion of an arm lives in a few
hertz; its noise is spread to the Nyquist frequency, all along the log. On the uniform grid of the
checked log, per joint:
- the motion's band f_m, the frequency below which BAND_ENERGY of the velocity's energy lies (Welch's
  spectrum of the positions' first differences, scipy.signal.welch);
- the noise's level: the median of |the velocity high-passed at NOISE_BAND x f_m| over the velocity's
  RMS. A median, so that a single kink (a gap bridged by interpolation) does not count: noise is there
  at every sample (a bench log of exact positions: 2e-10 to 9e-10, with a 50 ms gap bridged the same;
  the Staubli TX40's quantised encoders: 0.009 to 0.013).
Where some joint's level exceeds NOISY and no cut-off is given, the cut-off is CUTOFF_FACTOR x the
largest f_m and, where no decimation is given either, the filtered grid keeps about SAMPLES_PER_CUTOFF
samples per second per hertz of cut-off (decimate = rate // (SAMPLES_PER_CUTOFF x cut-off)). Positions
without noise are left unfiltered, as before. Either way the choice is recorded and said.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from harness.base.numerics import sampled
from harness.base.series import TimeSeries

BAND_ENERGY = 0.99  # the motion's band holds this share of the velocity's energy
NOISE_BAND = 10.0  # beyond this many times the motion's band, a velocity's energy is noise
NOISY = 1e-4  # a joint whose high-passed velocity's median is over this share of its RMS carries noise
CUTOFF_FACTOR = 3.0  # the default cut-off: this many times the motion's band
SAMPLES_PER_CUTOFF = 20.0  # the default decimation keeps this many samples per second per hertz of cut-off
WELCH_SECONDS = 4.0  # Welch's segments


def motion_band(kept: TimeSeries, rate: float) -> tuple[np.ndarray, np.ndarray]:
    """Per joint (the motion's band f_m in Hz, the noise's level: the module's docstring), on the log's
    rows resampled to `rate`."""
    from scipy.signal import butter, sosfiltfilt, welch

    grid = kept.t[0] + np.arange(int(np.floor((kept.t[-1] - kept.t[0]) * rate)) + 1) / rate
    v = np.diff(sampled(kept.t, kept.q, grid), axis=0) * rate
    n = kept.q.shape[1]
    if len(v) < 64:
        return np.zeros(n), np.zeros(n)
    f, P = welch(v, fs=rate, nperseg=min(len(v), int(WELCH_SECONDS * rate)), detrend="linear", axis=0)
    total = np.maximum(P.sum(axis=0), np.finfo(float).tiny)
    band = f[np.minimum(np.argmax(np.cumsum(P, axis=0) / total >= BAND_ENERGY, axis=0), len(f) - 1)]
    level = np.zeros(n)
    rms = np.sqrt(np.mean(v**2, axis=0))
    for j in np.flatnonzero((band > 0) & (NOISE_BAND * band < 0.45 * rate) & (rms > 0)):
        sos = butter(4, NOISE_BAND * band[j], btype="highpass", fs=rate, output="sos")
        level[j] = np.median(np.abs(sosfiltfilt(sos, v[:, j]))) / rms[j]
    return band, level


def resolve(source, kept: TimeSeries, rate: float):
    """The scenario's `[data]` with the conditioning the data decide (the module's docstring), and the
    record of the choice (None where the scenario's own stands)."""
    if source.cutoff is not None:
        return source, None
    band, noise = motion_band(kept, rate)
    if not np.any(noise > NOISY):
        return source, None
    cutoff = float(min(CUTOFF_FACTOR * np.max(band), 0.4 * rate))
    decimate = source.decimate if source.decimate_given else max(1, int(rate // (SAMPLES_PER_CUTOFF * cutoff)))
    record = {"cutoff_hz": cutoff, "decimate": decimate,
              "definition": f"no cutoff given, and the positions carry noise: the median of the velocity high-passed "
                            f"at {NOISE_BAND:g} x the motion's band (where {BAND_ENERGY:.0%} of its energy lies) is "
                            f"over {NOISY:g} of its RMS on some joint; the cutoff is {CUTOFF_FACTOR:g} x the largest "
                            "band"
                            + ("" if source.decimate_given else
                               f", the grid kept at about {SAMPLES_PER_CUTOFF:g} samples per second per hertz of "
                               "cutoff"),
              "motion_band_hz": [float(b) for b in band], "noise_level": [float(x) for x in noise]}
    return dataclasses.replace(source, cutoff=cutoff, decimate=decimate), record
