"""Where a log is cut, and how far the conditioning of a sample reaches: the gaps of a raw log, its
stretches between them, and the guard band (the trim at both ends of every conditioned stretch, at the
gaps and at the split). Each number here is defined once; harness/base/numerics.py says what a gap is
in a log once conditioned (harness/base/series.py, `stretch_starts`). `source` is the scenario's
`[data]` (harness/sources/log/schema.py, DataSource)."""

from __future__ import annotations

import numpy as np

GAP_FACTOR = 2.0  # a raw log's step more than twice the median is irregular: counted, and bridged or cut
GAP_SPLIT = 5.0  # default: a step over five median steps splits the log into stretches
TRIM_PERIODS = 3.0  # default trim: three periods of the cut-off frequency
BRIDGE_PERIODS = 0.25  # with a low-pass filter, a step shorter than a quarter period of its cut-off is bridged


def split_step(source, median: float) -> float:
    """The longest step (s) the log is bridged across by interpolation; a longer one splits it. The
    scenario's `gap` median steps; by default GAP_SPLIT median steps, and with a low-pass filter at
    least a quarter period of its cut-off (interpolation over a shorter step changes nothing in the
    band the filter keeps: a 1 kHz log filtered at 10 Hz is bridged over 25 ms)."""
    if source.gap is not None:
        return source.gap * median
    return max(GAP_SPLIT * median, BRIDGE_PERIODS / source.cutoff if source.cutoff else 0.0)


def segments(t: np.ndarray, longest_step: float) -> list[np.ndarray]:
    """The rows of each stretch of a log (times t, increasing) without a step longer than
    `longest_step`, in time order."""
    cuts = np.flatnonzero(np.diff(t) > longest_step) + 1
    return [np.asarray(r) for r in np.split(np.arange(len(t)), cuts)]


def guard_band(source, rate: float) -> float:
    """How far a sample's conditioning reaches (s), and so what is trimmed at each end of every
    conditioned stretch: the scenario's `trim`; by default TRIM_PERIODS periods of the low-pass
    filter's cut-off (its transient), and without a filter two steps of the grid (the central
    differences' reach). Between the training span and the validation span lie twice this."""
    if source.trim is not None:
        return source.trim
    return TRIM_PERIODS / source.cutoff if source.cutoff else 2.0 / rate


def segment_record(t: np.ndarray, pieces: list[np.ndarray], source, median: float) -> dict:
    """results.json's `data.conditioning.segments`: where the log was cut, and its stretches."""
    return {"split_at_steps_over_s": split_step(source, median),
            "definition": "a step over split_at_steps_over_s splits the log (the scenario's `gap` median steps; "
                          f"by default {GAP_SPLIT:g} median steps, with a low-pass filter at least a quarter period of "
                          "its cut-off): each stretch is resampled, filtered, differentiated and trimmed on its own",
            "stretches": [{"t_start": float(t[r[0]]), "t_end": float(t[r[-1]]), "rows": len(r)} for r in pieces]}
