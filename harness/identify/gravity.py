"""The direction of gravity in the robot's base axes, read off a log's torques: a base mounted off level.

A scenario states gravity g_W (its `gravity`, the model's, or standard gravity along -z). A robot on a
table or a cart a few tenths of a degree off level feels it turned, g = exp([omega]) g_W with omega
perpendicular to g_W (a turn about g_W itself changes nothing), and every link's gravity torque with it.
The joint torques are linear in gravity (the gravity torque is the regressor at q' = q'' = 0 times the
same parameters, and the regressor there is linear in g), so that

    Y(q, q', q''; g) = Y_0 + sum_i g_i D_i,    Y_0 = Y(q, q', q''; 0),    D_i = Y(q, q', q''; e_i) - Y_0,

four regressors made once (LogModel.rows: a log's measured channels, a counterbalanced channel's without
gravity, a closed chain's through G^T). Only the links' mass and first-moment columns of D_i are not zero.
The least squares of the structural base parameters at any g is then read off one small triangle per fold:
the QR factor T of [Y_0 | D_x | D_y | D_z | tau] (rows reduced a chunk at a time), whose columns combine for
g as the regressor's do (variable projection: the parameters eliminated by least squares at each g, the two
angles of omega searched by Gauss-Newton from the declared direction).

Which gravity the fits use (`[data] tilt`): "declared" keeps the scenario's; "identified" takes the
torques' direction; "chosen" (the default) takes it only where the data demand it: on FOLDS contiguous
folds of the training span, each fold's torques predicted by the least squares of the others, with the
direction those others give, are DEMAND (relative) better than with the declared direction, the turn is
at most MAX_TILT, and at least SPREADS times its jackknife standard error (the turns the folds' others give
agree: an effect the model lacks, a channel's delay, can lower the folds' error with a turn that each part of
the span puts elsewhere). The validation span is never read. Floating bases are not turned here: their log
measures the base's orientation (harness/stages/floating_log.py).
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import pairwise

import numpy as np

from harness.base.numerics import column_scale, finite_or_null, relative_residual_of_sums

FOLDS = 5  # contiguous folds of the training span for the choice
DEMAND = 0.01  # the turned direction's folds' held-out relative error this much lower than the declared one's
SPREADS = 2.0  # the turn at least this many times its jackknife standard error over the folds: the data tell it
MAX_TILT = np.radians(5.0)  # a larger turn is not a mounting off level: the declared direction is kept, said
MIN_FOLD = 20  # samples: a fold of fewer is no test of a fit
SAMPLES_AT_A_TIME = 2048  # samples whose four regressors are made at once (a long log's rows never whole)
GENERIC_TURN = np.array([0.6, -0.8])  # rad: a direction of gravity no robot's axes single out (gravity_of)
TILT_ONLY_RANK = 1e-9  # a column at the declared gravity under this of the largest pivot: another's combination
ANGLE_TOL = 1e-9  # rad: a Gauss-Newton step this small ends the search over the turn's two angles
GAUSS_NEWTON_STEPS = 50


@dataclass(frozen=True, eq=False)
class Tilt:
    """The gravity a log's fits use and why (results.json's `log_identification.gravity`)."""

    mode: str  # [data] tilt: harness/sources/log/schema.py, TILT_CHOICES
    declared_W: np.ndarray  # (3,) m/s^2, the scenario's
    identified_W: np.ndarray  # (3,) the direction the training span's torques give, the declared magnitude
    chosen: bool  # the fits use identified_W
    folds_error: dict[str, float]  # "declared", "identified": the folds' held-out relative torque error
    training_error: dict[str, float]  # the same fitted and judged on the whole training span
    reason: str
    spread: float = float("nan")  # rad: the jackknife's standard error of the turn over the folds

    @property
    def gravity_W(self) -> np.ndarray:
        return self.identified_W if self.chosen else self.declared_W

    @property
    def angle(self) -> float:
        """rad: between the declared and the identified directions."""
        return angle_between(self.declared_W, self.identified_W)

    def describe(self) -> dict:
        return {"mode": self.mode, "used": [float(x) for x in self.gravity_W],
                "declared": [float(x) for x in self.declared_W],
                "identified": [float(x) for x in self.identified_W], "turned_deg": float(np.degrees(self.angle)),
                "chosen": self.chosen, "turn_spread_deg": finite_or_null(float(np.degrees(self.spread))),
                "folds_rel_error": self.folds_error,
                "training_rel_error": self.training_error, "reason": self.reason,
                "definition": "the direction of gravity in the base's axes the training span's torques give (the "
                              "least squares of the base parameters at each direction, the declared magnitude); "
                              f"'chosen' takes it where {FOLDS} contiguous folds of the training span, each "
                              "predicted by a fit on the others, are "
                              f"{100 * DEMAND:g} % better with it and the turn is within "
                              f"{np.degrees(MAX_TILT):g} degrees and at least {SPREADS:g} times its spread over the "
                              "folds (the jackknife's standard error of the turns each fold's others give)"}


def declared(gravity_W: np.ndarray, mode: str = "declared", reason: str = "as the scenario states it") -> Tilt:
    g = np.asarray(gravity_W, dtype=float)
    return Tilt(mode, g, g, False, {}, {}, reason)


def angle_between(a: np.ndarray, b: np.ndarray) -> float:
    """rad: the angle between two vectors (atan2 of |a x b| and a . b: exact near 0 and pi)."""
    return float(np.arctan2(np.linalg.norm(np.cross(a, b)), a @ b))


def turned(gravity_W: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """g = exp([k]) g_W, k = omega_1 u_1 + omega_2 u_2 (u_1, u_2 orthonormal, perpendicular to g_W): by
    Rodrigues' formula with k . g_W = 0, g_W cos|k| + (k / |k|) x g_W sin|k| (written out: the search calls it
    hundreds of times, where scipy's Rotation cost a third of the search)."""
    u1, u2 = _perpendicular(gravity_W)
    k = omega[0] * u1 + omega[1] * u2
    angle = float(np.linalg.norm(k))
    if angle == 0.0:
        return np.array(gravity_W, dtype=float)
    return gravity_W * np.cos(angle) + np.cross(k / angle, gravity_W) * np.sin(angle)


