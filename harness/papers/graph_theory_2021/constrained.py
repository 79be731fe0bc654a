"""Section 2.5: the constrained dynamics with Lagrange multipliers, Eq. 111, at every sample.

    [[M,    Phi_q^T], [Phi_q, 0]] [q''; lambda] = [Q; zeta]          (Eq. 111)

The paper writes Eq. 110 as A q'' - B + Phi_q^T lambda = 0 with A, B of Eq. 37, whose rotational
rows are Euler's equations in body components (moments), while Phi_theta^T lambda is a
generalized force conjugate to the Cardano angles, D^T times a moment. The two agree only once
the rotational rows are premultiplied by D^T (the Lagrange equations of the first kind in these
coordinates), which is what is solved here:

    M_i = blockdiag(m_i E, D_i^T J_i D_i),
    Q_i = [m_i g + F_i^a ;  D_i^T ( -(J_i D_i' + (D_i theta')~ J_i D_i) theta' + M_i^a(i) )],

with F_i^a, M_i^a the active (drive) forces and moments on B_i: the recorded drive torque tau_J
about each revolute axis, and the rail's drive force along the rail. Everything else a joint
transmits is constraint reaction: -Phi_q^T lambda. The blocks D^T J D are singular where
cos(beta) = 0, so Eq. 111 is too (B1 of kr500 at t = 0).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from harness.base.series import TimeSeries
from harness.model import friction
from harness.model.kinematics import cross, joint_axes_W, skew
from harness.model.spec import RobotSpec
from harness.papers.graph_theory_2021.cardano import GIMBAL_COND_D, D, D_dot
from harness.papers.graph_theory_2021.constraints import ConstraintSet, State
from harness.papers.graph_theory_2021.dynamics import BodySeries, GraphModel, angle_rates, at_rest_floor


def active_wrenches(spec: RobotSpec, model: GraphModel, tau: np.ndarray, A: np.ndarray, r: np.ndarray,
                    q: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Drive forces and moments (about each centre of mass) on every body from the drive forces
    and torques tau (N, joints of the spec), world components, (N, n, 3) each.
    A: (N, n, 3, 3), r: (N, n, 3) in graph order; q (N, joints of the spec), the joint coordinates, needed
    where a chain of hinges through massless carriages turns its middle axes (kinematics.joint_axes_W).
    A drive acts between the body it moves and that body's massive ancestor (carriages pass its wrench on).
    A chain's hinges each drive the component of one moment M along their axes u_k (rows of U, (N, h, 3)),
    u_k . M = tau_k: M = U^+ tau = U^T (U U^T)^-1 tau, in their span (the rest of the joint's moment is the
    constraints'); a lone hinge's is tau u."""
    N = tau.shape[0]
    F = np.zeros((N, model.topology.n, 3))
    M = np.zeros((N, model.topology.n, 3))
    drives, chains = _drives(spec, model)
    for jj, revolute, j, inner, frame, u_frame, c in drives:
        tau_j = tau[:, jj]
        u = np.broadcast_to(u_frame, (N, 3)) if frame is None else np.einsum("nab,b->na", A[:, frame], u_frame)
        if revolute:
            M[:, j] += tau_j[:, None] * u
            if inner is not None:
                M[:, inner] -= tau_j[:, None] * u
        else:
            point = r[:, j] + np.einsum("nab,b->na", A[:, j], c)
            force = tau_j[:, None] * u
            F[:, j] += force
            M[:, j] += cross(point - r[:, j], force)
            if inner is not None:
                F[:, inner] -= force
                M[:, inner] -= cross(point - r[:, inner], force)
    if chains:
        if q is None:
            raise ValueError("a chain of hinges through massless carriages: its axes need the joint coordinates")
        axes = joint_axes_W(spec, model.topology.bodies, A, q)
        for j, inner, hinges in chains:
            # the least-norm M with U M = tau: at a chain's lock (its first and last axes in line) it stays finite
            moment = (np.linalg.pinv(axes[:, list(hinges)]) @ tau[:, list(hinges), None])[..., 0]
            M[:, j] += moment
            if inner is not None:
                M[:, inner] -= moment
    return F, M


