"""Friction chosen by the data: per joint the Coulomb smoothing velocity v_c and a friction family
(harness/model/friction.py, FAMILIES), each judged by how well the fit predicts held-out parts of
the training span.

The training span is cut in time into `folds` consecutive parts (blocked cross-validation: a log's
neighbouring samples are not independent, so each part is predicted by the fit on the others, less the
rows within the conditioning's reach of it on either side, `blocked_folds`: never by a fit that saw its
neighbours); the validation span is never seen. The least-squares fit of the
structural base parameters is nested in every trial: the columns the friction law does not touch
(the links' inertial parameters, each joint's rotor inertia and offset) are folded into per-part
normal equations once; a trial for joint j rewrites only joint j's friction columns, which act on
joint j's rows alone (_Normal), so that one trial costs O(N r) and K small solves rather than new
factorisations of the whole regressor. The figure judged is the held-out error of every joint,
||tau_pred - tau||_F / ||tau||_F over the training span: the joints share the base parameters, so a
law that helps one joint's rows by spoiling the shared parameters is caught on the others' rows.

Joint by joint (two passes, so that each choice sees the others'), every family is tried:
  - v_c searched over a logarithmic grid (and a sharp sign, v_c = 0), then refined between the best
    point's neighbours by a bounded scalar search in log v_c (_search);
  - Stribeck: v_s over its own grid at that v_c, then v_c searched again at the chosen v_s;
  - load-dependent: |tau_R| s with tau_R the rigid-body torque of the fit so far, the links' part of
    the base parameters (the fit is bilinear in it; its rigid torque is held while the joint's
    columns are tried).
The family chosen is the simplest whose held-out error is within one standard error of the best
family's (the one-standard-error rule of cross-validation, Hastie, Tibshirani and Friedman, The
Elements of Statistical Learning, 2nd ed., section 7.10): a richer law must earn its terms by more than
the scatter of the parts' errors. A smoothing velocity the model declares stands unless the data's
beats it by more than DECLARED_GAIN of the held-out error and one standard error (`_declared`).
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass, replace

import numpy as np
from scipy.linalg.lapack import dpotrf, dpotrs
from scipy.optimize import minimize, minimize_scalar

from harness.base.numerics import Folds, blocked_folds, consecutive_blocks, relative_residual_of_sums, sample_step
from harness.identify import filtered
from harness.identify.laws import Law, spring_positions
from harness.identify.torque_id import drive_column, links_weights
from harness.model import drives, friction
from harness.model.drives import Transmission
from harness.model.friction import EXTRA_KEYS, FAMILIES, JointFriction

VELOCITY_GRID = np.geomspace(1e-4, 1.0, 17)  # rad/s or m/s: v_c tried, and 0 (a sharp sign)
FLAT = 1e-4  # held-out errors within this (relative) of the best are the same to the data
UNDECIDED = 4  # that many velocities of a grid (three of its steps, a factor 10 on VELOCITY_GRID) as good: undecided
STRIBECK_GRID = np.geomspace(1e-3, 2.0, 12)  # v_s tried
PASSES = 2
REFINE_TOL = 1e-3  # in log v: a velocity to 0.1 %
REFINE_EVALUATIONS = 60  # trials of the joint (v_c, v_s) refinement
LOAD_ITERATIONS = 3  # fixed-point steps of a load-dependent law's rigid-body torque
MIN_FOLD = 50  # samples each part of the training span needs
SAMPLES_AT_A_TIME = 4096  # samples of the regressor read at a time (`_Normal`)
KEPT_COLUMNS = 64  # filtered friction columns a search keeps for reuse (`_LawColumns`)
GRAM_FLOOR = 1e-5  # a fold's squared error below this of its |tau|^2 is taken from its rows (_Normal.held_out_sse)
MAX_UNKNOWNS = 250  # base parameters and friction slots beyond which the choice is not tried (the Panda: 83)
DECLARED_GAIN = 0.02  # a model's declared v_c gives way only to one whose held-out error is 2 % lower (and more
# than one standard error over the parts): a declaration is information the data must clearly beat


@dataclass(frozen=True)
class FrictionLawConfig:
    """`[friction_law]`: `choose` (default true) the law per joint from the data, else the model's;
    `folds` the consecutive parts of the training span, each judged by the fit on the others;
    `families` those tried (viscous_coulomb always)."""

    choose: bool = True
    folds: int = 5
    families: tuple[str, ...] = tuple(FAMILIES)


@dataclass(frozen=True, eq=False)
class FrictionChoice:
    laws: tuple[Law, ...]  # per joint
    scores: tuple[dict[str, dict], ...]  # per joint, per family: the held-out error at its best velocities
    # (empty for a joint that never moved: it keeps the model's law)
    model_error: float  # the held-out error with the model's own law at every joint
    chosen_error: float  # the held-out error with the chosen laws
    folds: int
    tau_rigid: np.ndarray  # (N, n) the rigid-body torque of the chosen law's fit on the whole training span
    guard_s: float = 0.0  # the rows within this of a fold are left out of the fit that predicts it
    undecided: tuple = ()  # per joint, the plain law's v_c range the data cannot tell apart ((lo, hi) or None)

    def frictions(self, model: tuple[JointFriction, ...]) -> tuple[JointFriction, ...]:
        """The model's friction values with the chosen velocities (the coefficients are the fit's to find)."""
        return tuple(law.friction(f.armature, f.viscous, f.coulomb, f.offset)
                     for f, law in zip(model, self.laws, strict=True))


def _columns(law: Law, qd: np.ndarray, tau_rigid: np.ndarray, q: np.ndarray | None = None) -> np.ndarray:
    """(N, m): one joint's friction columns under `law`: q', s, then its family's terms (a spring's q)."""
    s = friction.coulomb_shape(qd[:, None], np.array([law.coulomb_velocity]))
    positions = None if q is None else q[:, None]
    extra = friction.extra_columns((law.shapes,), qd[:, None], tau_rigid[:, None], positions)[:, 0]
    return np.column_stack([qd, s[:, 0], *(extra[:, EXTRA_KEYS.index(k)] for k in law.terms)])


class _Normal:
    """The least-squares problem with every joint's friction columns replaceable, cross-validated over
    `folds` (Folds: consecutive slices of the training span, each with a guard): per piece i of the span
    the normal equations of its rows, M_i x = r_i, with the fixed columns G (the base parameters but each
    joint's viscous and Coulomb ones) folded once and each joint's friction columns in a slot of their
    own. The fit that predicts fold k solves (sum M - sum_{i left out} M_i) x = (the same of r) and
    predicts fold k's rows. Replacing joint j's columns rewrites its slot only: O(N r) per trial."""

    def __init__(self, rows_of, columns: np.ndarray, order: np.ndarray, link_part: tuple[np.ndarray, np.ndarray],
                 tau: np.ndarray, folds: Folds, slot: int, coupling: np.ndarray | None = None):
        """rows_of(samples) -> (len, n, c): the regressor's rows of those samples (`regressor_rows`), of
        which the fixed columns G are `columns`, read in the samples' `order` (time) SAMPLES_AT_A_TIME at
        a time; tau (N, n) in that order. Without a transmission, G is kept once, joint by joint beside
        the joint's torque (`by_joint`), and never whole: a long log's regressor is the largest thing a
        run holds, and the search need not hold it."""
        N, n = tau.shape
        # with a transmission, slot k holds motor k's columns, which reach joint j times coupling[k, j]
        # (N of harness/model/drives.py); None: slot j is joint j's own, on its rows alone
        self.coupling = coupling
        self.slot = slot  # friction columns a joint may have: q', s and the most terms of a law tried
        r = len(columns)
        self.n, self.r = n, r
        self.link_part = link_part  # the fixed columns that hold a link's parameters, the drive's share in each
        self.tau = tau
        self.folds, self.pieces, self.left_out = folds.folds, folds.pieces, folds.left_out
        p = r + slot * n
        self.M = np.zeros((len(self.pieces), p, p))
        self.rhs = np.zeros((len(self.pieces), p))
        # (N, r + 1) per joint: its rows' fixed columns and its torque; with a transmission, what motor k's
        # slot meets: the joints' rows' fixed columns and torques, weighted by N[k, j], and G3 (N, n, r)
        # the joints' rows themselves
        own = [np.empty((N, r + 1)) for _ in range(n)]
        for a in range(0, N, SAMPLES_AT_A_TIME):
            block = rows_of(order[a: a + SAMPLES_AT_A_TIME])
            for j, g in enumerate(own):
                g[a: a + len(block), :r] = block[:, j, columns]
        for j, g in enumerate(own):
            g[:, r] = tau[:, j]
        self.G3 = None if coupling is None else np.stack([g[:, :r] for g in own], axis=1)
        self.by_joint = own if coupling is None else [
            np.column_stack([np.einsum("tjr,j->tr", self.G3, w), tau @ w]) for w in coupling]
        for k, f in enumerate(self.pieces):  # each piece's G^T G and G^T tau, joint by joint
            for g in own:
                product = g[f].T @ g[f]
                self.M[k, :r, :r] += product[:r, :r]
                self.rhs[k, :r] += product[:r, r]
        # (K, P) 0/1: the pieces fold k is made of; (P,) each piece's |tau|^2
        self.in_fold = np.array([[f.start <= piece.start < f.stop for piece in self.pieces] for f in self.folds], float)
        self.tau_sq = np.array([float(np.sum(tau[f] ** 2)) for f in self.pieces])
        self.S = np.zeros((N, n, slot))  # each joint's (or motor's) friction columns, on its own rows
        if coupling is not None:
            self.overlap = coupling @ coupling.T  # (n, n): sum_j N[k, j] N[l, j]

    def fixed_torque(self, rows: slice, w: np.ndarray) -> np.ndarray:
        """(len, n): the fixed columns' torque G w on the joints' rows `rows` (w (r,))."""
        if self.G3 is not None:  # as one matrix: numpy loops over a stack's rows
            G = self.G3[rows]
            return (G.reshape(-1, self.r) @ w).reshape(G.shape[:2])
        w_and_no_torque = np.append(w, 0.0)  # a joint's rows hold its torque last: one product, no copy
        return np.column_stack([joint[rows] @ w_and_no_torque for joint in self.by_joint])

    def set(self, j: int, C: np.ndarray) -> None:
        """Joint j's (motor j's) friction columns C (N, m <= slot); the slot's unused columns stay zero,
        with a unit diagonal in the fitted folds' sum so that their unknowns are zero."""
        r, m, slot = self.r, C.shape[1], self.slot
        lo, at = r + slot * j, slice(r + slot * j, r + slot * (j + 1))
        self.M[:, :, at] = 0.0
        self.M[:, at, :] = 0.0
        self.rhs[:, at] = 0.0
        weight = 1.0 if self.coupling is None else self.overlap[j, j]
        shared = [] if self.coupling is None else [l for l in np.flatnonzero(self.overlap[j]) if l != j]
        with_tau = self.by_joint[j]  # (N, r + 1): the fixed columns on the joint's rows, and its torque
        B = np.stack([with_tau[f].T @ C[f] for f in self.pieces])  # (P, r + 1, m): G_j^T C and tau_j^T C
        D = np.stack([C[f].T @ C[f] for f in self.pieces])
        self.M[:, :r, lo: lo + m], self.M[:, lo: lo + m, :r] = B[:, :r], B[:, :r].transpose(0, 2, 1)
        self.M[:, lo: lo + m, lo: lo + m] = D if self.coupling is None else weight * D
        self.rhs[:, lo: lo + m] = B[:, r]
        idle = np.arange(lo + m, lo + slot)
        self.M[:, idle, idle] = 1.0 / len(self.pieces)
        for l in shared:  # a motor that shares a joint with this one: their columns meet on its rows
            cross = self.overlap[j, l] * np.stack([C[f].T @ self.S[f, l] for f in self.pieces])
            self.M[:, lo: lo + m, r + slot * l: r + slot * (l + 1)] = cross
            self.M[:, r + slot * l: r + slot * (l + 1), lo: lo + m] = cross.transpose(0, 2, 1)
        self.S[:, j, :m], self.S[:, j, m:] = C, 0.0

    def _solve(self, M: np.ndarray, rhs: np.ndarray) -> np.ndarray:
        """x of M x = rhs, batched over the leading axis, equilibrated, by LAPACK's Cholesky (potrf, potrs;
        numpy's batched solve would factor the triangles again by LU); where the columns are not
        independent (a joint that never reverses: |s| is its offset), the minimum-norm solution."""
        diag = np.diagonal(M, axis1=-2, axis2=-1)
        d = np.sqrt(np.where(diag > 0, diag, 1.0))
        Ms, b = M / d[..., :, None] / d[..., None, :], rhs / d
        flat_M, flat_b = Ms.reshape(-1, *Ms.shape[-2:]), b.reshape(-1, b.shape[-1])
        x = np.empty_like(flat_b)
        for k, (A, c) in enumerate(zip(flat_M, flat_b, strict=True)):
            L, info = dpotrf(A, lower=1, clean=0)
            if info:  # one system not positive definite: every one by its minimum-norm solution
                x = np.stack([np.linalg.lstsq(A_k, c_k, rcond=1e-13)[0]
                              for A_k, c_k in zip(flat_M, flat_b, strict=True)])
                break
            x[k] = dpotrs(L, c, lower=1)[0]
        return x.reshape(b.shape) / d

    def held_out_sse(self) -> np.ndarray:
        """(K,) the squared error of every fold, each predicted by the fit on the others: from the fold's
        normal equations, |tau_k|^2 - x.(2 r_k - M_k x), where that keeps its digits, else from the fold's
        rows (`_rows_sse`). The normal equations' form loses about 10 eps |tau_k|^2 (a difference of
        two sums of that size, each rounded to eps of it): at an error below
        GRAM_FLOOR |tau_k|^2 (a log the law fits closely, a bench log to round-off) the rows answer."""
        P, p = self.M.shape[:2]
        flat = self.M.reshape(P, p * p)
        fitted = 1.0 - self.left_out  # (K, P): the pieces each fold's fit reads
        x = self._solve((fitted @ flat).reshape(-1, p, p), fitted @ self.rhs)  # (K, p): fold k's fit
        M_k, r_k, tau_k = ((self.in_fold @ flat).reshape(-1, p, p), self.in_fold @ self.rhs,
                            self.in_fold @ self.tau_sq)
        sse = tau_k - np.einsum("kp,kp->k", x, 2 * r_k - np.einsum("kpq,kq->kp", M_k, x))
        for k in np.flatnonzero(~(sse > GRAM_FLOOR * tau_k)):
            sse[k] = self._rows_sse(self.folds[k], x[k])
        return sse

    def _rows_sse(self, f: slice, x: np.ndarray) -> float:
        """The squared error of the rows f predicted by the fit x, from the rows."""
        r, n = self.r, self.n
        drive = (self.S[f] * x[r:].reshape(n, self.slot)).sum(axis=-1)
        pred = self.fixed_torque(f, x[:r]) + (drive if self.coupling is None else drive @ self.coupling)
        residual = (pred - self.tau[f]).ravel()
        return float(residual @ residual)

    def rigid_torque(self) -> np.ndarray:
        """(N, n) the rigid-body torque of the fit on every fold."""
        g = self._solve(self.M.sum(0), self.rhs.sum(0))[: self.r]
        return self.fixed_torque(slice(None), links_weights(g, self.link_part))


