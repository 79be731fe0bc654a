"""Numbers every layer defines the same way, written once: relative errors and their floor, a series' sample step, the
relative residual of a fit (||tau_pred - tau||_F / ||tau||_F), column scaling of a regressor and its
equilibrated condition number, the classical RK4 tableau, consecutive blocks of samples, the normal
quantile of a 95 % interval, and how a number goes into results.json.

Relative error. A difference is reported relative to a scale that says how large the quantity
is where it is measured, never to the quantity at the same sample (a torque through zero would
make any error infinite):
- a joint quantity of a run: |a - b| / L_J, L_J the largest load the joint carries over the run
  (harness/stages/metrics.py, joint_load_scale);
- a parameter: |identified - true| / max(|true|, PARAMETER_FLOOR x the largest |true| of its set)
  (`parameter_scale`), since a parameter that is zero in truth has no size of its own;
- a joint position of a run: |q - q_ref| / the joint's range of motion over the run, no less than
  RANGE_FLOOR of the largest range among the joints of its kind (revolute or prismatic) nor than
  RANGE_FLOOR rad or m (`range_scale`): a joint that does not move (a passive hinge of a spatial loop
  that the motion leaves still, 3e-16 rad) has no range of its own to divide by.
0/0 (a joint that carries nothing) is NaN and is reported, not hidden.

Column scaling. Each regressor column is divided by its norm, so that a least-squares solve and a
condition number see the columns' directions, not their units. A column below ZERO_COLUMN of the
largest column's norm is round-off (a parameter with no effect on any torque, or an axis written
with twelve digits): it keeps scale 1, so that it stays negligible instead of being blown up to
look independent.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

PARAMETER_FLOOR = 1e-6  # relative errors of parameters near zero are taken against 1e-6 of the largest
ZERO_COLUMN = 1e-10  # a column below this fraction of the largest is round-off (see above)
RANGE_FLOOR = 1e-3  # a joint's range of motion is taken as at least this of its kind's largest, and 1 mrad or 1 mm
RK4_A = (0.5, 0.5, 1.0)  # the classical Runge-Kutta tableau: stage i + 1 from stage i's rates, that far into the step
RK4_B = (1 / 6, 1 / 3, 1 / 3, 1 / 6)  # and the four stages' weights
SHIFT_GAIN = 0.9  # a time shift of a channel (a torque's delay, a velocity's lag) is found where reading the channel
# that much later leaves at most 90 % of the residual at zero: a shift that explains less is noise's doing
PREDICTION_TIMESTEP = 0.001  # s: RK4 steps of a prediction (the log's torques read at every stage)
NORMAL_975 = 1.959963984540054  # the standard normal's 97.5 % quantile: a 95 % interval where no degrees of
# freedom are stated (an estimate's own intervals take Student's t: harness/identify/lstsq.py)


def relative_error(a: np.ndarray, b: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """|a - b| / scale, elementwise (scale broadcast); 0/0 is NaN, without a warning."""
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.abs(a - b) / scale


def largest_relative_difference(a: np.ndarray, ref: np.ndarray) -> float:
    """Largest |a - ref| over each column's largest |ref| ((N, m) each; a column that carries nothing, below
    1e-12 of the largest, skipped): two readings of the same torques, joint by joint."""
    scale = np.max(np.abs(ref), axis=0)
    scale = np.where(scale > 1e-12 * max(float(np.max(scale, initial=0.0)), 1e-300), scale, np.inf)
    return float(np.max(relative_error(a, ref, scale), initial=0.0))


def relative_residual(e: np.ndarray, reference: np.ndarray) -> float:
    """||e||_F / ||reference||_F: a fit's residual e (or predicted - measured) relative to what it fits,
    over every sample and joint at once (the figure published identifications quote). 0/0 is NaN."""
    with np.errstate(invalid="ignore", divide="ignore"):
        return float(np.linalg.norm(e) / np.linalg.norm(reference))


def relative_residual_of_sums(squared_error: float, squared_reference: float) -> float:
    """`relative_residual` from its two sums of squares, where they are gathered piece by piece (the
    folds of a cross-validation, joint by joint): sqrt(sum e^2 / sum reference^2)."""
    return float(np.sqrt(squared_error / squared_reference))


def parameter_scale(true: np.ndarray, floor: float = PARAMETER_FLOOR) -> np.ndarray:
    """What a parameter's error is relative to: |true|, at least `floor` of the largest |true|."""
    return np.maximum(np.abs(true), floor * np.max(np.abs(true), initial=0.0))


def sample_step(t: np.ndarray) -> float:
    """A series' sample step: the median of its time steps (s), 0 for fewer than two samples."""
    return float(np.median(np.diff(t))) if len(t) > 1 else 0.0