@functools.lru_cache(maxsize=8)
def _drives(spec: RobotSpec, model: GraphModel) -> tuple[tuple, tuple]:
    """Per joint of the spec, where its drive acts: (joint, revolute, body j it drives (a carriage's
    drive acts on the body it carries), j's massive ancestor or None (the ground), the body whose frame
    carries the axis (a revolute axis turns with the outer body, a prismatic one with the inner body or
    the ground; None: the world), the axis in that frame, the joint point in body j); and apart, each
    chain of two or more hinges through massless carriages: (j, its ancestor or None, the hinges' spec
    indices, inner first)."""
    top = model.topology
    index = {b: i for i, b in enumerate(top.bodies)}
    names = spec.joint_names
    chains = tuple((index[c[-1].child], index.get(c[0].parent), tuple(names.index(h.name) for h in c))
                   for c in spec.hinge_chains())  # a chain's first joint starts at the massive ancestor
    in_chains = {k for _, _, hinges in chains for k in hinges}
    out = []
    for jj, joint in enumerate(spec.joints):
        if jj in in_chains:
            continue
        carrier = spec.carried_joint(joint.name).child
        j = index[carrier]
        inner = index.get(spec.massive_parent(carrier)[0])
        frame = j if joint.revolute else index.get(joint.parent)
        u = joint.axis_W0 if frame is None else spec.body(top.bodies[frame]).R_WB0.T @ joint.axis_W0
        c = None if joint.revolute else top.c_B[j, top.joints.index(spec.inner_joint(carrier).name)]
        out.append((jj, joint.revolute, j, inner, frame, u, c))
    return tuple(out), chains


def generalized_mass(model: GraphModel, theta: np.ndarray) -> np.ndarray:
    """blockdiag over bodies of (m_i E, D_i^T J_i D_i): (N, 6n, 6n)."""
    N, n = theta.shape[:2]
    Dm = D(theta)
    blocks = np.zeros((N, n, 6, 6))
    blocks[..., :3, :3] = model.m[:, None, None] * np.eye(3)
    blocks[..., 3:, 3:] = np.swapaxes(Dm, -1, -2) @ (model.J[..., :, None] * Dm)
    out = np.zeros((N, 6 * n, 6 * n))
    for i in range(n):
        out[:, 6 * i: 6 * i + 6, 6 * i: 6 * i + 6] = blocks[:, i]
    return out


def generalized_forces(model: GraphModel, theta: np.ndarray, theta_dot: np.ndarray, A: np.ndarray,
                       F_W: np.ndarray, M_W: np.ndarray) -> np.ndarray:
    """Q of Eq. 111 for applied forces F_W and moments M_W about the centres of mass: (N, 6n)."""
    Dm, Dd = D(theta), D_dot(theta, theta_dot)
    J = model.J[..., :, None]
    omega = np.einsum("...ab,...b->...a", Dm, theta_dot)
    gyro = np.einsum("...ab,...b->...a", J * Dd + skew(omega) @ (J * Dm), theta_dot)
    M_B = np.einsum("...ba,...b->...a", A, M_W)
    Q = np.concatenate([model.m[:, None] * model.g_W + F_W,
                        np.einsum("...ba,...b->...a", Dm, M_B - gyro)], axis=-1)
    return Q.reshape(theta.shape[0], -1)


def kkt_matrix(M: np.ndarray, Phi_q: np.ndarray) -> np.ndarray:
    N, p = M.shape[:2]
    m = Phi_q.shape[1]
    K = np.zeros((N, p + m, p + m))
    K[:, :p, :p] = M
    K[:, :p, p:] = np.swapaxes(Phi_q, 1, 2)
    K[:, p:, :p] = Phi_q
    return K