def regressor_rows(W: np.ndarray, n: int):
    """`rows_of` of an array W (N n, c), the regressor with friction: samples -> (len, n, c)."""
    W3 = W.reshape(-1, n, W.shape[1])
    return lambda samples: W3[samples]


def choose(W, independent: np.ndarray, link_part: tuple[np.ndarray, np.ndarray], tau: np.ndarray,
           qd: np.ndarray, t: np.ndarray, model: tuple[JointFriction, ...], config: FrictionLawConfig,
           reach: float = 0.0, transmission: Transmission | None = None, columns=None,
           measured: np.ndarray | None = None, q: np.ndarray | None = None) -> FrictionChoice:
    """Each joint's friction law, chosen within the training span. W: (N n, 10 n + 4 n) the
    regressor with friction (harness/identify/torque_id.py), or a function of sample indices that
    gives their rows (len, n, 10 n + 4 n) (`regressor_rows`: a long log's regressor made a chunk of
    samples at a time, never whole), `independent` the base parameters'
    columns and `link_part` which hold a link's parameters and the drive's share in each
    (BaseParameters.link_part: the rigid-body torque of a load-dependent law); tau, qd: (N, n);
    t: (N,); `reach` (s) how far a sample's conditioning reaches, the guard around each fold
    (`blocked_folds`). With a `transmission` (harness/model/drives.py) the laws are the motors': each
    motor's columns at its own rates, reaching the joints through N, its load the motor's share of
    the rigid-body torque, N^-T tau_R. With a filtered span's `columns` (FilteredColumns), each law's
    nonlinear columns are filtered as the torques were (harness/identify/filtered.py). `measured` (n,)
    bool: the joints whose torque the log holds (harness/stages/log_model.py); an unmeasured joint's rows
    are W's and tau's zeros; a drive that reaches none of the measured joints (`drives_reaching`) keeps
    the model's law, its columns none, and a motor's columns are weighed on the measured joints' rows
    alone; q (N, n) the positions, a spring's column. Raises ValueError when the span is too short to cut."""
    N, n = tau.shape
    order = np.argsort(t, kind="stable")  # in time, so that each part is a slice (a view, not a copy)
    tau, qd, q = tau[order], qd[order], None if q is None else q[order]
    if min(f.stop - f.start for f in consecutive_blocks(N, config.folds)) < MIN_FOLD:
        raise ValueError(f"{N} training samples: too few for {config.folds} parts of at least {MIN_FOLD}")
    step = sample_step(t[order])
    folds = blocked_folds(N, config.folds, int(np.ceil(reach / step - 1e-9)) if reach > 0 and step > 0 else 0)
    laws = [Law.of(f) for f in model]  # the model's own, where the search starts
    declared = [f.coulomb_velocity for f in model]  # a model's smoothing velocity (0: none declared)
    # a joint's slot: q', s and the most terms of a law it may be given (a model's own may join families)
    slot = 2 + max(len(t) for t in [*(FAMILIES[f] for f in config.families), *(law.terms for law in laws)])
    unknowns = len(independent) + (slot - 2) * n
    if unknowns > MAX_UNKNOWNS:
        raise ValueError(f"{unknowns} unknowns with every joint's friction slot: over {MAX_UNKNOWNS}, the search "
                         f"(about {300 * n} trials of {config.folds} factorisations each) would take too long")
    law_shaped = {drive_column(n, j, key) for j in range(n) for key in ("viscous", "coulomb")}  # a law's columns
    kept = np.array([k for k, c in enumerate(independent) if c not in law_shaped])
    rows_of = regressor_rows(W, n) if isinstance(W, np.ndarray) else W
    measured = np.ones(n, dtype=bool) if measured is None else np.asarray(measured, dtype=bool)
    normal = _Normal(rows_of, independent[kept], order, tuple(x[kept] for x in link_part), tau, folds, slot,
                     None if transmission is None else transmission.N * measured)  # an unmeasured joint's: none

    def at_motor(x: np.ndarray) -> np.ndarray:  # a joint torque as its motors' share
        return x if transmission is None else transmission.motor_torques(x)

    qd, q = drives.at_drives(transmission, qd, spring_positions(q, "spring" in config.families, laws))
    columns_of = _LawColumns(qd, t[order], transmission, columns, q)
    moving = _searched(qd, reached := drives_reaching(measured, transmission))
    rigid = np.zeros((N, n))
    total = float(np.sum(tau**2))

    def place(j: int, law: Law) -> None:
        """Joint j's columns under `law`; a load-dependent law's |tau_R| s column from the rigid-body
        torque of the fit with it, iterated LOAD_ITERATIONS times towards a fixed point (the fit is
        bilinear in f_l and tau_R; the map contracts by about f_l, a few hundredths). tau_R is read
        from the base parameters that hold a link's inertia, less the drive's share in each (the
        model's rotor inertia where one is regrouped with a link's: BaseParameters.link_part). A fixed
        point need not be the bilinear fit's least-squares minimum; on the bench of
        tests/test_friction_law.py, Levenberg-Marquardt on the whole bilinear fit moved f_l by 1e-4 of
        itself, and the alternation is kept."""
        if not reached[j]:  # no measured row of its own: no column to place
            normal.set(j, np.zeros((N, 0)))
            return
        normal.set(j, columns_of(j, law, rigid[:, j]))
        if "load_coulomb" in law.terms:
            for _ in range(LOAD_ITERATIONS):
                normal.set(j, columns_of(j, law, at_motor(normal.rigid_torque())[:, j]))

    for j in range(n):
        place(j, laws[j])
    model_error = relative_residual_of_sums(normal.held_out_sse().sum(), total)
    scores: list[dict] = [{} for _ in range(n)]
    flat: list = [None] * n
    for sweep in range(PASSES):
        first = sweep == 0  # the first pass searches v_c over the whole grid; the next, around its choice
        for j in np.flatnonzero(moving):
            rigid = at_motor(normal.rigid_torque())

            def score(law: Law, j=j) -> float:
                place(j, law)
                return relative_residual_of_sums(normal.held_out_sse().sum(), total)

            undecided: list = []
            found = _families(score, laws[j], first, config.families, columns_of.v_s_floor[j], undecided)
            chosen = _simplest(found, normal, place, j, total)
            laws[j] = found[chosen][0]
            if first and undecided:  # the whole grid's range, found on the first pass
                flat[j] = undecided[0]
            scores[j] = {f: {"held_out_rel_error": e, "coulomb_velocity": law.coulomb_velocity,
                             **({"stribeck_velocity": law.stribeck_velocity} if f == "stribeck" else {})}
                         for f, (law, e) in found.items()}
            if declared[j] > 0:  # the model's own v_c stands unless the data's beats it clearly
                laws[j], scores[j]["declared"] = _declared(laws[j], found[chosen][1], declared[j], score, normal,
                                                           place, j, total)
            place(j, laws[j])
    chosen_error = relative_residual_of_sums(normal.held_out_sse().sum(), total)
    tau_rigid = np.empty_like(tau)
    tau_rigid[order] = normal.rigid_torque()
    return FrictionChoice(tuple(laws), tuple(scores), model_error, chosen_error, config.folds, tau_rigid,
                          folds.guard * step, tuple(flat))


