"""A ball joint's chart, turned to fit a closed chain's motion.

The harness reads a ball joint as three hinges at one point through two massless carriages
(harness/model/mjcf.py), their axes a, b, c at q = 0 orthonormal: W = [a b c] (world components). By the
product of exponentials the ball's rotation from its pose at q = 0 is

    R_W = exp(a^ alpha) exp(b^ beta) exp(c^ gamma) = W R(theta) W^T,    R(theta) = Rx Ry Rz

(harness/model/cardano.py), so that the hinges' angles theta are Cardano coordinates of SO(3) in the chart
W. Every orthonormal W is a chart: the ball, its bodies and the loops are where they were, and only the
coordinates change. Each chart has its lock, the rotations with a^T R_W c = sin(beta) = +-1 (the middle
hinge at +-pi/2: the first and last axes in line), where omega = D(theta) theta' loses a direction. In a
tree that costs nothing (the hinges' motion is given, whatever omega it makes); in a closed chain a passive
ball's hinges follow the loops, q'_p = -J_p^+ J_a q'_a (harness/model/closure.py), which needs 1/cos(beta)
of the rates near the lock and cannot be solved at it.

A motion is a curve R_W(t) in SO(3). A sample rules out the charts whose lock holds it, a surface in the
three-dimensional set of charts, so charts regular along the whole curve exist: `fitted` takes, for each
passive ball that comes nearer its lock than cos(beta) = MARGIN along the motion (or meets it, where the
loops cannot be followed), the chart W that keeps the motion's rotations farthest from its lock
(the largest smallest cos(beta), `chart_for`), read from the rotations the loops give, and turns the
ball's hinges to it (`turned`). Said in the spec's notes; a ball the motion keeps within MARGIN keeps its
file's chart."""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.optimize import minimize
from scipy.spatial.transform import Rotation

from harness.model.cardano import rotation
from harness.model.spec import RobotSpec

MARGIN = 0.5  # cos(beta) along the motion below which a passive ball's chart is turned: its rates at most 2 |omega|
ORTHONORMAL = 1e-9  # three hinges at one point are a ball's where W^T W = 1 to this
ATTEMPTS = 4  # charts tried for one motion: each is fitted to every rotation the loops gave with the ones before
STARTS = 5  # the best starting charts refined by Nelder-Mead (`chart_for`)
SPREAD, SEED = 500, 0  # further starting charts, a fixed draw over SO(3)
SIMPLEX = np.vstack([np.zeros(3), 0.2 * np.eye(3)])  # rad: Nelder-Mead's first steps about each axis


@dataclasses.dataclass(frozen=True)
class Ball:
    """Three hinges of the spec, inner first, at one point, their axes at q = 0 orthonormal."""

    hinges: tuple[str, str, str]
    W: np.ndarray  # (3, 3) their axes at q = 0 as columns, world components


def balls(spec: RobotSpec, among: set[str] | None = None) -> list[Ball]:
    """The spec's chains of three hinges through massless carriages at one point whose axes at q = 0 are
    a right-handed orthonormal triad, none with a drive term or limits of its own (a ball joint as the
    harness reads one, its cone's share of limits allowed: any chart of it is the same joint), those wholly
    `among` the named joints where given."""
    coned = {h for hinges, _ in (spec.cones or {}).values() for h in hinges}
    out = []
    for chain in spec.hinge_chains():
        names = tuple(j.name for j in chain)
        W = np.column_stack([j.axis_W0 for j in chain]) if len(chain) == 3 else np.zeros((3, 3))
        if (np.max(np.abs(W.T @ W - np.eye(3))) > ORTHONORMAL or np.linalg.det(W) < 0
                or any(np.linalg.norm(j.p_W0 - chain[0].p_W0) > ORTHONORMAL or not j.friction.none for j in chain)
                or any(h in (spec.limits or {}) and h not in coned for h in names)):
            continue
        if among is None or set(names) <= among:
            out.append(Ball(names, W))  # type: ignore[arg-type]
    return out


