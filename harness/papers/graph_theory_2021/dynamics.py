"""Section 2.2: the unconstrained dynamics in Cardano coordinates, for all samples at once.

Per body B_i with q_i = (r_i, theta_i), Eqs. 35-37:

    A_i q_i'' = B_i,   A_i = [[m_i E, 0], [0, J_i D_i]],
    B_i = [ m_i g + F_i^J ;  -(J_i D_i' + (D_i theta_i')~ J_i D_i) theta_i' + M_i^J(i) ],

with F_i^J, M_i^J the joint resultants of section 2.1 (world components; (i): body components)
and J_i = diag(J11, J22, J33) in body components. The measured quantities are what the paper's
test bench gives (section 3.1): centre-of-mass accelerations, Cardano angles, and angular velocity
and acceleration in world components, with the joint forces and moments. The angle rates follow
from Eq. 33: theta' = D^-1 omega^(i) and theta'' = D^-1 (omega'^(i) - D' theta'), which needs D
to be invertible: rows near gimbal lock (cond(D) > GIMBAL_COND_D) are reported, not evaluated.

Note: with theta'' obtained through D as above, D cancels from A_i q_i'' - B_i, which reduces to
the Newton-Euler residual; D and D' themselves are checked against a rotation library and
finite differences of the engine's orientation in the tests.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from harness.base.series import TimeSeries
from harness.model.kinematics import skew  # Eq. 31: a~ b = a x b
from harness.model.spec import RobotSpec
from harness.papers.graph_theory_2021.cardano import GIMBAL_COND_D, A_0i, D, D_dot, D_from_rotations, cond_D
from harness.papers.graph_theory_2021.topology import Topology, build_topology, joint_resultants


@dataclass(frozen=True, eq=False)
class GraphModel:
    """The model under test: the graph and each body's m_i and principal J_i (from the spec)."""

    topology: Topology
    m: np.ndarray  # (n,)
    J: np.ndarray  # (n, 3) principal moments J11, J22, J33
    g_W: np.ndarray  # (3,)


def build_graph_model(spec: RobotSpec, gravity_W: np.ndarray) -> GraphModel:
    top = build_topology(spec)
    bodies = [spec.body(b) for b in top.bodies]
    return GraphModel(top, np.array([b.mass for b in bodies]),
                      np.array([b.principal_inertia for b in bodies]), np.asarray(gravity_W, float))


@dataclass(frozen=True, eq=False)
class BodySeries:
    """Measured body quantities in the graph's order, each (N, n, ...)."""

    t: np.ndarray  # (N,)
    theta: np.ndarray  # Cardano angles
    A: np.ndarray  # A(0i), (N, n, 3, 3)
    a_W: np.ndarray  # centre-of-mass acceleration r_i''
    omega_B: np.ndarray  # omega^(i)
    omegadot_B: np.ndarray  # omega'^(i)
    F_J_W: np.ndarray  # joint resultant force on B_i
    M_J_B: np.ndarray  # joint resultant moment about O_ci, body components
    F_J_size: np.ndarray  # (N, n) sum of the sizes of the joint forces on B_i
    M_J_size: np.ndarray  # (N, n) sum of the sizes of the joint moments (about O_ci) on B_i


def body_series(rec: TimeSeries, top: Topology, rows: np.ndarray | None = None) -> BodySeries:
    """Gather the graph's inputs from a recording (optionally at selected rows)."""
    rows = np.arange(len(rec.t)) if rows is None else np.asarray(rows)
    b = [rec.body_index(name) for name in top.bodies]
    j = [rec.joint_index(name) for name in top.joints]
    theta = rec.theta[rows][:, b]
    A = A_0i(theta)
    A_T = np.swapaxes(A, -1, -2)
    F_J_W, M_J_W, F_size, M_size = joint_resultants(top, A, rec.q[rows][:, j], rec.F_W[rows][:, j],
                                                     rec.M_W[rows][:, j])
    return BodySeries(
        t=rec.t[rows], theta=theta, A=A, a_W=rec.a_W[rows][:, b],
        omega_B=np.einsum("niab,nib->nia", A_T, rec.omega_W[rows][:, b]),
        omegadot_B=np.einsum("niab,nib->nia", A_T, rec.omegadot_W[rows][:, b]),
        F_J_W=F_J_W, M_J_B=np.einsum("niab,nib->nia", A_T, M_J_W), F_J_size=F_size, M_J_size=M_size)