def drives_reaching(measured: np.ndarray, transmission: Transmission | None) -> np.ndarray:
    """(drives,) bool: each drive whose torque reaches a measured joint (`measured` (n,) bool): the joint's
    own, or with a transmission a motor k with N[k, j] != 0 at some measured joint j."""
    if transmission is None:
        return np.asarray(measured, dtype=bool)
    return np.any(transmission.N[:, np.asarray(measured, dtype=bool)] != 0, axis=1)


def _searched(qd: np.ndarray, measured: np.ndarray) -> np.ndarray:
    """(n,) the joints (motors) whose law is searched: a joint that never moves faster than the smallest
    v_c tried shows nothing of its friction's shape, and an unmeasured one has no row of its own: either
    keeps the model's law."""
    return (np.max(np.abs(qd), axis=0, initial=0.0) > VELOCITY_GRID[0]) & measured


class _LawColumns:
    """A joint's (a motor's) friction columns under a law, at the velocities qd (N, n; the motors' with a
    transmission) in time order `t`: q', s and the law's family terms (`_columns`), or with a filtered
    span's `columns` (FilteredColumns) each nonlinear one filtered as the torques were
    (harness/identify/filtered.py), made once per joint, term and velocity and shared by the laws that
    use it. `v_s_floor` (n,): on a filtered log a Stribeck bump narrower in time than the filter
    resolves (1 / (2 pi f_c)) shows only its area; its v_s is kept above the velocity each drive sweeps
    in that time (median |q''|); 0 on an unfiltered log."""

    def __init__(self, qd: np.ndarray, t: np.ndarray, transmission: Transmission | None, columns,
                 q: np.ndarray | None = None):
        self.qd, self.t, self.transmission, self.columns, self.q = qd, t, transmission, columns, q
        # (joint, term, the velocities it turns over) -> its filtered column, the KEPT_COLUMNS last asked
        # for (a search's continuous velocities make a new one at almost every trial: kept all, 2,500
        # columns of the span's length; the Panda's search filters 2,548 columns instead of 2,464)
        self.made: OrderedDict = OrderedDict()
        self.v_s_floor = np.zeros(qd.shape[1]) if columns is None else (
            np.median(np.abs(np.gradient(qd, t, axis=0)), axis=0) / (2 * np.pi * columns.cutoff_hz))

    def term(self, j: int, law: Law, term: str) -> np.ndarray:
        if term == "stiffness":  # the positions themselves, as the linear columns are: no filter, no cache
            return self.q[:, j]
        key = (j, "coulomb" if term == "load_coulomb" else term,
               *(() if term == "viscous_asymmetry" else (law.coulomb_velocity,)),
               *((law.stribeck_velocity,) if term == "stribeck" else ()))
        if key in self.made:
            self.made.move_to_end(key)
        else:
            self.made[key] = filtered.drive_term(self.columns, self.t, law, j, self.transmission, key[1])
            if len(self.made) > KEPT_COLUMNS:
                self.made.popitem(last=False)
        return self.made[key]

    def __call__(self, j: int, law: Law, rigid_j: np.ndarray) -> np.ndarray:
        if self.columns is None:
            return _columns(law, self.qd[:, j], rigid_j, None if self.q is None else self.q[:, j])
        extra = [self.term(j, law, k) * (np.abs(rigid_j) if k == "load_coulomb" else 1.0) for k in law.terms]
        return np.column_stack([self.qd[:, j], self.term(j, law, "coulomb"), *extra])