def rotations_W(spec: RobotSpec, ball: Ball, q: np.ndarray) -> np.ndarray:
    """R_W (N, 3, 3): the ball's rotation from its pose at q = 0, world components, at q (N, n)."""
    ks = [spec.joint_names.index(h) for h in ball.hinges]
    return ball.W @ rotation(np.asarray(q, dtype=float)[:, ks]) @ ball.W.T


def cos_beta(W: np.ndarray, R_W: np.ndarray) -> np.ndarray:
    """cos(beta) (..., N) of the rotations R_W (N, 3, 3) in the charts W (..., 3, 3): 1 at a chart's centre's
    axes, 0 at its lock."""
    s = np.einsum("...i,nij,...j->...n", W[..., :, 0], R_W, W[..., :, 2])
    return np.sqrt(np.clip(1.0 - s * s, 0.0, 1.0))


def angles(W: np.ndarray, R_W: np.ndarray) -> np.ndarray:
    """theta (N, 3): the Cardano angles of R_W (N, 3, 3) in the chart W, R_W = W R(theta) W^T."""
    return Rotation.from_matrix(np.swapaxes(W, -1, -2) @ R_W @ W).as_euler("XYZ")


def chart_for(R_W: np.ndarray, W0: np.ndarray) -> np.ndarray:
    """The orthonormal chart W (3, 3) whose lock is farthest from the rotations R_W (N, 3, 3): the largest
    smallest cos(beta) over them. Started from W0, W0 with its axes put in every order and sign (the
    cube's 24 turns), the charts whose first or last axis is the rotations' main axis (where they turn
    about one axis, a chart with its first or last hinge on it has beta = 0 throughout) and SPREAD charts
    spread over SO(3) (a fixed draw); the STARTS best refined by Nelder-Mead over W = W_start Rot(phi),
    twice (the cost, a smallest value, has corners where a simplex stalls)."""
    starts = [W0 @ C for C in Rotation.create_group("O").as_matrix()]
    axes = Rotation.from_matrix(R_W).as_rotvec()
    if np.any(np.linalg.norm(axes, axis=1) > 0):
        k = np.linalg.svd(axes, full_matrices=False)[2][0]
        other = np.linalg.svd(k[None])[2][1:]  # two unit vectors across k
        starts += [np.column_stack([other[0], other[1], k]), np.column_stack([k, other[0], other[1]])]
    starts = np.array([W if np.linalg.det(W) > 0 else W * np.array([1.0, 1.0, -1.0]) for W in starts])
    starts = np.concatenate([starts, Rotation.random(SPREAD, random_state=SEED).as_matrix()])
    ranked = starts[np.argsort(-np.min(cos_beta(starts, R_W), axis=1), kind="stable")[:STARTS]]

    def cost(phi: np.ndarray, W_start: np.ndarray) -> float:
        return -float(np.min(cos_beta(W_start @ Rotation.from_rotvec(phi).as_matrix(), R_W)))

    best = None
    for W in ranked:
        for _ in range(2):
            found = minimize(cost, np.zeros(3), args=(W,), method="Nelder-Mead",
                             options={"xatol": 1e-9, "fatol": 1e-13, "maxiter": 800, "initial_simplex": SIMPLEX})
            W = W @ Rotation.from_rotvec(found.x).as_matrix()
        if best is None or found.fun < best[0]:
            best = (found.fun, W)
    return best[1]


def turned(spec: RobotSpec, ball: Ball, W: np.ndarray) -> RobotSpec:
    """The spec with the ball's hinges about W's columns at q = 0 (the same ball in another chart)."""
    axes = dict(zip(ball.hinges, W.T, strict=True))
    joints = tuple(dataclasses.replace(j, axis_W0=axes[j.name].copy()) if j.name in axes else j
                   for j in spec.joints)
    return dataclasses.replace(spec, joints=joints)


def carried(spec: RobotSpec, charted: RobotSpec) -> RobotSpec:
    """`spec` (another model of the same robot: a log's truth) with its ball joints in the charts of
    `charted`'s balls of the same hinges (`turned`), so that both read one log's coordinates alike."""
    for ball in balls(charted):
        if set(ball.hinges) <= set(spec.joint_names):
            spec = turned(spec, ball, ball.W)
    return spec


