"""Section 2.4: joint constraints Phi(q), their Jacobian Phi_q and zeta = -(Phi_q q')_q q'.

Generalized coordinates q = (q_1, ..., q_n), q_i = (r_i, theta_i) (Eq. 4): centre of mass and
Cardano angles of every massive body, 6n in all; every quantity is evaluated for N samples and
all constraint rows at once.

Every constraint row is a dot product (X1 - X2) . (Y1 - Y2) of differences of elements, each a
point or a direction fixed in a body or in the world. For a direction fixed in body i,
v = A(0i) v^(i), with w = omega^(i):

    dv/dtheta_i = -A v~ D,     v'' = -A v~ D theta'' + A((D' theta') x v + w x (w x v)),

and a point adds r_i. Jacobian rows and the velocity-product terms gamma = Phi'' - Phi_q q''
follow by the product rule, and zeta = -gamma (Eq. 109).

Joint constraints (Eqs. 65-73), for a joint O_k between inner body i (or the ground) and outer
body j:
- points coincide: r_i + A(0i) c_ik - r_j - A(0j) c_jk = 0, three world components (Eqs. 65-69);
- axes coincide. Formulation "paper" keeps, as the paper does, the first two world components of
  A(0i) p_k^(i) - A(0j) p_k^(j) (Eqs. 70-73, Phi_k4 and Phi_k5). Their linearisation constrains
  only the rotation about e3(0) when the axis has no e3(0) component: Phi_q then loses rank.
  Formulation "normal" uses two dot products with directions n1, n2 normal to the axis in the
  inner body, (A(0i) n_a) . (A(0j) p_k^(j)) = 0: rank 2 in every pose.
- The rail: a prismatic joint from the ground to a massless carriage that carries the revolute
  O1. B1 keeps two degrees of freedom: its joint point stays on the rail line (its components
  along two directions normal to the rail; the paper's Phi_11, along the rail, is dropped) and
  its axis stays parallel to the carriage's, which does not turn: 4 constraints.
- A prismatic joint between massive bodies (not in the paper): the outer body's point stays on
  the line through the inner body's point along the axis (2), the axes stay parallel (2), and the
  outer body does not twist about the axis (1). Both formulations use these rows.

`State` also has a quasi-velocity form (orientation A given directly, D = E, rates = omega^(i)):
the same rows then give the Jacobian with respect to (r', omega^(i)), which is how the
constrained forward simulation carries orientation without Cardano singularities.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from harness.model.kinematics import cross, skew
from harness.model.spec import WORLD, RobotSpec
from harness.papers.graph_theory_2021.cardano import A_0i, D, D_dot
from harness.papers.graph_theory_2021.topology import Topology

FORMULATIONS = ("paper", "normal")
CHAIN_AXES = 1e-6  # |det| of three unit axes (|a1 x a2| of two) below which they do not span the rotations


@dataclass(frozen=True, eq=False)
class State:
    """Positions and rates of every body, (N, n, ...), and the derived A, D, D' theta', omega."""

    r: np.ndarray  # (N, n, 3)
    A: np.ndarray  # (N, n, 3, 3)
    D: np.ndarray  # (N, n, 3, 3): omega^(i) = D rate
    Dd_rate: np.ndarray  # (N, n, 3): D' rate
    r_dot: np.ndarray  # (N, n, 3)
    rate: np.ndarray  # (N, n, 3): theta' (Cardano) or omega^(i) (quasi-velocities)

    @classmethod
    def cardano(cls, r, theta, r_dot, theta_dot) -> State:
        return cls(r, A_0i(theta), D(theta), np.einsum("...ab,...b->...a", D_dot(theta, theta_dot),
                                                        theta_dot), r_dot, theta_dot)

    @classmethod
    def quasi(cls, r, A, r_dot, omega_B) -> State:
        eye = np.broadcast_to(np.eye(3), A.shape)
        return cls(r, A, eye, np.zeros_like(omega_B), r_dot, omega_B)

    @property
    def omega(self) -> np.ndarray:
        return np.einsum("...ab,...b->...a", self.D, self.rate)

    @property
    def q_dot(self) -> np.ndarray:
        """(N, 6n) in the order (r_1, rate_1, r_2, rate_2, ...)."""
        return np.concatenate([self.r_dot, self.rate], axis=-1).reshape(self.r.shape[0], -1)


@dataclass(frozen=True)
class Element:
    """A point (`point`=True) or direction `vec` fixed in body `body` (-1: the world)."""

    body: int
    vec: tuple[float, float, float]
    point: bool = False


ZERO = Element(-1, (0.0, 0.0, 0.0))


@dataclass(frozen=True)
class Row:
    """One scalar constraint (X1 - X2) . (Y1 - Y2) of joint `joint`."""

    joint: str
    label: str
    x1: Element
    x2: Element
    y1: Element
    y2: Element


class ConstraintSet:
    """The rows of a formulation, evaluated together: Phi, Phi_q and zeta (Eqs. 105-109)."""

    def __init__(self, formulation: str, rows: list[Row], n: int):
        self.formulation, self.rows, self.n = formulation, tuple(rows), n
        slots = [[getattr(r, s) for r in rows] for s in ("x1", "x2", "y1", "y2")]
        # world elements use an extra, motionless body n; its Jacobian columns are dropped
        self._body = [np.array([e.body if e.body >= 0 else n for e in sl]) for sl in slots]
        self._vec = [np.array([e.vec for e in sl], dtype=float) for sl in slots]
        self._point = [np.array([e.point for e in sl]) for sl in slots]
        # a slot whose elements are all fixed in the world is a constant: its rates and its
        # Jacobian (the motionless body's columns) vanish
        self._fixed = [not any(e.body >= 0 for e in sl) for sl in slots]
        self._rows = np.arange(len(rows))

    @property
    def m(self) -> int:
        return len(self.rows)

    @property
    def labels(self) -> list[str]:
        return [f"{r.joint}.{r.label}" for r in self.rows]

    def evaluate(self, s: State) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Phi (N, m), Phi_q (N, m, 6n) and zeta (N, m)."""
        N, n = s.r.shape[:2]
        pad = lambda x, fill: np.concatenate([x, np.broadcast_to(fill, (N, 1) + x.shape[2:])], axis=1)  # noqa: E731
        A, Dm = pad(s.A, np.eye(3)), pad(s.D, np.eye(3))
        r, r_dot = pad(s.r, np.zeros(3)), pad(s.r_dot, np.zeros(3))
        w, Dd = pad(s.omega, np.zeros(3)), pad(s.Dd_rate, np.zeros(3))
        rotating = s.Dd_rate.any()  # D' theta' is zero for quasi-velocities
        el = []
        for b, v, pt, fixed in zip(self._body, self._vec, self._point, self._fixed, strict=True):
            if fixed:  # A = E and r = 0 for the world: the element is v itself
                zero = np.zeros((N, len(b), 3))
                el.append((np.broadcast_to(v, (N, len(b), 3)), zero, zero, None))
                continue
            Ab, wb = A[:, b], w[:, b]
            w_x_v = cross(wb, v)
            value = np.einsum("nkab,kb->nka", Ab, v) + pt[None, :, None] * r[:, b]
            vel = np.einsum("nkab,nkb->nka", Ab, w_x_v) + pt[None, :, None] * r_dot[:, b]
            gamma = np.einsum("nkab,nkb->nka", Ab, (cross(Dd[:, b], v) + cross(wb, w_x_v)) if rotating
                              else cross(wb, w_x_v))
            d_rot = -Ab @ skew(v) @ Dm[:, b]  # (N, m, 3, 3): d value / d rate_b
            el.append((value, vel, gamma, d_rot))
        X = [el[0][k] - el[1][k] for k in range(3)]
        Y = [el[2][k] - el[3][k] for k in range(3)]
        phi = np.einsum("nka,nka->nk", X[0], Y[0])
        gamma = (np.einsum("nka,nka->nk", X[2], Y[0]) + 2 * np.einsum("nka,nka->nk", X[1], Y[1])
                 + np.einsum("nka,nka->nk", X[0], Y[2]))
        jac = np.zeros((N, self.m, 6 * (n + 1)))
        for slot, (sign, other) in enumerate(((1, Y[0]), (-1, Y[0]), (1, X[0]), (-1, X[0]))):
            if self._fixed[slot]:
                continue
            b = self._body[slot]
            rot = sign * np.einsum("nka,nkab->nkb", other, el[slot][3])
            lin = sign * other * self._point[slot][None, :, None]
            cols = 6 * b[:, None] + np.arange(3)
            # within one slot each (row, column) occurs once, so fancy-index += adds correctly
            jac[:, self._rows[:, None], cols + 3] += rot
            jac[:, self._rows[:, None], cols] += lin
        return phi, jac[..., : 6 * n], -gamma