def _families(score, last: Law, first: bool, families: tuple[str, ...], v_s_floor: float,
              undecided: list | None = None) -> dict:
    """One joint's search: {family: (its best law, its held-out error)}, v_c of the plain law over the
    whole grid (`first`) or around `last`, the joint's law so far; each richer family around that v_c;
    Stribeck's v_s over its grid (or around its last choice), no lower than `v_s_floor`, then v_c. The
    plain law's v_c range the data cannot tell apart, where they cannot (`_search`), into `undecided`."""
    found = {"viscous_coulomb": _search(score, Law("viscous_coulomb"), "coulomb_velocity",
                                        _grid(None if first else last.coulomb_velocity), undecided=undecided)}
    v_c = found["viscous_coulomb"][0].coulomb_velocity  # the richer families searched around it
    stribeck_grid = STRIBECK_GRID[STRIBECK_GRID >= v_s_floor]
    for family in (f for f in FAMILIES if f in families and f != "viscous_coulomb"):
        if family == "stribeck" and not len(stribeck_grid):
            continue  # every v_s tried is below what the filter resolves
        law = Law(family, v_c)
        if family == "stribeck":  # v_s at this v_c (over its grid, or around its last choice), then v_c
            again = not first and last.family == "stribeck"
            start = replace(last, coulomb_velocity=v_c) if again else law
            around = _around(last.stribeck_velocity, STRIBECK_GRID, 1)
            around = around[around >= v_s_floor]
            law, _ = _search(score, start, "stribeck_velocity", around if again and len(around) else stribeck_grid,
                             floor=v_s_floor)
        found[family] = _search(score, law, "coulomb_velocity", _grid(v_c))
        if family == "stribeck" and found[family][1] < found["viscous_coulomb"][1]:
            found[family] = _refine_both(score, *found[family], v_s_floor)  # v_c and v_s trade: refined together
    return found