def range_scale(q: np.ndarray, revolute) -> np.ndarray:
    """(n,) what a joint's position error is relative to, from a run's positions `q` (N, n): each joint's
    range of motion, floored (the module docstring) at RANGE_FLOOR of the largest range among the
    joints of its kind (`revolute`, (n,) bool) and at RANGE_FLOOR (rad or m)."""
    span = np.ptp(q, axis=0)
    revolute = np.asarray(revolute, dtype=bool)
    kind_largest = np.array([np.max(span[revolute == r]) for r in revolute])
    return np.maximum(span, RANGE_FLOOR * np.maximum(kind_largest, 1.0))


def live_columns(norms: np.ndarray) -> np.ndarray:
    """(p,) bool: the columns whose norm is over ZERO_COLUMN of the largest (the others are round-off,
    or never moved by the trajectory)."""
    return norms > ZERO_COLUMN * np.max(norms, initial=0.0)


def column_scale(W: np.ndarray | SideBySide) -> np.ndarray:
    """(p,) each column's norm; 1 for a column that is not live (`live_columns`: left as it is, not
    divided by zero or blown up)."""
    s = W.column_norms() if isinstance(W, SideBySide) else np.linalg.norm(W, axis=0)
    return np.where(live_columns(s), s, 1.0)


ROWS_AT_A_TIME = 1 << 15  # rows of a tall matrix read or reduced at a time (`SideBySide`, `triangle`)


@dataclass(frozen=True, eq=False)
class SideBySide:
    """Column blocks side by side, [B_1 | B_2 | ...], never joined: each block an array or an array's
    columns `(array, columns)`; read a chunk of rows at a time (`A[a:b]`, a joined copy of those rows),
    multiplied by a vector, its columns' norms taken, without a copy of the whole (a long log's
    regressor is the largest thing a run holds: [W[:, base] | E] joined copies most of it again)."""

    blocks: tuple

    def _parts(self):
        for block in self.blocks:
            yield block if isinstance(block, tuple) else (block, None)

    @property
    def shape(self) -> tuple[int, int]:
        rows = next(self._parts())[0].shape[0]
        return rows, sum(B.shape[1] if columns is None else len(columns) for B, columns in self._parts())

    def __getitem__(self, rows: slice) -> np.ndarray:
        return np.column_stack([B[rows] if columns is None else B[rows][:, columns] for B, columns in self._parts()])

    def __matmul__(self, x: np.ndarray) -> np.ndarray:
        out, at = np.zeros(self.shape[0]), 0
        for B, columns in self._parts():
            width = B.shape[1] if columns is None else len(columns)
            if columns is None:
                out += B @ x[at: at + width]
            else:  # one product over every column of B: a column subset would copy it
                w = np.zeros(B.shape[1])
                w[columns] = x[at: at + width]
                out += B @ w
            at += width
        return out

    def column_norms(self) -> np.ndarray:
        """Each column's norm, its squares summed a chunk of rows at a time (|B|^2 of a whole block
        would be a copy of it)."""
        squares = np.zeros(self.shape[1])
        for a in range(0, self.shape[0], ROWS_AT_A_TIME):
            chunk = self[a: a + ROWS_AT_A_TIME]
            squares += np.einsum("ij,ij->j", chunk, chunk)
        return np.sqrt(squares)