def _normals(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors normal to u and to each other."""
    helper = np.eye(3)[np.argmin(np.abs(u))]
    n1 = cross(u, helper)
    n1 /= np.linalg.norm(n1)
    return n1, cross(u, n1)


def _e(body: int, v, point: bool = False) -> Element:
    return Element(body, tuple(float(x) for x in v), point)


def build_constraints(spec: RobotSpec, top: Topology, formulation: str = "normal") -> ConstraintSet:
    """The constraints of every joint O_1..O_n of the graph (any tree)."""
    if formulation not in FORMULATIONS:
        raise ValueError(f"formulation must be one of {FORMULATIONS}, got {formulation!r}")
    index = {b: i for i, b in enumerate(top.bodies)}
    world = np.eye(3)
    rows: list[Row] = []
    for k, name in enumerate(top.joints):
        joint = spec.joint(name)
        j = index[joint.child]
        child = spec.body(joint.child)
        Pj = _e(j, top.c_B[j, k], point=True)
        pj = child.R_WB0.T @ joint.axis_W0  # the axis in the outer body
        ancestor, chain = spec.massive_parent(joint.child)
        if len(chain) > 1 and (chain[0].revolute or len(chain) > 2 or chain[0].parent != WORLD):
            i = index.get(ancestor, -1)
            Pi = _e(-1, joint.p_W0, point=True) if i < 0 else _e(i, top.c_B[i, k], point=True)
            rows += _hinge_chain_rows(spec, name, chain, ancestor, i, Pi, j, Pj)
            continue
        if joint.parent not in index:  # joined to the ground, possibly through a carriage on a rail
            i, Pi, pi = -1, _e(-1, joint.p_W0, point=True), joint.axis_W0
            point_dirs = world if joint.parent == WORLD else np.array(_normals(chain[0].axis_W0))
            normals = _normals(joint.axis_W0)
        else:
            i = index[joint.parent]
            parent = spec.body(joint.parent)
            Pi, pi = _e(i, top.c_B[i, k], point=True), parent.R_WB0.T @ joint.axis_W0
            normals = _normals(pi)
            if not joint.revolute:
                rows += _prismatic_rows(name, i, Pi, pi, j, Pj, pj,
                                        child.R_WB0.T @ parent.R_WB0 @ normals[1])
                continue
            point_dirs = world
        labels = "xyz" if len(point_dirs) == 3 else ("line1", "line2")
        rows += [Row(name, lab, _e(-1, e), ZERO, Pi, Pj) for lab, e in zip(labels, point_dirs, strict=True)]
        if formulation == "paper":
            rows += [Row(name, f"axis{a + 1}", _e(-1, world[a]), ZERO, _e(i, pi), _e(j, pj)) for a in range(2)]
        else:
            rows += [Row(name, f"axis{a + 1}", _e(i, normals[a]), ZERO, _e(j, pj), ZERO) for a in range(2)]
    return ConstraintSet(formulation, rows, top.n)


def _hinge_chain_rows(spec: RobotSpec, name: str, chain: list, ancestor: str, i: int, Pi: Element, j: int,
                      Pj: Element) -> list[Row]:
    """A chain of two or three hinges through massless carriages at one point (a universal joint; a ball
    joint read as its three hinges), from body i (-1: the ground) to body j: the points coincide (3 rows),
    and two hinges keep the angle between their axes, the first's fixed in i, the last's in j:
    (A(0i) a_1^(i)) . (A(0j) a_2^(j) - c A(0i) a_1^(i)) = 0 with c = a_1 . a_2 at q = 0 (1 row); three
    independent axes leave the rotation free. Refused in one line: a slide in the chain (but the rail's),
    more than three hinges, axes that do not span their rotations."""
    axes = np.array([h.axis_W0 / np.linalg.norm(h.axis_W0) for h in chain])
    span = abs(np.linalg.det(axes)) if len(chain) == 3 else float(np.linalg.norm(np.cross(*axes[:2])))
    if any(not h.revolute for h in chain) or len(chain) > 3 or span < CHAIN_AXES:
        raise ValueError(f"joint {name}: the constraint equations read a chain of joints through massless bodies "
                         "as a rail (a prismatic joint from the world, then a hinge) or as two or three hinges at "
                         f"one point whose axes span their rotations ({', '.join(h.name for h in chain)})")
    rows = [Row(name, lab, _e(-1, e), ZERO, Pi, Pj) for lab, e in zip("xyz", np.eye(3), strict=True)]
    if len(chain) == 2:
        a1 = axes[0] if ancestor == WORLD else spec.body(ancestor).R_WB0.T @ axes[0]
        a2 = spec.body(chain[-1].child).R_WB0.T @ axes[1]
        rows.append(Row(name, "angle", _e(i, a1), ZERO, _e(j, a2), _e(i, float(axes[0] @ axes[1]) * a1)))
    return rows


def _prismatic_rows(name, i, Pi, pi, j, Pj, pj, twist_j) -> list[Row]:
    n = _normals(pi)
    rows = [Row(name, f"line{a + 1}", _e(i, n[a]), ZERO, Pj, Pi) for a in range(2)]
    rows += [Row(name, f"axis{a + 1}", _e(i, n[a]), ZERO, _e(j, pj), ZERO) for a in range(2)]
    rows.append(Row(name, "twist", _e(i, n[0]), ZERO, _e(j, twist_j), ZERO))
    return rows