def _simplest(found: dict, normal: _Normal, place, j: int, total: float) -> str:
    """The simplest family (FAMILIES' order) whose held-out error is within one standard error of the
    best's. The best's error r = sqrt(S / T), S = sum_k S_k over the K parts: S's standard error is
    sqrt(K) std(S_k), and r's, to first order, that over 2 sqrt(S T)."""
    best = min(found, key=lambda f: found[f][1])
    place(j, found[best][0])
    parts = normal.held_out_sse()
    S = float(parts.sum())
    se = np.sqrt(len(parts)) * float(np.std(parts, ddof=1)) / (2 * np.sqrt(S * total)) if S > 0 else 0.0
    return next(f for f in found if found[f][1] <= found[best][1] + se)


def _declared(law: Law, error: float, v_declared: float, score, normal: _Normal, place, j: int,
              total: float) -> tuple[Law, dict]:
    """The chosen `law` (held-out `error`) against the same law at the model's declared v_c: the
    declared velocity stands unless the chosen one's held-out error is lower by more than DECLARED_GAIN
    of it and by more than one standard error over the parts (as `_simplest`)."""
    kept = replace(law, coulomb_velocity=v_declared)
    at_declared = score(kept)
    parts = normal.held_out_sse()
    S = float(parts.sum())
    se = np.sqrt(len(parts)) * float(np.std(parts, ddof=1)) / (2 * np.sqrt(S * total)) if S > 0 else 0.0
    beaten = error < at_declared - max(se, DECLARED_GAIN * at_declared)
    return (law if beaten else kept), {"coulomb_velocity": v_declared, "held_out_rel_error": at_declared,
                                       "kept": not beaten}


