"""A span's regressor with friction as the fit reads it, held whole on a short log and made a chunk of
samples at a time wherever it is read on a long one.

The regressor W (N n, 14 n) of harness/identify/torque_id.py, with each drive's Coulomb column the
filtered one on a filtered log (harness/identify/filtered.py), is the largest thing a log's run holds:
1.4 GB for the 70 % training span of an hour at 100 Hz of a 7-joint arm. Over WHOLE_BYTES it is a
`RowsOnDemand`: the same rows, bit for bit, made SAMPLES_AT_A_TIME samples at a time where a row
range is read (`W[a:b]`) or a product taken (`W @ x`), which is all that harness.base.numerics'
SideBySide, triangle and the least squares read of it. Each read makes its rows again (about 1 us a
row of a 7-joint arm on a 2-core Xeon: 1.9 s for an hour's training span); the fit reads it a handful
of times.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from harness.engines.pinocchio import PinocchioModel
from harness.identify.torque_id import SAMPLES_AT_A_TIME, put_coulomb, regressor

WHOLE_BYTES = 256 << 20  # a span's regressor up to this size is held whole (the Panda log's training span: 7 MiB)


@dataclass(frozen=True, eq=False)
class RowsOnDemand:
    """The regressor with friction of the states (q, q', q'') (N, n) of `pm`, its Coulomb columns
    `coulomb` (N, m) where given (`put_coulomb`), made where it is read."""

    pm: PinocchioModel
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    coulomb: np.ndarray | None = None

    @property
    def shape(self) -> tuple[int, int]:
        n = self.q.shape[1]
        return len(self.q) * n, 14 * n

    def samples(self, a: int, b: int) -> np.ndarray:
        """(b - a, n, 14 n): the rows of samples a to b."""
        W3 = regressor(self.pm, self.q[a:b], self.qd[a:b], self.qdd[a:b], with_friction=True).reshape(
            -1, self.q.shape[1], self.shape[1])
        if self.coulomb is not None:
            put_coulomb(W3, self.coulomb[a:b], self.pm.transmission)
        return W3

    def __getitem__(self, rows: slice) -> np.ndarray:
        start, stop, step = rows.indices(self.shape[0])
        if step != 1:
            raise IndexError("rows are read as a range")
        n = self.q.shape[1]
        first, last = start // n, -(-stop // n)
        return self.samples(first, last).reshape(-1, self.shape[1])[start - first * n: stop - first * n]

    def __matmul__(self, x: np.ndarray) -> np.ndarray:
        products = [self.samples(a, a + SAMPLES_AT_A_TIME).reshape(-1, self.shape[1]) @ x
                    for a in range(0, len(self.q), SAMPLES_AT_A_TIME)]
        return np.concatenate(products) if products else np.zeros(0)

    def whole(self) -> np.ndarray:
        """The rows held whole (what a reader that needs them so takes)."""
        return self[0: self.shape[0]]


def span_regressor(pm: PinocchioModel, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray,
                   coulomb: np.ndarray | None = None) -> np.ndarray | RowsOnDemand:
    """The span's regressor with friction (N n, 14 n), its Coulomb columns `coulomb` (N, m) where given:
    an array up to WHOLE_BYTES, else RowsOnDemand."""
    N, n = q.shape
    if N * n * 14 * n * 8 > WHOLE_BYTES:
        return RowsOnDemand(pm, q, qd, qdd, coulomb)
    W = regressor(pm, q, qd, qdd, with_friction=True)
    if coulomb is not None:
        put_coulomb(W.reshape(N, n, -1), coulomb, pm.transmission)
    return W


def rows_by_sample(W: np.ndarray | RowsOnDemand, n: int):
    """(samples a to b) -> (b - a, n, 14 n): a span's regressor read a chunk of samples at a time, held
    or on demand."""
    if isinstance(W, RowsOnDemand):
        return W.samples
    W3 = W.reshape(-1, n, W.shape[1])
    return lambda a, b: W3[a:b]