def triangle(A: np.ndarray | SideBySide, y: np.ndarray, col: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """R, b = Q^T y and ||y - Q b|| of the column-scaled A / col = Q R (A an array or `SideBySide`; Q with
    orthonormal columns, R upper triangular, min(rows, p) x p): Householder QR of [A | y],
    ROWS_AT_A_TIME rows at a time, each chunk stacked under the triangle of those before (a tall
    matrix's rows reduced in pieces: only a chunk of A is ever copied, where one QR of the whole copies
    it twice and its Q once more; a long log's regressor is the largest thing a run holds). The last is
    the least-squares residual of y on A, read off the factorisation (no |y|^2 - |b|^2 cancellation):
    the part of y outside Q's columns, and where A's rank is short of p the part of b that R's columns
    do not reach (the minimum-norm solution's cut-off as numpy's for A itself)."""
    p = len(col)
    T = np.zeros((0, p + 1))
    for a in range(0, len(y), ROWS_AT_A_TIME):
        rows = np.column_stack([A[a: a + ROWS_AT_A_TIME], y[a: a + ROWS_AT_A_TIME]])
        rows[:, :p] /= col
        T = np.linalg.qr(np.vstack([T, rows]), mode="r")
    k = min(T.shape[0], p)
    R, b = T[:k, :p], T[:k, p]
    outside = float(abs(T[p, p])) if T.shape[0] > p else 0.0
    unreached = R @ np.linalg.lstsq(R, b, rcond=np.finfo(float).eps * max(len(y), p))[0] - b
    return R, b, float(np.hypot(outside, np.linalg.norm(unreached)))


def fit_residual(A: np.ndarray | SideBySide, y: np.ndarray) -> float:
    """||y - A x|| at the least-squares x: read off the QR of A's scaled columns (`triangle`), never
    from |y|^2 - |A x|^2. Relative to y it is `relative_residual`'s figure for a fit's own residual."""
    return triangle(A, y, column_scale(A))[2]


def equilibrated_singular_values(W: np.ndarray) -> np.ndarray:
    """The singular values of W with its columns scaled (`column_scale`), largest first."""
    return np.linalg.svd(W / column_scale(W), compute_uv=False)


def condition(sv: np.ndarray) -> float:
    """sigma_max / sigma_min of singular values sv, largest first (inf where the smallest is 0)."""
    with np.errstate(divide="ignore"):
        return float(sv[0] / sv[-1])


def equilibrated_condition_number(W: np.ndarray) -> float:
    """The condition number a least-squares solve of the column-scaled W meets (inf when a column is
    zero or dependent)."""
    return condition(equilibrated_singular_values(W))


def consecutive_blocks(n: int, count: int) -> list[slice]:
    """range(n) cut into `count` consecutive blocks of (nearly) equal length, in order."""
    edges = np.linspace(0, n, count + 1).round().astype(int)
    return [slice(int(a), int(b)) for a, b in itertools.pairwise(edges)]


def sampled(t: np.ndarray, x: np.ndarray, when: np.ndarray) -> np.ndarray:
    """A signal x (N, n) sampled at times t (N,), read at times `when` (any shape) by linear
    interpolation, column by column (into one array: a long log's columns are not held twice): (*when.shape, n)."""
    out = np.empty((*np.shape(when), x.shape[1]))
    for j in range(x.shape[1]):
        out[..., j] = np.interp(when, t, x[:, j])
    return out


def evenly_spaced(n: int, count: int) -> np.ndarray:
    """`count` indices spread evenly over range(n), from the first to the last (the first alone where
    count is 1), each rounded to the nearest and kept once: min(n, count) of them, ascending; none
    where n or count is 0. The rounded points never decrease, so a repeat is next to its twin."""
    if n < 1 or count < 1:
        return np.empty(0, dtype=int)
    x = np.linspace(0, n - 1, count).round().astype(int)
    return x[np.concatenate(([True], x[1:] != x[:-1]))]


def floats(v) -> list[float]:
    """An array as a flat list of Python floats, for JSON."""
    return [float(x) for x in np.ravel(v)]


def finite_or_null(x: float) -> float | None:
    """A number that may be meaningfully infinite or undefined (a condition number, the standard
    deviation of an undetermined parameter): null in the file, and not a fault of the run."""
    return float(x) if np.isfinite(x) else None


@dataclass(frozen=True, eq=False)
class Folds:
    """Blocked cross-validation with a guard (`blocked_folds`): the folds, each predicted by a fit that
    reads neither its rows nor those within `guard` rows of it."""

    folds: list[slice]  # each fold's rows, in time order: what is predicted and scored
    pieces: list[slice]  # the span cut into pieces, in order: each fold's first `guard` rows, its middle, its last
    left_out: np.ndarray  # (K, P) 0/1: the pieces the fit that predicts fold k does not read
    guard: int


def blocked_folds(N: int, count: int, guard: int) -> Folds:
    """range(N) cut into `count` consecutive folds (harness/base/numerics.py, consecutive_blocks), each
    into its first `guard` rows, its middle and its last `guard` rows; fold k is predicted by the fit on
    every piece but its own and its neighbours' `guard` rows next to it. A conditioned log's samples
    within the conditioning's reach of each other share filter inputs (harness/sources/log/segments.py,
    guard_band): without the guard, a fold's neighbours would carry part of it into its own fit."""
    folds = consecutive_blocks(N, count)
    if min(f.stop - f.start for f in folds) <= 2 * guard:
        raise ValueError(f"{N} training samples: {count} parts of at most {min(f.stop - f.start for f in folds)} "
                         f"cannot be held out with a guard of {guard} rows at each end")
    pieces, owner = [], []
    for k, f in enumerate(folds):
        for a, b in ((f.start, f.start + guard), (f.start + guard, f.stop - guard), (f.stop - guard, f.stop)):
            if b > a:
                pieces.append(slice(a, b))
                owner.append(k)
    owner = np.array(owner)
    left_out = np.zeros((count, len(pieces)))
    for k in range(count):
        for i, piece in enumerate(pieces):
            nearest = min(abs(piece.start - folds[k].stop), abs(folds[k].start - piece.stop))
            left_out[k, i] = owner[i] == k or nearest < guard
    return Folds(folds, pieces, left_out, guard)