def _refine_both(score, law: Law, error: float, v_s_floor: float = 0.0) -> tuple[Law, float]:
    """A Stribeck law's v_c and v_s refined together (Nelder-Mead in log v, from the coordinate
    searches' point; its simplex a quarter of a grid step wide): the two shapes overlap, and one
    velocity at a time stalls in the valley between them."""
    if law.coulomb_velocity <= 0:
        return law, error

    def at(x: np.ndarray) -> Law:
        return replace(law, coulomb_velocity=float(np.exp(x[0])),
                       stribeck_velocity=max(float(np.exp(x[1])), v_s_floor))

    x0 = np.log([law.coulomb_velocity, law.stribeck_velocity])
    step = np.log(VELOCITY_GRID[1] / VELOCITY_GRID[0]) / 4
    found = minimize(lambda x: score(at(x)), x0, method="Nelder-Mead",
                     options={"initial_simplex": np.array([x0, x0 + [step, 0.0], x0 + [0.0, step]]),
                              "xatol": REFINE_TOL, "fatol": 0.0, "maxfev": REFINE_EVALUATIONS})
    return (at(found.x), float(found.fun)) if found.fun < error else (law, error)


def _grid(v: float | None) -> np.ndarray:
    """The smoothing velocities tried: the whole grid and a sharp sign (v None), or five around v
    (v > 0, one grid step apart), or a sharp sign and the grid's two smallest (v = 0)."""
    if v is None:
        return np.concatenate([[0.0], VELOCITY_GRID])
    if v == 0:
        return np.concatenate([[0.0], VELOCITY_GRID[:2]])
    return _around(v, VELOCITY_GRID, 2)


