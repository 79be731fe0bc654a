"""Least squares of the joint-torque base parameters over a log too long to hold its regressor: a
1 kHz arm over 15 minutes is 900,000 samples, whose regressor with friction (7 joints, 98 columns)
would take 4.9 GB. The samples are taken in blocks of CHUNK: each block's regressor, batched over
its samples (harness/model/regressor.py) and laid out joint by joint with samples last, is folded into
the normal equations (W^T W, W^T y), each joint's rows over the columns that can move its torque,
in a second thread while the next block is evaluated. Memory: two blocks' regressors (90 MB) and a
p^2 matrix. Measured on a 2-core virtual machine (README, "Speed"): 0.9 to 1.2 times the time of
Pinocchio's regressor called sample by sample from Python alone.

Normal equations square the condition number of the column-scaled regressor (18.5 on the test's
Panda motion, 1e2 to 1e3 on others), so the estimate keeps round-off times its square: within 1e-12
of the dense QR fit of harness/identify/estimators.py in the torque each parameter moves
(tests/test_streaming.py), far below any measured log's noise. The standard deviations are the
classical sigma^2 (W^T W)^-1 with sigma^2 the residual variance: white, equal noise on every row
(the dense fit's cluster-robust ones need every residual, a second pass over the log).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import cho_factor, cho_solve

from harness.engines.pinocchio import PinocchioModel
from harness.identify.torque_id import BaseParameters, regressor, regressor_by_joint

CHUNK = 8192  # samples per block: its regressor (7 joints, 98 columns) is 45 MB


@dataclass(frozen=True, eq=False)
class LongFit:
    beta: np.ndarray  # (r,) base parameters
    std: np.ndarray  # (r,) classical standard deviations
    rms_residual: float  # N m, over every row
    samples: int


def _moving_columns(pm: PinocchioModel, n: int, with_friction: bool) -> list[np.ndarray]:
    """Per joint, the regressor columns that can move its torque: nonzero at some of 16 random states."""
    rng = np.random.default_rng(0)
    W = regressor(pm, *rng.uniform(-2.0, 2.0, (3, 16, n)), with_friction).reshape(16, n, -1)
    return [np.flatnonzero(np.any(W[:, i, :] != 0, axis=0)) for i in range(n)]


def _gram(pm: PinocchioModel, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, tau: np.ndarray,
          with_friction: bool, chunk: int) -> tuple[np.ndarray, np.ndarray, float]:
    """W^T W, W^T y and y^T y of the samples given, one block's regressor at a time (module docstring).
    Joint by joint, over the columns that can move its torque: the inertial ones from the first that
    does (for joint i of a chain, the bodies it carries) and its own drive's (for 7 joints, a quarter
    of the products of the whole W^T W). A block is folded in a second thread while the next one is
    evaluated: both are large array operations, during which numpy lets go of the interpreter."""
    from concurrent.futures import ThreadPoolExecutor

    n = q.shape[1]
    p = 14 * n if with_friction else 10 * n
    WtW, Wty, yy = np.zeros((p, p)), np.zeros(p), np.zeros(1)
    # two blocks: one evaluated while the other is folded; reused, the entries written are the same every time
    buffers = [np.zeros((n, p, min(chunk, len(q)))) for _ in range(2)]
    # joint i's rows: its inertial columns from the first that moves it (none before it does; for a
    # chain, the bodies it carries), and its own drive's four columns (the other drives' are zero there)
    inertial = 10 * n
    blocks = [(slice(min(int(cols.min()), inertial), inertial),
               slice(inertial + 4 * i, inertial + 4 * i + 4) if with_friction else None)
              for i, cols in enumerate(_moving_columns(pm, n, with_friction))]

    def fold(W: np.ndarray, y: np.ndarray) -> None:
        for i, (I, F) in enumerate(blocks):
            X = W[i, I]  # (columns, samples), a contiguous view: BLAS reads it in place
            WtW[I, I] += X @ X.T
            Wty[I] += X @ y[:, i]
            if F is not None:
                D = W[i, F]
                cross_terms = X @ D.T
                WtW[I, F] += cross_terms
                WtW[F, I] += cross_terms.T
                WtW[F, F] += D @ D.T
                Wty[F] += D @ y[:, i]
        yy[0] += float(np.sum(y * y))

    with ThreadPoolExecutor(max_workers=1) as pool:
        pending = None
        for b, start in enumerate(range(0, len(q), chunk)):
            rows = slice(start, start + chunk)
            W = buffers[b % 2][:, :, :len(q[rows])]
            regressor_by_joint(pm, q[rows], qd[rows], qdd[rows], with_friction, out=W)
            if pending is not None:
                pending.result()  # the fold of the block before: its buffer is the next one written
            pending = pool.submit(fold, W, tau[rows])
        if pending is not None:
            pending.result()
    return WtW, Wty, float(yy[0])


def fit_long(pm: PinocchioModel, base: BaseParameters, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray,
             tau: np.ndarray, with_friction: bool = False, chunk: int = CHUNK) -> LongFit:
    """Ordinary least squares of the base parameters from the joint data (N, n) each, block by block
    (module docstring). Every column's products are accumulated, W^T W, W^T y and y^T y: the base
    columns are picked and scaled once at the end ((W S)^T (W S) = S W^T W S), so no block is copied.
    The products run on one BLAS thread: they are small, and OpenBLAS's second thread made the whole
    fit 1.5 times slower on two cores (threadpoolctl sets it)."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1, user_api="blas"):
        WtW, Wty, yy = _gram(pm, q, qd, qdd, tau, with_friction, chunk)
    cols = base.independent
    r = len(cols)
    A, b = WtW[np.ix_(cols, cols)], Wty[cols]
    d = np.sqrt(np.diag(A))  # the base columns' norms
    d = np.where(d > 0, d, 1.0)
    factor = cho_factor(A / np.outer(d, d))
    beta = cho_solve(factor, b / d) / d
    rows_total = len(q) * q.shape[1]
    rss = max(float(yy - 2 * beta @ b + beta @ A @ beta), 0.0)
    sigma2 = rss / max(rows_total - r, 1)
    std = np.sqrt(sigma2 * np.diag(cho_solve(factor, np.eye(r)))) / d
    return LongFit(beta, std, float(np.sqrt(rss / rows_total)), len(q))