def _perpendicular(g: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    z = g / np.linalg.norm(g)
    a = np.eye(3)[int(np.argmin(np.abs(z)))]
    u1 = np.cross(z, a)
    u1 /= np.linalg.norm(u1)
    return u1, np.cross(z, u1)


def gravity_columns(n_links: int, independent: np.ndarray) -> np.ndarray:
    """Positions in `independent` (the base parameters' columns of the 14 n regressor) of the links' mass
    and first-moment columns (10 k + 0..3): the only ones gravity enters."""
    moved = {10 * k + c for k in range(n_links) for c in range(4)}
    return np.array([i for i, c in enumerate(independent) if int(c) in moved], dtype=int)


def fold_triangles(rows, tau: np.ndarray, independent: np.ndarray, moved: np.ndarray, folds: int) -> list[np.ndarray]:
    """Each fold's upper-triangular factor T of [Y_0 | D_x | D_y | D_z | tau] on the columns the fit reads
    (`independent`, 14 n indices; D_i on `moved` of them, positions in `independent`): `rows(i, sl)` gives
    the regressor (samples' rows, 14 n) at gravity 0 (i = None) or e_i for the samples `sl`; tau (N,
    channels) their torques; contiguous folds of the samples, each reduced a chunk at a time."""
    N = len(tau)
    edges = np.linspace(0, N, folds + 1).round().astype(int)
    out = []
    for a, b in pairwise(edges):
        T = None
        for s in range(a, b, SAMPLES_AT_A_TIME):
            sl = slice(s, min(s + SAMPLES_AT_A_TIME, b))
            Y0 = rows(None, sl)
            blocks = [Y0[:, independent]] + [(rows(i, sl) - Y0)[:, independent[moved]] for i in range(3)]
            M = np.column_stack([*blocks, tau[sl].ravel()])
            T = np.linalg.qr(M if T is None else np.vstack([T, M]), mode="r")
        out.append(T)
    return out


class _Folds:
    """The triangles of `fold_triangles` (the base parameters' columns of gravity in no special direction)
    and the least squares they give at any gravity. At the declared gravity g_0 some of those columns are
    another's combination or nothing (a first link's first moment about a vertical first axis): the
    `tilt_only` ones, found here by pivoted QR of the columns at g_0. A turned gravity g = g_0 + delta adds
    to them delta_i D_i, which vanishes with the turn; so that the residual is smooth in the turn, the
    turned model carries their turn's part as columns of their own, D_u1 and D_u2 (u the turn's axes:
    (delta x m c) of such a link spans the same columns for every turn), beside the columns at g."""

    def __init__(self, triangles: list[np.ndarray], r: int, moved: np.ndarray, g0: np.ndarray):
        self.T, self.r, self.moved = triangles, r, moved
        self.joined: dict[tuple[int, ...], np.ndarray] = {}
        from scipy.linalg import qr

        B0 = self._combined(self._stacked(list(range(len(triangles)))), g0)
        _, R, pivots = qr(B0 / column_scale(B0), mode="economic", pivoting=True)
        diagonal = np.abs(np.diag(R))
        rank = int(np.sum(diagonal > TILT_ONLY_RANK * diagonal[0])) if diagonal.size and diagonal[0] > 0 else 0
        dependent = set(pivots[rank:].tolist())
        self.tilt_only = np.array([k for k, c in enumerate(moved) if int(c) in dependent], dtype=int)  # in moved
        u = _perpendicular(g0)
        self.u = np.array(u)

    def _stacked(self, parts: list[int]) -> np.ndarray:
        key = tuple(parts)
        if key not in self.joined:
            self.joined[key] = np.linalg.qr(np.vstack([self.T[k] for k in parts]), mode="r")
        return self.joined[key]

    def system(self, parts: list[int], g: np.ndarray, turned: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """(B, t): the folds `parts` as one triangle (theirs stacked and reduced once), B theta - t the
        residual of the parameters theta at g (its norm the rows' residual's); with `turned`, the tilt-only
        columns' turn after them."""
        T = self._stacked(parts)
        B = self._combined(T, g)
        if turned and self.tilt_only.size:
            r, m = self.r, len(self.moved)
            D = [T[:, r + i * m: r + (i + 1) * m][:, self.tilt_only] for i in range(3)]
            B = np.hstack([B, *(sum(w[i] * D[i] for i in range(3)) for w in self.u)])
        return B, T[:, -1]

    def _combined(self, T: np.ndarray, g: np.ndarray) -> np.ndarray:
        """T's columns at gravity g: Y_0 + sum_i g_i D_i on the base parameters' columns."""
        B = T[:, : self.r].copy()
        B[:, self.moved] += self._gravity_part(T, g)
        return B

    def _gravity_part(self, T: np.ndarray, g: np.ndarray) -> np.ndarray:
        """sum_i g_i D_i on the `moved` columns: what gravity g adds to them (linear in g)."""
        r, m = self.r, len(self.moved)
        return sum(g[i] * T[:, r + i * m: r + (i + 1) * m] for i in range(3))

    def fit(self, parts: list[int], g: np.ndarray, turned: bool = True) -> np.ndarray:
        return self.solved(parts, g, turned)[0]

    def solved(self, parts: list[int], g: np.ndarray, turned: bool = True) -> tuple[np.ndarray, float]:
        """The least squares on the folds `parts` at g: its parameters and its residual's sum of squares."""
        B, t = self.system(parts, g, turned)
        theta = _lstsq(B, t)
        return theta, float(np.sum((B @ theta - t) ** 2))

    def squared(self, parts: list[int], g: np.ndarray, theta: np.ndarray, turned: bool = True) -> tuple[float, float]:
        """The residual's and the torques' sums of squares on the folds `parts`."""
        B, t = self.system(parts, g, turned)
        return float(np.sum((B @ theta - t) ** 2)), float(np.sum(t**2))

    def direction(self, parts: list[int], g0: np.ndarray, start: np.ndarray | None = None) -> np.ndarray:
        """The turn omega (2,) whose gravity the least squares on `parts` fits best: Gauss-Newton from
        `start` (no turn) on the residual with the parameters eliminated (variable projection, Kaufman's
        Jacobian P_perp (dB/domega) theta, P_perp = 1 - B B^+; B is affine in g, dg/domega by central
        differences), each step halved until the residual falls."""
        T = self._stacked(parts)
        omega = np.zeros(2) if start is None else np.array(start, dtype=float)
        g = turned(g0, omega)
        theta, cost = self.solved(parts, g)
        h = 1e-6
        for _ in range(GAUSS_NEWTON_STEPS):
            B, t = self.system(parts, g)
            r = B @ theta - t
            dg = [(turned(g0, omega + h * e) - turned(g0, omega - h * e)) / (2 * h) for e in np.eye(2)]
            base = theta[: self.r]  # the tilt-only columns do not turn with the gravity
            J = np.zeros((len(B), 2))
            for k, d in enumerate(dg):
                J[:, k] = self._gravity_part(T, d) @ base[self.moved]
            J -= B @ _lstsq(B, J)  # P_perp: the parameters follow the turn
            step = -np.linalg.lstsq(J, r, rcond=None)[0]
            for _ in range(30):
                trial = omega + step
                g_trial = turned(g0, trial)
                theta_trial, c = self.solved(parts, g_trial)
                if c <= cost:
                    break
                step = step / 2
            else:
                return omega
            omega, g, theta, cost = trial, g_trial, theta_trial, c
            if np.linalg.norm(step) <= ANGLE_TOL:
                break
        return omega

    def held_out(self, g0: np.ndarray, turn: np.ndarray | None) -> tuple[float, np.ndarray]:
        """The folds' held-out relative error: each fold predicted by the fit on the others, at g0 (`turn`
        None) or at the direction the others give (with the tilt-only columns), searched from `turn`; and
        those directions (folds, 2), each the others' (none without a turn)."""
        e2 = ref2 = 0.0
        every = range(len(self.T))
        omegas = []
        for k in every:
            others = [j for j in every if j != k]
            if turn is not None:
                omegas.append(self.direction(others, g0, turn))
            g = g0 if turn is None else turned(g0, omegas[-1])
            e, ref = self.squared([k], g, self.fit(others, g, turn is not None), turn is not None)
            e2, ref2 = e2 + e, ref2 + ref
        return relative_residual_of_sums(e2, ref2), np.array(omegas).reshape(-1, 2)


def _lstsq(B: np.ndarray, y: np.ndarray) -> np.ndarray:
    """numpy's minimum-norm least squares of B x = y with B's columns scaled to unit norm (numerics.column_scale:
    a column of round-off left as it is)."""
    scale = column_scale(B)
    x = np.linalg.lstsq(B / scale, y, rcond=None)[0]
    return x / (scale if x.ndim == 1 else scale[:, None])


def tilt(mode: str, gravity_W: np.ndarray, rows, tau: np.ndarray, independent: np.ndarray, n_links: int) -> Tilt:
    """The gravity the fits use (module docstring): `rows(i, sl)` the training span's regressor (14 n
    columns) of the samples `sl` at gravity 0 (i = None) or e_i; tau (N, channels) its torques;
    `independent` the base parameters' columns of gravity in no special direction (_Folds)."""
    g0 = np.asarray(gravity_W, dtype=float)
    if mode == "declared":
        return declared(g0)
    if not np.linalg.norm(g0) > 0:
        return declared(g0, mode, "no gravity declared: no direction to turn")
    if len(tau) < FOLDS * MIN_FOLD:
        return declared(g0, mode, f"{len(tau)} training samples: too few for {FOLDS} folds of {MIN_FOLD}")
    moved = gravity_columns(n_links, independent)
    folds = _Folds(fold_triangles(rows, tau, independent, moved, FOLDS), len(independent), moved, g0)
    every = list(range(FOLDS))
    omega = folds.direction(every, g0)
    g = turned(g0, omega)
    training = {name: relative_residual_of_sums(*folds.squared(every, x, folds.fit(every, x, turn), turn))
                for name, x, turn in (("declared", g0, False), ("identified", g, True))}
    held = {"declared": folds.held_out(g0, None)[0]}
    held["identified"], others = folds.held_out(g0, omega)
    # the jackknife's standard error of the turn: the spread of the turns each fold's others give
    spread = float(np.sqrt((FOLDS - 1) / FOLDS * np.sum((others - others.mean(axis=0)) ** 2)))
    chosen, reason = choice(mode, angle_between(g0, g), spread, held)
    return Tilt(mode, g0, g, chosen, held, training, reason, spread)


def choice(mode: str, angle: float, spread: float, held: dict[str, float]) -> tuple[bool, str]:
    """Whether the fits take the turned gravity, and why (module docstring): `angle` the turn (rad), `spread`
    its jackknife standard error over the folds, `held` the folds' held-out errors ("declared", "identified")."""
    degrees = np.degrees(angle)
    if mode == "identified":
        return True, f"identified ([data] tilt = \"identified\"): turned {degrees:.3g} degrees"
    if angle > MAX_TILT:
        return False, (f"the torques' direction is {degrees:.3g} degrees off the declared one, more than a mounting "
                       f"off level ({np.degrees(MAX_TILT):g}): declared kept")
    if not angle >= SPREADS * spread:
        return False, (f"declared kept: turned {degrees:.3g} degrees, less than {SPREADS:g} times the turn's spread "
                       f"over the folds ({np.degrees(spread):.3g} degrees): the data do not tell it")
    if held["identified"] < (1.0 - DEMAND) * held["declared"]:
        return True, (f"turned {degrees:.3g} degrees (+-{np.degrees(spread):.2g} over the folds): the folds' held-out "
                      f"error {100 * held['identified']:.4g} % against {100 * held['declared']:.4g} % declared")
    return False, (f"declared kept: turned {degrees:.3g} degrees, the folds' held-out error "
                   f"{100 * held['identified']:.4g} % against {100 * held['declared']:.4g} % (not {100 * DEMAND:g} % "
                   "better)")