def _around(v: float, grid: np.ndarray, steps: int) -> np.ndarray:
    """2 steps + 1 velocities about v, `grid`'s step apart."""
    return v * (grid[1] / grid[0]) ** np.arange(-steps, steps + 1.0)


def _search(score, law: Law, key: str, grid: np.ndarray, floor: float = 0.0,
            undecided: list | None = None) -> tuple[Law, float]:
    """The best velocity `key` (coulomb_velocity or stribeck_velocity) for `law` over `grid`, then,
    where the best is not a sharp sign, refined between its neighbours in log v by a bounded scalar
    search (Brent's, to REFINE_TOL): on a log that the law fits closely the held-out error is sharp
    at its minimum, and a parabola through three grid points misses it. Where the held-out errors are
    flat (UNDECIDED or more of the grid's velocities within FLAT of the best), the data cannot tell the
    velocity: the middle in log v of those velocities is taken, not the grid's edge the smallest error
    happens to sit at, and their range appended to `undecided`."""
    values = [score(replace(law, **{key: float(v)})) for v in grid]
    i = int(np.argmin(values))
    best_v, best = float(grid[i]), values[i]
    near = [float(v) for v, e in zip(grid, values, strict=True) if v > 0 and e <= best * (1.0 + FLAT)]
    if len(near) >= UNDECIDED:
        middle = float(np.sqrt(min(near) * max(near)))
        if undecided is not None:
            undecided.append((min(near), max(near)))
        return replace(law, **{key: middle}), score(replace(law, **{key: middle}))
    if best_v > 0:
        lo = grid[i - 1] if i > 0 and grid[i - 1] > 0 else max(best_v / 2, floor) if floor < best_v else best_v
        hi = grid[i + 1] if i < len(grid) - 1 else best_v * 2
        found = minimize_scalar(lambda x: score(replace(law, **{key: float(np.exp(x))})),
                                bounds=(np.log(lo), np.log(hi)), method="bounded", options={"xatol": REFINE_TOL})
        if found.fun < best:
            best_v, best = float(np.exp(found.x)), float(found.fun)
    return replace(law, **{key: best_v}), best
