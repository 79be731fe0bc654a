"""A closed chain's motion from its actuated joints, and its actuated joints' torques.

The joints split into the actuated ones (q_a, named by the model) and the passive ones (q_p). The
loops' constraint equations (harness/model/loops.py) fix the passive joints:

    position      Phi(q_a, q_p) = 0                        solved by Newton's method for q_p
    velocity      J_a q'_a + J_p q'_p = 0                  q'_p = -J_p^+ J_a q'_a
    acceleration  J_a q''_a + J_p q''_p + b = 0            q''_p = -J_p^+ (J_a q''_a + b)

so that q' = G q'_a and q'' = G q''_a + g with G (n x n_a) the identity on the actuated rows and
-J_p^+ J_a on the passive ones, and g zero on the actuated rows and -J_p^+ b on the passive ones.
J_p^+ is the pseudo-inverse: a planar loop's connect has an out-of-plane row that is zero, which
a plain inverse cannot take.
G is accepted where J_p has full column rank (the passive joints are determined) and J G = 0 to
NULL_SPACE of |J| |G| (the actuated joints are independent: the loop allows every actuated motion).

Torques (d'Alembert, the first seed's Lagrange multipliers): the tree's joint torques tau(q, q',
q'') (RNEA of the open tree, any engine) and the loops' forces lambda satisfy

    tau = S^T tau_a + J^T lambda,        so    tau_a = G^T tau,    lambda = (J^T)^+ (tau - S^T tau_a)

(G^T S^T = 1, G^T J^T = (J G)^T = 0). tau_a is the closed chain's actuated torque; an engine's raw
torque on the actuated joints is not (it is whatever the tree needs, with the loop's share carried
by the passive joints or the constraint, depending on the engine).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from harness.model.loops import bias, jacobian, residual_and_jacobian
from harness.model.spec import WORLD, Loop, RobotSpec

NEWTON_ITERATIONS = 30
CLOSED = 1e-12  # a loop is closed when |Phi| <= CLOSED times the mechanism's size (positions; rad for welds)
NULL_SPACE = 1e-12  # |J G| <= NULL_SPACE |J| |G|: G's columns in J's null space
RANK = 1e-9  # J_p's smallest singular value over its largest: below, the passive joints are not determined
CONTINUATION_STEP = 0.05  # rad (or this fraction of the size, m): the largest actuated step between solves
LOCK = 1e-9  # two columns a, b of J in line: |a (b.b) - b (a.b)| <= LOCK |a| |b|^2, the sine of their angle
CONTINUATION_BLOCK = 8  # stations closed by one Newton's method, each predicted from the last one kept


class ClosureError(ValueError):
    """The loop cannot be closed, or the actuated joints do not determine the passive ones. `closed`: where a
    motion was followed, the configurations closed before it stopped (harness/model/charts.py reads them)."""

    closed: np.ndarray | None = None


@dataclass(frozen=True, eq=False)
class ClosedChain:
    """A spec with loops and its actuated joints (indices into the spec's joints)."""

    spec: RobotSpec
    loops: tuple[Loop, ...]
    actuated: tuple[int, ...]
    passive: tuple[int, ...]
    size: float  # m: the largest distance between joint points and joined points at q = 0

    @classmethod
    def of(cls, spec: RobotSpec) -> ClosedChain:
        """The spec's loops and actuated joints (RobotSpec.loops, .actuated)."""
        loops, actuated = spec.loops, spec.actuated
        if not loops:
            raise ClosureError(f"{spec.name}: no loop closes the tree")
        if not actuated:
            raise ClosureError(f"{spec.name}: its actuated joints are not named")
        names = spec.joint_names
        missing = [a for a in actuated if a not in names]
        if missing:
            raise ClosureError(f"{spec.name}: actuated joint {missing[0]!r} is not one of its joints")
        act = tuple(names.index(a) for a in actuated)
        passive = tuple(i for i in range(len(names)) if i not in act)
        points = [j.p_W0 for j in spec.joints] + [p for lp in loops if lp.joins_points
                                                  for p in (lp.point_a_W0, lp.point_b_W0)]
        P = np.array(points)
        size = float(np.max(np.linalg.norm(P[:, None] - P[None], axis=-1))) or 1.0
        return cls(spec, tuple(loops), act, passive, size)

    @property
    def n(self) -> int:
        return len(self.spec.joints)

    @property
    def actuated_span(self) -> np.ndarray:
        """(n_a,) what one unit of an actuated joint's travel is: 1 rad, or the mechanism's size (m)."""
        return self._span(self.actuated)

    @property
    def passive_span(self) -> np.ndarray:
        """(n_p,) the same of the passive joints."""
        return self._span(self.passive)

    def _span(self, joints) -> np.ndarray:
        return np.array([1.0 if self.spec.joints[k].revolute else self.size for k in joints])

    def _scale(self) -> np.ndarray:
        """(rows,) each constraint row's unit: the size for positions, 1 for a weld's rotation; a coupling's,
        its follower's travel unit (1 rad, or the size)."""
        names = self.spec.joint_names
        return np.concatenate([self._span([names.index(lp.follower)]) if not lp.joins_points
                               else [self.size] * 3 + ([1.0] * 3 if lp.kind == "weld" else []) for lp in self.loops])


def pinv_passive(chain: ClosedChain, J: np.ndarray, where: str, numbered: bool = True) -> np.ndarray:
    """J_p^+ (N, n_p, rows) from one SVD of J_p (singular values under RANK of the largest dropped, as
    numpy's pinv with rcond=RANK drops them), refused where J_p lacks full column rank."""
    N, rows, n_p = len(J), J.shape[1], len(chain.passive)
    if not n_p:
        return np.zeros((N, 0, rows))
    U, s, Vt = np.linalg.svd(J[:, :, chain.passive], full_matrices=False)
    smallest = s[:, n_p - 1] if rows >= n_p else np.zeros(N)  # fewer loop rows than passive joints: rank short
    ratio = smallest / np.maximum(s[:, 0], np.finfo(float).tiny)
    bad = np.flatnonzero(~(ratio > RANK))
    if bad.size:
        at = f"{where} {bad[0]}" if numbered else where
        locked = _locked_chains(chain, J[bad[0]])
        raise ClosureError(f"{chain.spec.name}: the passive joints are not determined by the loops at {at} "
                           f"(J_p's singular values' ratio {ratio[bad[0]]:.1e}: a singular "
                           "configuration, or fewer independent loop equations than passive joints)"
                           + (f"; at their lock, the first and last axes in line: the hinges {', '.join(locked)} "
                              "(a ball joint's Cardano hinges, its middle one at +-pi/2)" if locked else ""))
    return np.swapaxes(Vt, 1, 2) @ np.swapaxes(U / s[:, None, :], 1, 2)


def _locked_chains(chain: ClosedChain, J: np.ndarray) -> list[str]:
    """The passive chains of three hinges through massless carriages (a ball joint read as its hinges)
    whose first and last hinges move the loops alike at one configuration's J (rows, n): their axes in
    line through their common point, the chain's lock (its Cardano chart's singularity)."""
    spec, out = chain.spec, []
    for hinges in spec.hinge_chains():
        k = [spec.joint_names.index(h.name) for h in hinges]
        if len(k) != 3 or not set(k) <= set(chain.passive):
            continue
        a, b = J[:, k[0]], J[:, k[2]]
        if np.linalg.norm(a * (b @ b) - b * (a @ b)) <= LOCK * np.linalg.norm(a) * (b @ b):  # sin(angle) <= LOCK
            out.append(" ".join(h.name for h in hinges))
    return out


def _G(chain: ClosedChain, J: np.ndarray, P: np.ndarray) -> np.ndarray:
    """G (N, n, n_a) from J and J_p^+ (`pinv_passive`): the identity on the actuated rows, -J_p^+ J_a on
    the passive ones."""
    G = np.zeros((len(J), chain.n, len(chain.actuated)))
    G[:, chain.actuated, np.arange(len(chain.actuated))] = 1.0
    G[:, chain.passive, :] = -P @ J[:, :, chain.actuated]
    return G


def projection(chain: ClosedChain, q: np.ndarray, J: np.ndarray | None = None,
               where: str = "sample", closed: bool = True, numbered: bool = True) -> np.ndarray:
    """G(q), (N, n, n_a): q' = G q'_a for every velocity the loops allow (module docstring); refused
    where J_p is rank deficient or, at `closed` configurations, G's columns are not in J's null space to
    NULL_SPACE (where a loop is slightly open, as in a simulation's recording, a planar loop's
    out-of-plane row is not quite zero and J G is of the gap's order)."""
    q = np.atleast_2d(q)
    J = jacobian(chain.spec, chain.loops, q) if J is None else J
    G = _G(chain, J, pinv_passive(chain, J, where, numbered))
    if closed:
        _check_null_space(chain, J, G, where, numbered)
    return G


def _check_null_space(chain: ClosedChain, J: np.ndarray, G: np.ndarray, where: str, numbered: bool) -> None:
    """Refused where |J G| > NULL_SPACE |J| |G|: the loops forbid some actuated motions."""
    JG = np.abs(J @ G).max(axis=(1, 2))
    bound = NULL_SPACE * np.linalg.norm(J, axis=(1, 2)) * np.linalg.norm(G, axis=(1, 2))
    bad = np.flatnonzero(~(JG <= bound))
    if bad.size:
        at = f"{where} {bad[0]}" if numbered else where
        raise ClosureError(f"{chain.spec.name}: the actuated joints are not independent at {at}: "
                           f"|J G| = {JG[bad[0]]:.1e} (the loops forbid some actuated motions)")


def predicted(chain: ClosedChain, q: np.ndarray, J: np.ndarray, P: np.ndarray, target: np.ndarray) -> np.ndarray:
    """q (N, n) moved to the actuated values `target` (N, n_a) to first order along the loops:
    q_p - J_p^+ J_a (target - q_a), P = J_p^+ at q: the guess Newton's method starts from."""
    act = list(chain.actuated)
    out = q.copy()
    out[:, chain.passive] -= (P @ (J[:, :, act] @ (target - q[:, act])[:, :, None]))[:, :, 0]
    out[:, act] = target
    return out


def _newton(chain: ClosedChain, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Newton's method on q_p for every row of q at once (q_a held): q, the scaled |Phi| per row and J
    at q (loops.residual_and_jacobian: Phi and J from one evaluation of the tree's positions)."""
    q = q.copy()
    scale = chain._scale()
    for iteration in range(NEWTON_ITERATIONS + 1):
        phi, J = residual_and_jacobian(chain.spec, chain.loops, q)
        err = np.max(np.abs(phi) / scale, axis=1)
        todo = err > CLOSED
        if not todo.any() or iteration == NEWTON_ITERATIONS:
            return q, err, J
        step = np.linalg.pinv(J[todo][:, :, chain.passive], rcond=RANK) @ phi[todo][:, :, None]
        q[np.ix_(np.flatnonzero(todo), chain.passive)] -= step[:, :, 0]
    raise AssertionError("unreachable")


def close(chain: ClosedChain, q: np.ndarray, where: str = "sample", numbered: bool = True) -> np.ndarray:
    """q (N, n) with its passive joints moved so that every loop closes, each row from itself; a row
    that does not close is refused, named `where` and its row number (or `where` alone)."""
    return close_with_jacobian(chain, q, where, numbered)[0]


def close_with_jacobian(chain: ClosedChain, q: np.ndarray, where: str = "sample",
                        numbered: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """`close`, and J (N, rows, n) at the closed configurations (Newton's last evaluation)."""
    q, err, J = _newton(chain, np.atleast_2d(np.asarray(q, dtype=float)))
    bad = np.flatnonzero(~(err <= CLOSED))
    if bad.size:
        at = f"{where} {bad[0]}" if numbered else where
        raise ClosureError(f"{chain.spec.name}: the loops do not close at {at} (|Phi| = "
                           f"{err[bad[0]]:.1e} of the size after {NEWTON_ITERATIONS} Newton steps: out of reach, or "
                           "too far from the configuration it started from)")
    return q, J


def positions(chain: ClosedChain, q_a: np.ndarray, q_start: np.ndarray) -> np.ndarray:
    """q (N, n): the actuated joints at q_a (N, n_a), a motion in sample order, and the passive ones
    closing every loop, followed continuously from q_start (n,) (whose actuated entries need not be
    q_a[0]'s): first along stations at most CONTINUATION_STEP apart (`_follow`), then every sample at
    once from the nearest station before it."""
    q_a = np.atleast_2d(np.asarray(q_a, dtype=float))
    path = np.vstack([np.asarray(q_start, dtype=float)[list(chain.actuated)], q_a])
    travel = np.concatenate([[0.0], np.cumsum(np.max(np.abs(np.diff(path, axis=0)) / chain.actuated_span, axis=1))])
    # stations: q_start, then samples at most CONTINUATION_STEP of travel apart (steps larger than it
    # between two samples are cut into intermediate stations)
    stations_travel = np.arange(0.0, travel[-1] + CONTINUATION_STEP, CONTINUATION_STEP)
    stations = np.array([np.interp(stations_travel, travel, path[:, k]) for k in range(path.shape[1])]).T
    sample = np.minimum(np.searchsorted(travel[1:], stations_travel), len(q_a) - 1)
    solved = _follow(chain, np.asarray(q_start, dtype=float), stations, sample)
    nearest = np.clip(np.searchsorted(stations_travel, travel[1:], side="right") - 1, 0, len(stations) - 1)
    guess = solved[nearest]
    try:
        J = jacobian(chain.spec, chain.loops, guess)
        return close(chain, predicted(chain, guess, J, pinv_passive(chain, J, "sample"), q_a))
    except ClosureError as exc:
        exc.closed = solved  # every station was followed
        raise


def _follow(chain: ClosedChain, q_start: np.ndarray, stations: np.ndarray, sample: np.ndarray) -> np.ndarray:
    """Every station's closed q (len(stations), n), followed from q_start: a block of up to
    CONTINUATION_BLOCK stations at a time, each predicted by G from the last one solved and all closed
    by one Newton's method, kept where the block stays on the branch it started from (no fold between
    neighbours, `_folded`, and no station's passive joints moved by Newton more than the block's travel,
    CONTINUATION_STEP a station: a solve that jumped to another assembly moves them by the mechanism's
    size); else its stations one at a time, each predicted from the one before, whose failures are
    refused naming the station's sample (`sample`, its row of the motion)."""
    q, J = close_with_jacobian(chain, q_start, "the starting configuration", numbered=False)
    solved = np.empty((len(stations), chain.n))
    s = 0
    try:
        while s < len(stations):
            block = stations[s: s + CONTINUATION_BLOCK]
            kept = _block(chain, q, J, block) if len(block) > 1 else None
            if kept is not None:
                solved[s: s + len(block)], q, J = kept[0], kept[0][-1:], kept[1][-1:]
                s += len(block)
                continue
            for target in block:
                where = (f"sample {sample[s]} of the motion (q_a = {np.array2string(target, precision=4)}, reached "
                         "from the one before)")
                P = pinv_passive(chain, J, where, numbered=False)
                J_before = J
                q, J = close_with_jacobian(chain, predicted(chain, q, J, P, target[None]), where, numbered=False)
                if _folded(chain, J_before, J)[0]:
                    raise _fold_error(chain, where)
                solved[s] = q[0]
                s += 1
    except ClosureError as exc:
        exc.closed = solved[:s]  # the stations followed before it stopped
        raise
    return solved


def _block(chain: ClosedChain, q: np.ndarray, J: np.ndarray, block: np.ndarray):
    """The stations of `block` (B, n_a) closed at once from q (1, n) and its J, each predicted by G there:
    (q (B, n), J (B, rows, n)), or None where the block is not kept (`_follow`)."""
    B = len(block)
    try:
        P = pinv_passive(chain, J, "", numbered=False)
        guess = predicted(chain, np.repeat(q, B, axis=0), J, P, block)  # J and P the start's, broadcast
        q_b, J_b = close_with_jacobian(chain, guess, "", numbered=False)
    except ClosureError:
        return None
    moved = (np.abs(q_b - guess)[:, chain.passive] / chain.passive_span).max(axis=1)
    reach = CONTINUATION_STEP * np.arange(1, B + 1)
    if np.any(moved > reach) or np.any(_folded(chain, np.concatenate([J, J_b[:-1]]), J_b)):
        return None
    return q_b, J_b
def _folded(chain: ClosedChain, J_before: np.ndarray, J_now: np.ndarray) -> np.ndarray:
    """(N,) bool: a step of the motion across a singular configuration of the loops, from J_before to
    J_now (N, rows, n) row by row: J_p (the passive joints' columns of J) before and after the step, read
    in the frame of the range before (its first n_p left singular vectors), have determinants of
    opposite signs where a singular value has passed through zero between them (a parallelogram
    folding flat) or the solve has jumped to the mechanism's other assembly."""
    n_p = len(chain.passive)
    if not n_p:
        return np.zeros(len(J_now), dtype=bool)
    J_p_before, J_p = J_before[:, :, chain.passive], J_now[:, :, chain.passive]
    frame = np.swapaxes(np.linalg.svd(J_p_before)[0][:, :, :n_p], 1, 2)
    return np.linalg.det(frame @ J_p_before) * np.linalg.det(frame @ J_p) <= 0.0


def _fold_error(chain: ClosedChain, where: str) -> ClosureError:
    return ClosureError(f"{chain.spec.name}: the motion crosses a singular configuration of the loops before "
                        f"{where} (the passive joints' Jacobian changes orientation: the mechanism folds, or "
                        "changes assembly, and the actuated joints no longer drive it)")


@dataclass(frozen=True, eq=False)
class ChainMotion:
    """A consistent motion of a closed chain: every joint's (q, q', q''), (N, n), G (N, n, n_a) and J."""

    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    G: np.ndarray
    J: np.ndarray


def motion(chain: ClosedChain, q: np.ndarray, qd_a: np.ndarray, qdd_a: np.ndarray,
           J: np.ndarray | None = None, P: np.ndarray | None = None) -> ChainMotion:
    """The velocity and acceleration levels at closed configurations q (N, n): q' = G q'_a and
    q'' = G q''_a - J_p^+ b on the passive rows (module docstring); J at q and P = J_p^+ from it
    (`pinv_passive`) where the caller holds them already."""
    J = jacobian(chain.spec, chain.loops, q) if J is None else J
    P = pinv_passive(chain, J, "sample") if P is None else P
    G = _G(chain, J, P)
    _check_null_space(chain, J, G, "sample", numbered=True)
    qd = (G @ np.atleast_2d(qd_a)[:, :, None])[:, :, 0]
    b = bias(chain.spec, chain.loops, q, qd)
    qdd = (G @ np.atleast_2d(qdd_a)[:, :, None])[:, :, 0]
    qdd[:, chain.passive] -= (P @ b[:, :, None])[:, :, 0]
    return ChainMotion(q, qd, qdd, G, J)


def along(chain: ClosedChain, t: np.ndarray, actuated_motion) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A closed chain's (q, q', q'') (N, n) at times t (N,), any order: `actuated_motion(times)` gives
    the actuated joints' (q_a, q'_a, q''_a), each (len(times), n_a); the passive joints' follow from the
    loops, from q = 0 to the motion at t = 0 and then in time order, so that every call finds the same
    assembly of the mechanism."""
    order = np.argsort(t, kind="stable")
    q_a, qd_a, qdd_a = actuated_motion(np.concatenate([[0.0], t[order]]))
    m = motion(chain, positions(chain, q_a, np.zeros(chain.n))[1:], qd_a[1:], qdd_a[1:])
    back = np.empty_like(order)
    back[order] = np.arange(len(order))
    return m.q[back], m.qd[back], m.qdd[back]


def actuated_torques(G: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """tau_a = G^T tau, (N, n_a): the tree's joint torques (N, n) projected onto the actuated joints."""
    return (np.swapaxes(G, 1, 2) @ tau[:, :, None])[:, :, 0]


def multipliers(chain: ClosedChain, J: np.ndarray, tau: np.ndarray, tau_a: np.ndarray) -> np.ndarray:
    """lambda (N, rows): the loops' forces (and a weld's moments) on body a, from
    J^T lambda = tau - S^T tau_a (least norm where a loop's rows are redundant, as a planar loop's
    out-of-plane row is)."""
    rhs = tau.copy()
    rhs[:, chain.actuated] -= tau_a
    return (np.linalg.pinv(np.swapaxes(J, 1, 2), rcond=RANK) @ rhs[:, :, None])[:, :, 0]


def reach(chain: ClosedChain, q_a: np.ndarray, q_start: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Closed configurations (N, n) with the actuated joints at q_a (N, n_a), each followed from
    q_start (n,) along the straight line of actuated values in steps of at most CONTINUATION_STEP,
    every row at once; and which rows closed (N,) (a target out of the mechanism's reach does not)."""
    q_a = np.atleast_2d(np.asarray(q_a, dtype=float))
    act = list(chain.actuated)
    q0 = close(chain, np.asarray(q_start, dtype=float), "the starting configuration")[0]
    steps = max(1, int(np.ceil(np.max(np.abs(q_a - q0[act]) / chain.actuated_span) / CONTINUATION_STEP)))
    q = np.repeat(q0[None], len(q_a), axis=0)
    ok = np.ones(len(q_a), dtype=bool)
    for s in range(1, steps + 1):
        target = q0[act] + (q_a - q0[act]) * (s / steps)
        J = jacobian(chain.spec, chain.loops, q[ok])
        P = np.linalg.pinv(J[:, :, chain.passive], rcond=RANK)  # a row that cannot be followed is dropped, not refused
        closed, err, _ = _newton(chain, predicted(chain, q[ok], J, P, target[ok]))
        q[ok] = closed
        ok[np.flatnonzero(ok)[~(err <= CLOSED)]] = False
    return q, ok


def random_within_limits(chain: ClosedChain, limits: dict | None, count: int, seed: int) -> ChainMotion:
    """`count` random consistent states (`random_motion`): the actuated joints' q uniform within their
    position limits (or +-pi rad, +-1 m: harness/model/states.py), q'_a and q''_a within +-1."""
    from harness.model.states import position_bounds

    act = [chain.spec.joints[k] for k in chain.actuated]
    lo, hi = position_bounds([j.name for j in act], [j.revolute for j in act], limits)
    ones = np.ones(len(act))
    return random_motion(chain, lo, hi, ones, ones, count, seed)


def random_motion(chain: ClosedChain, lo: np.ndarray, hi: np.ndarray, qd_scale: np.ndarray, qdd_scale: np.ndarray,
                  count: int, seed: int) -> ChainMotion:
    """`count` random consistent states: the actuated joints' (q_a, q'_a, q''_a) uniform within
    [lo, hi], +-qd_scale and +-qdd_scale (each (n_a,); harness/model/states.py, random_states, with
    `seed`), the passive joints' from the loops (reached from q = 0; targets out of reach are drawn
    again, up to four draws)."""
    from harness.model.states import random_states

    kept: list[np.ndarray] = []
    for draw in range(4):
        q_a, qd_a, qdd_a = random_states(lo, hi, qd_scale, qdd_scale, count, seed + draw)
        q, ok = reach(chain, q_a, np.zeros(chain.n))
        kept.append((q[ok], qd_a[ok], qdd_a[ok]))
        if sum(len(k[0]) for k in kept) >= count:
            break
    q, qd_a, qdd_a = (np.concatenate([k[i] for k in kept])[:count] for i in range(3))
    if len(q) < count:
        raise ClosureError(f"{chain.spec.name}: only {len(q)} of {count} random actuated configurations are within "
                           "the loops' reach")
    return motion(chain, q, qd_a, qdd_a)


def loop_wrenches(chain: ClosedChain, q: np.ndarray, lam: np.ndarray
                  ) -> list[tuple[str, np.ndarray, np.ndarray, np.ndarray | None]]:
    """The loops' forces as forces on the bodies, (body, x_W, f_W, m_W) each (N, 3): lambda's force
    (and, for a weld, its moment) on body a at its joined point, the opposite on body b at its own
    (a world side left out). J^T lambda is their generalised force. A coupling's multiplier is a torque
    (or force) pair on its two joints, lambda on the follower and -r lambda on the leader, within the
    joints: no force on a body from outside them, left out (as MuJoCo's external wrenches leave it out)."""
    from harness.model.loops import joined_points

    out, row = [], 0
    for loop, (x_a, x_b) in zip(chain.loops, joined_points(chain.spec, chain.loops, q), strict=True):
        f = lam[:, row:row + 3]
        m = lam[:, row + 3:row + 6] if loop.kind == "weld" else None
        row += loop.rows
        if not loop.joins_points:
            continue
        for body, x, sign in ((loop.body_a, x_a, 1.0), (loop.body_b, x_b, -1.0)):
            if body != WORLD:
                out.append((body, x, sign * f, None if m is None else sign * m))
    return out