def angle_rates(theta: np.ndarray, omega_B: np.ndarray, omegadot_B: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """theta' and theta'' from Eq. 33 where D is well conditioned; NaN elsewhere.
    Returns (theta_dot, theta_ddot, cond(D))."""
    cond = cond_D(theta)
    ok = cond <= GIMBAL_COND_D
    Dm = np.where(ok[..., None, None], D(theta), np.eye(3))
    theta_dot = np.linalg.solve(Dm, omega_B[..., None])[..., 0]
    rhs = omegadot_B - np.einsum("...ab,...b->...a", D_dot(theta, theta_dot), theta_dot)
    theta_ddot = np.linalg.solve(Dm, rhs[..., None])[..., 0]
    theta_dot[~ok] = np.nan
    theta_ddot[~ok] = np.nan
    return theta_dot, theta_ddot, cond


def unconstrained_A(model: GraphModel, theta: np.ndarray) -> np.ndarray:
    """Eq. 37: A_i = blockdiag(m_i E, J_i D_i), (N, n, 6, 6)."""
    N, n = theta.shape[:2]
    A = np.zeros((N, n, 6, 6))
    A[..., :3, :3] = model.m[:, None, None] * np.eye(3)
    A[..., 3:, 3:] = model.J[..., :, None] * D(theta)
    return A


def unconstrained_B(model: GraphModel, s: BodySeries, theta_dot: np.ndarray) -> np.ndarray:
    """Eq. 37: B_i = [m_i g + F_i^J ; -(J_i D_i' + (D_i theta')~ J_i D_i) theta' + M_i^J(i)]."""
    Dm, Dd = D(s.theta), D_dot(s.theta, theta_dot)
    J = model.J[..., :, None]  # diag(J) @ X == J[:, None] * X
    omega = np.einsum("...ab,...b->...a", Dm, theta_dot)
    gyro = J * Dd + skew(omega) @ (J * Dm)
    B = np.empty(s.theta.shape[:2] + (6,))
    B[..., :3] = model.m[:, None] * model.g_W + s.F_J_W
    B[..., 3:] = -np.einsum("...ab,...b->...a", gyro, theta_dot) + s.M_J_B
    return B


@dataclass(frozen=True, eq=False)
class Residual:
    """Eq. 36 on the recording: relative residuals per row and body (NaN where not evaluated)."""

    t: np.ndarray
    translational: np.ndarray  # (N, n) |m r'' - (m g + F^J)| / |m g + F^J|
    rotational: np.ndarray  # (N, n) |J D theta'' - B_rot| / |B_rot|
    cond_D: np.ndarray  # (N, n)
    evaluated: np.ndarray  # (N, n) bool: cond(D) <= GIMBAL_COND_D


AT_REST = 1e-3  # a row whose scale is below this fraction of the run's largest is judged against that


def at_rest_floor(size: np.ndarray) -> np.ndarray:
    """(N, ...) a per-row scale, floored at AT_REST of its largest over the rows (axis 0): a row at
    rest, where every term vanishes, would divide round-off by round-off (0.69 at t = 0 of a
    trajectory that starts at rest, 1e-15 on the next row)."""
    floor = AT_REST * np.max(size, axis=0, initial=0.0)
    return np.maximum(np.maximum(size, floor), np.finfo(float).tiny)


def unconstrained_residual(model: GraphModel, s: BodySeries) -> Residual:
    """A q'' - B at every row where D is well conditioned; the others are listed with cond(D).

    Relative, each part separately, to the size of the terms summed into B_i: gravity and the
    joint forces on the body; the gyroscopic term and the joint moments. That is |B_i| or more; for
    a point mass, whose B_rot vanishes, it is the size of the joint moments that cancel on it. A
    row where all of them vanish (a body at rest whose weight passes through its centre of mass)
    is judged against AT_REST of the body's largest size over the run (at_rest_floor)."""
    theta_dot, theta_ddot, cond = angle_rates(s.theta, s.omega_B, s.omegadot_B)
    qdd = np.concatenate([s.a_W, theta_ddot], axis=-1)
    A = unconstrained_A(model, s.theta)
    B = unconstrained_B(model, s, theta_dot)
    r = np.einsum("...ab,...b->...a", A, qdd) - B
    gyro = np.linalg.norm(B[..., 3:] - s.M_J_B, axis=-1)
    sizes = (np.linalg.norm(model.m[:, None] * model.g_W, axis=-1) + s.F_J_size, gyro + s.M_J_size)
    parts = []
    for sl, size in zip((slice(0, 3), slice(3, 6)), sizes, strict=True):
        num = np.linalg.norm(r[..., sl], axis=-1)
        den = np.maximum(np.linalg.norm(B[..., sl], axis=-1), size)
        parts.append(num / at_rest_floor(den))
    return Residual(s.t, parts[0], parts[1], cond, cond <= GIMBAL_COND_D)



def D_error(theta: np.ndarray) -> float:
    """Largest |D(theta) - D from a rotation library| over the given angles (..., 3): Eq. 33's D
    checked at every recorded orientation. The residual of Eq. 36 and Eq. 111 cannot see a wrong
    D, which cancels from both; with A(0i) equal to the engine's orientation (checked when
    recording), a right D means D theta' is the engine's angular velocity, by the chain rule."""
    return float(np.max(np.abs(D(theta) - D_from_rotations(theta)), initial=0.0))