def note(ball: Ball, before: float, after: float, complete: bool) -> str:
    """The spec's note on a ball whose chart was turned (to ball.W), one line: `before` and `after` the
    smallest cos(beta) along the motion in the file's chart (`complete`: followed to its end there) and in
    the turned one."""
    axes = "; ".join(f"{h} about ({', '.join(f'{x:.4f}' for x in ball.W[:, k])})" for k, h in enumerate(ball.hinges))
    beta = np.degrees(np.arccos(before))
    reach = (f"its middle hinge reaches {beta:.1f} degrees (cos(beta) = {before:.3g}; the lock at 90)" if complete
             else "it reaches the lock, where the loops cannot be followed")
    return (f"ball joint hinges {', '.join(ball.hinges)}: along the motion, in the file's chart (the body's axes), "
            f"{reach}; its hinges turned to the chart {axes} (world axes at q = 0), where cos(beta) >= {after:.4f} "
            "along it (harness/model/charts.py)")


def fitted(chain, q_a: np.ndarray):
    """The ClosedChain `chain` with each passive ball that comes nearer its lock than MARGIN along the
    actuated motion q_a (N, n_a), followed from q = 0 (closure.positions), or meets it, turned to the chart
    that keeps every rotation the loops gave it farthest from its lock (`chart_for`), and said in the spec's
    notes; `chain` itself where no ball comes so near. ClosureError: the loops cannot be followed in the
    ATTEMPTS charts tried (the balls near their lock named), or stop for another reason than a ball's lock."""
    from harness.model.closure import ClosedChain, ClosureError, positions

    passive = {chain.spec.joints[i].name for i in chain.passive}
    files = {b.hinges: b for b in balls(chain.spec, passive)}
    if not files:
        return chain
    seen = {h: np.empty((0, 3, 3)) for h in files}  # the rotations the loops gave, in every chart tried
    before: dict[tuple, tuple[float, bool]] = {}  # each ball's nearest approach in the file's chart
    for _ in range(ATTEMPTS):
        try:
            q, error = positions(chain, q_a, np.zeros(chain.n)), None
        except ClosureError as exc:
            q, error = exc.closed, exc
            if q is None or not len(q):
                raise
        near = []
        for ball in balls(chain.spec, passive):
            R = rotations_W(chain.spec, ball, q)
            seen[ball.hinges] = np.concatenate([seen[ball.hinges], R])
            reach = float(np.min(cos_beta(ball.W, R)))
            before.setdefault(ball.hinges, (reach, error is None))  # the first attempt: the file's chart
            if reach < MARGIN:
                near.append((ball, reach))
        spec = chain.spec
        for ball, reach in near:
            W = chart_for(seen[ball.hinges], ball.W)
            if float(np.min(cos_beta(W, seen[ball.hinges]))) > reach:
                spec = turned(spec, ball, W)
        if spec is chain.spec:  # every ball far from its lock, or no chart does better on what the loops gave
            if error is not None:
                raise _near_lock(error, near)
            break
        chain = ClosedChain.of(spec)
    else:
        try:
            q = positions(chain, q_a, np.zeros(chain.n))
        except ClosureError as exc:
            raise _near_lock(exc, [(b, float(np.min(cos_beta(b.W, rotations_W(chain.spec, b, exc.closed)))))
                                   for b in balls(chain.spec, passive) if exc.closed is not None]) from None
    lines = tuple(note(b, before[b.hinges][0], float(np.min(cos_beta(b.W, rotations_W(chain.spec, b, q)))),
                       before[b.hinges][1])
                  for b in balls(chain.spec, passive) if not np.array_equal(b.W, files[b.hinges].W))
    return ClosedChain.of(dataclasses.replace(chain.spec, notes=(*chain.spec.notes, *lines))) if lines else chain


def _near_lock(error, near: list[tuple[Ball, float]]):
    """The loops' ClosureError, the balls near their chart's lock where it stopped said after it."""
    if not near:
        return error
    said = "; ".join(f"{', '.join(b.hinges)} at cos(beta) = {c:.2g}" for b, c in near)
    return type(error)(f"{error} (passive ball joints near their chart's lock where it stopped, and no chart "
                       f"found, of at most {ATTEMPTS} tried, that follows the motion: {said})")