@dataclass(frozen=True, eq=False)
class Constrained:
    """Eq. 111 on the recording, at the rows where every body's cond(D) <= GIMBAL_COND_D and the
    matrix of Eq. 111 is not singular to double precision (cond < 1/eps)."""

    t: np.ndarray  # (N,) all rows
    evaluated: np.ndarray  # (N,) bool
    qdd: np.ndarray  # (N, 6n), NaN where not evaluated
    lam: np.ndarray  # (N, m)
    acceleration_error: np.ndarray  # (N,) |[r''; omega'] - recorded| / |recorded|, per row
    reaction_error: np.ndarray  # (N,) |-Phi_q^T lambda - recorded reactions| / |recorded|
    phi: np.ndarray  # (N, m) constraints on the recording
    phi_dot: np.ndarray  # (N, m) Phi_q q', NaN where not evaluated (theta' needs D^-1)
    Phi_q: np.ndarray  # (N, m, 6n)
    cond_Phi_q: np.ndarray  # (N,) at every row
    cond_system: np.ndarray  # (N,) cond of the (6n + m) matrix of Eq. 111
    rank_Phi_q: np.ndarray  # (N,)


EQUILIBRATION_SWEEPS = 30  # alternate row and column scalings: converged to 1e-9 on random matrices
EQUILIBRATED = 1e-12  # every row and column norm within this of 1: converged, stop early
ROUND_OFF = 64 * np.finfo(float).eps  # relative to a matrix's largest entry: what products of its data leave
RANK_TOL = 1e-10  # singular values below this fraction of the largest (equilibrated) count as zero: the
# scaling amplifies round-off in a structurally deficient matrix to 1e-13 (kr500's paper rows), and a
# matrix full rank to 1e-10 is still solved to about six digits


def equilibrate(X: np.ndarray) -> np.ndarray:
    """(N, r, c) matrices with rows and columns scaled, alternately, to unit Euclidean norm
    (Sinkhorn-Knopp on the squared entries), so that a condition number or rank depends little on
    the units of the coordinates (m, rad) or of the constraint rows. cond and rank are reported and
    decided on this form. The scaling stops after EQUILIBRATION_SWEEPS: a rectangular Phi_q (its
    rows and columns cannot all reach unit norm) and Eq. 111's matrix (its zero block) do not
    converge by then, and on kr500_rail a change of units by up to 10 per row and column moves
    cond(Eq. 111) by 0.5 % (median over the rows; 5 % at most), far from the 1/eps that decides
    a row singular. Entries at round-off of the largest are zero first: scaled up, an entry of 1e-17
    in a row of nothing would pass for data. The scalings are iterated as vectors, u (N, r) and
    v (N, c) with diag(u) X diag(v) the scaled matrix, two batched matrix-vector products with the
    squared entries a sweep, and applied once at the end (scaling the matrix itself at every sweep
    read and wrote it four times)."""
    X = np.array(X, dtype=float)
    size = np.max(np.abs(X), axis=(1, 2), keepdims=True)
    X[np.abs(X) <= ROUND_OFF * size] = 0.0
    A = X * X
    u, v = np.ones(X.shape[:2]), np.ones((X.shape[0], X.shape[2]))
    for _ in range(EQUILIBRATION_SWEEPS):
        rows = (A @ (v * v)[:, :, None])[:, :, 0]  # each row's squared norm over u^2
        rows_now = np.sqrt(u * u * rows)  # the scaled matrix's row norms before this sweep
        u = 1.0 / np.sqrt(np.where(rows > 0, rows, 1.0))  # an empty row keeps u = 1
        cols = ((u * u)[:, None, :] @ A)[:, 0, :]
        cols_now = np.sqrt(v * v * cols)
        v = 1.0 / np.sqrt(np.where(cols > 0, cols, 1.0))
        if (np.all(np.abs(rows_now[rows > 0] - 1.0) < EQUILIBRATED)
                and np.all(np.abs(cols_now[cols > 0] - 1.0) < EQUILIBRATED)):
            break  # a further sweep would change no entry by more than this
    return u[:, :, None] * X * v[:, None, :]


