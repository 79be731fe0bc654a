"""Random joint states of a robot, for judging an algorithm away from any scripted motion (as
Pinocchio's own tests judge theirs): positions uniform within the joint limits, velocities and
accelerations uniform within given scales."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

DEFAULT_RANGE = {True: (-np.pi, np.pi), False: (-1.0, 1.0)}  # revolute (rad), prismatic (m): no limit given


def position_bounds(names: Sequence[str], revolute: Sequence[bool],
                    limits: dict[str, tuple[float, float]] | None) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi) per joint: its position limits, or +-pi rad (revolute) and +-1 m (prismatic) where it
    has none, they are not finite, or they leave no range (lower = upper: URDF's way of writing none)."""
    lo, hi = np.empty(len(names)), np.empty(len(names))
    for k, (name, rev) in enumerate(zip(names, revolute, strict=True)):
        lo[k], hi[k] = (limits or {}).get(name, DEFAULT_RANGE[bool(rev)])
        if not (np.isfinite(lo[k]) and np.isfinite(hi[k]) and lo[k] < hi[k]):
            lo[k], hi[k] = DEFAULT_RANGE[bool(rev)]
    return lo, hi


def motion_scale(x: np.ndarray) -> np.ndarray:
    """(n,) the largest |x| of each joint over a motion (N, n); a joint that does not move takes the
    largest of the others, and 1 where nothing moves."""
    s = np.max(np.abs(x), axis=0)
    fallback = s.max() if s.size and s.max() > 0 else 1.0
    return np.where(s > 0, s, fallback)


def random_states(lo: np.ndarray, hi: np.ndarray, qd_scale: np.ndarray, qdd_scale: np.ndarray, count: int,
                  seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(q, q', q''), each (count, n): q uniform in [lo, hi], q' in [-qd_scale, qd_scale], q'' in
    [-qdd_scale, qdd_scale], from numpy's default generator with `seed`."""
    rng = np.random.default_rng(seed)
    q = rng.uniform(lo, hi, (count, len(lo)))
    qd = rng.uniform(-1.0, 1.0, (count, len(lo))) * qd_scale
    qdd = rng.uniform(-1.0, 1.0, (count, len(lo))) * qdd_scale
    return q, qd, qdd
