"""A log in several files joined on time: a robot's tools often write one file per topic or quantity
(positions, velocities, efforts), each row stamped by its own time column. The file holding the
positions is the reference (the encoders' clock); each other file's row for a reference row is the one
at the same time, or the nearest within half the reference's median step; a reference row some file has
no row for within that is dropped. What was joined exactly, what to the nearest (and its largest offset)
and what was dropped is the read step's record, and said on the terminal where it is not exact."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from harness.base.tomlio import InputError

MIN_JOINED = 10  # rows: fewer joined is no log (the files are not of one run, or not of one clock)


@dataclass(frozen=True)
class Join:
    """Which reference rows are kept (N,) and, per other file, its row for each kept one."""

    keep: np.ndarray
    rows: dict[Path, np.ndarray]
    record: dict
    warnings: list[str]


def _name(source: Path | str) -> str:
    """A file's name, or a bag's topic as it is."""
    return source.name if isinstance(source, Path) else source


def join_on_time(reference: Path | str, t_ref: np.ndarray, others: dict, column: str) -> Join:
    """Each file of `others` ({file: its times (M,)}, times in the same unit and origin as t_ref (N,))
    joined to the reference's rows: exactly, or to its nearest row within half the reference's median
    step (`column`, the time column's name, for the errors). A bag's topics join as files do, each named by
    its topic (a str) where a file is by its path."""
    steps = np.diff(t_ref)
    tolerance = 0.5 * float(np.median(steps[steps > 0])) if np.any(steps > 0) else 0.0
    keep = np.ones(len(t_ref), dtype=bool)
    nearest: dict[Path, np.ndarray] = {}
    offsets: dict[Path, np.ndarray] = {}
    for path, t in others.items():
        back = np.flatnonzero(np.diff(t) < 0)
        if back.size:
            raise InputError(path, column, f"row {back[0] + 3} goes back in time ({t[back[0] + 1]!r} after "
                                           f"{t[back[0]]!r}): a file joined on time must be in time order")
        after = np.clip(np.searchsorted(t, t_ref), 0, len(t) - 1)
        before = np.maximum(after - 1, 0)
        pick = np.where(np.abs(t[before] - t_ref) <= np.abs(t[after] - t_ref), before, after)
        offsets[path] = np.abs(t[pick] - t_ref)
        nearest[path] = pick
        keep &= offsets[path] <= tolerance
    if keep.sum() < MIN_JOINED:
        worst = max(others, key=lambda p: int(np.sum(offsets[p] > tolerance)))
        raise InputError(worst, column, f"{int(keep.sum())} rows of {_name(reference)} have a row of every file within "
                                        f"half a step ({tolerance:.3g} s): not the files of one run, or not of "
                                        "one clock (times in another unit or from another origin?)")
    record = {"reference": str(reference), "column": column, "tolerance_s": tolerance,
              "rows_of_reference": len(t_ref), "rows_kept": int(keep.sum()), "files": {}}
    warnings = []
    for path in others:
        off = offsets[path][keep]
        exact = int(np.sum(off == 0.0))
        record["files"][str(path)] = {"exact": exact, "nearest": int(len(off) - exact),
                                      "largest_offset_s": float(off.max()),
                                      "unmatched_rows_of_reference": int(np.sum(offsets[path] > tolerance))}
        if exact < len(off):
            warnings.append(f"{_name(path)} joined to {_name(reference)} on {column!r}: {len(off) - exact} of "
                            f"{len(off)} rows to the nearest within half a step (largest offset {off.max() * 1e3:.3g} "
                            "ms)")
    dropped = len(t_ref) - int(keep.sum())
    if dropped:
        alone = [_name(p) for p in others if np.any(offsets[p] > tolerance)]
        warnings.append(f"{dropped} of {len(t_ref)} rows of {_name(reference)} have no row of {', '.join(alone)} "
                        f"within half a step ({tolerance * 1e3:.3g} ms): dropped")
    return Join(keep, {p: nearest[p][keep] for p in others}, record, warnings)