def _cond_rank(X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Condition number and numerical rank of the equilibrated matrices."""
    s = np.linalg.svd(equilibrate(X), compute_uv=False)
    with np.errstate(divide="ignore"):
        cond = np.where(s[:, -1] > 0, s[:, 0] / s[:, -1], np.inf)
    rank = np.sum(s > s[:, :1] * RANK_TOL, axis=1)
    return cond, rank


def solve_constrained(spec: RobotSpec, model: GraphModel, constraints: ConstraintSet,
                      rec: TimeSeries, s: BodySeries) -> Constrained:
    """Solve Eq. 111 at every row (batched) and check it against what MuJoCo recorded."""
    top = model.topology
    b = [rec.body_index(name) for name in top.bodies]
    theta_dot, _, cond_D = angle_rates(s.theta, s.omega_B, s.omegadot_B)
    ok = np.all(cond_D <= GIMBAL_COND_D, axis=1)
    thd = np.where(ok[:, None, None], theta_dot, 0.0)
    state = State.cardano(rec.p_W[:, b], s.theta, rec.v_W[:, b], thd)
    phi, Phi_q, zeta = constraints.evaluate(state)
    phi_dot = np.where(ok[:, None], np.einsum("nmk,nk->nm", Phi_q, state.q_dot), np.nan)
    M = generalized_mass(model, s.theta)
    cols = [rec.joint_index(j) for j in spec.joint_names]
    # the drives' friction and rotor inertia act between motor and joint: the bodies get the rest (a
    # load-dependent term read back from the drive torque: friction.rigid_torque)
    tau = friction.rigid_torque(spec.frictions, rec.tau[:, cols], rec.qd[:, cols], rec.qdd[:, cols], rec.q[:, cols])
    F_a, M_a = active_wrenches(spec, model, tau, s.A, state.r, rec.q[:, cols])
    Q = generalized_forces(model, s.theta, thd, s.A, F_a, M_a)
    K = kkt_matrix(M, Phi_q)
    cond_Phi, rank_Phi = _cond_rank(Phi_q)
    cond_K, _ = _cond_rank(K)
    # singular to double precision: no solution is computed (the paper's axis rows in kr500_rail)
    ok = ok & (cond_K < 1.0 / np.finfo(float).eps)

    N, p, m = len(s.t), M.shape[1], Phi_q.shape[1]
    qdd = np.full((N, p), np.nan)
    lam = np.full((N, m), np.nan)
    acc_err = np.full(N, np.nan)
    react_err = np.full(N, np.nan)
    if ok.any():
        x = np.linalg.solve(K[ok], np.concatenate([Q, zeta], axis=1)[ok][..., None])[..., 0]
        qdd[ok], lam[ok] = x[:, :p], x[:, p:]
        qdd_b = qdd[ok].reshape(-1, top.n, 6)
        omegadot = (np.einsum("...ab,...b->...a", D(s.theta[ok]), qdd_b[..., 3:])
                    + np.einsum("...ab,...b->...a", D_dot(s.theta[ok], thd[ok]), thd[ok]))
        got = np.concatenate([qdd_b[..., :3], omegadot], axis=-1).reshape(ok.sum(), -1)
        want = np.concatenate([s.a_W[ok], s.omegadot_B[ok]], axis=-1).reshape(ok.sum(), -1)
        acc_err[ok] = np.linalg.norm(got - want, axis=1) / at_rest_floor(np.linalg.norm(want, axis=1))
        # recorded constraint reactions: joint resultants less the drives, generalized
        F_c = s.F_J_W[ok] - F_a[ok]
        M_c_B = s.M_J_B[ok] - np.einsum("...ba,...b->...a", s.A[ok], M_a[ok])
        G = np.concatenate([F_c, np.einsum("...ba,...b->...a", D(s.theta[ok]), M_c_B)], axis=-1)
        G = G.reshape(ok.sum(), -1)
        reaction = -np.einsum("nmk,nm->nk", Phi_q[ok], lam[ok])
        react_err[ok] = np.linalg.norm(reaction - G, axis=1) / at_rest_floor(np.linalg.norm(G, axis=1))
    return Constrained(s.t, ok, qdd, lam, acc_err, react_err, phi, phi_dot, Phi_q, cond_Phi, cond_K, rank_Phi)
