"""Physically consistent inertial parameters from joint torques: a semidefinite program.

Least squares determines the base parameters only, and nothing keeps the full parameters they
stand for physical. Here all 10 parameters of every link (and each joint's friction and rotor
inertia) are fitted at once, subject to each link's pseudo-inertia matrix being positive
semidefinite (Wensing, Kim and Slotine, "Linear matrix inequalities for physically consistent
inertial parameter identification", IEEE RA-L 2018):

    J_i = [[Sigma_i, h_i], [h_i^T, m_i]] >= 0,   Sigma_i = tr(I_i)/2 1 - I_i,

with I_i the inertia about the link's frame origin and h_i = m_i c_i. J_i >= 0 holds exactly when
the link is a mass distribution: m >= 0, and the inertia about the centre of mass positive
semidefinite and satisfying the triangle inequality; J_i >= eps_i 1 (MARGIN of the largest eigenvalue
of the link's own pseudo-inertia in the model, `margins`) keeps the mass and the principal moments
strictly positive, at a scale of each link's own (one margin for all, of the model's largest link, would
hold a hand's finger links, whose pseudo-inertia can be 1.5e-4 of the arm's, above their own bodies).
Viscous and Coulomb friction and rotor inertia are kept non-negative; the offset is free.

The objective is the torque residual plus a small pull towards the model's own values,

    ||W theta + W_f phi - tau||^2 / r_0^2 + PULL * ||(theta - theta_0) / s||^2 / p,

so the directions the data cannot see (the parameters outside the base ones) settle at the
model's values rather than anywhere, while the data decide everything they can (r_0 is the
least-squares residual, so PULL = 1e-4 costs the fit at most that fraction; s is each parameter's
magnitude of its kind in the model). An SDP rather
than a log-Cholesky parametrisation: the problem stays convex, so the solution is the global one
and needs no starting point, and cvxpy with the interior-point solver Clarabel solves the
Panda's 98 unknowns in well under a second. The torque residual is first reduced to the
triangular factor of W's QR decomposition (p rows instead of N n).

Where Clarabel fails (an error, or a panic of its own), SCS (a first-order conic solver) tries the
same problem; a solution short of the solver's tolerances ("optimal_inaccurate"), or SCS's, is kept,
said so, and moved onto the constraints it may miss by the solver's tolerance (each link to the
nearest physical one, as below). Where both fail, the
unconstrained minimum of the same objective is taken and each link's pseudo-inertia moved to the
nearest one with every eigenvalue at least the margin (harness/model/inertia.py, nearest_physical),
the friction terms clipped at zero. Which of the three gave the fit is `fallback` (0, 1, 2), a
number a gate can read; a fit never fails.
"""

from __future__ import annotations

import dataclasses
import warnings
from dataclasses import dataclass, field

import cvxpy as cp
import numpy as np

from harness.base.numerics import PARAMETER_FLOOR, SideBySide, column_scale, relative_residual, triangle
from harness.base.tomlio import in_one_line
from harness.identify.laws import Law, extra_terms
from harness.identify.torque_id import SAMPLES_AT_A_TIME
from harness.model import drives
from harness.model.drives import Transmission
from harness.model.friction import BOUNDED_BY, IDENTIFIED_KEYS, JointFriction
from harness.model.inertia import (
    MOMENT_FLOOR,
    about_centre_of_mass,
    model_kind_scales,
    nearest_physical,
    pseudo_inertia,
)

PULL = 1e-4  # weight of the pull towards the model's values, relative to the least-squares residual
# the objective is 1 at the least-squares optimum: 1e-7 of it is far below anything the data resolve
# (Clarabel's default 1e-8 flags the Panda's fit "inaccurate" without changing it in any digit shown)
SOLVER_TOLERANCES = {"tol_gap_abs": 1e-7, "tol_gap_rel": 1e-7, "tol_feas": 1e-7}
# SCS is first-order: its tolerances are looser, and it is the second choice
SOLVERS = ((cp.CLARABEL, SOLVER_TOLERANCES), (cp.SCS, {"eps_abs": 1e-9, "eps_rel": 1e-9, "max_iters": 200_000}))
FALLBACKS = ("solved by Clarabel to its tolerances", "solved by SCS, or short of the solver's tolerances",
             "no solver succeeded: the unconstrained minimum, each link moved to the nearest physical one")
RESIDUAL_FLOOR = 1e-6  # of ||tau||: the least-squares residual taken as at least this (see `fit`)
MARGIN = 1e-6  # J_i >= MARGIN * (the link's largest pseudo-inertia eigenvalue in the model) 1: strictly physical
MASS_BAND = (0.1, 10.0)  # each link's identified mass within these times its model's, unless the data demand more
DEMAND = 0.01  # the fit free of the band explains the training torques this much (relative residual) better:
# the data demand a mass beyond it (more freedom always explains a little more; a hundredth is not noise's doing)
AT_BAND = 1e-4  # a mass within this (relative) of the band's edge is held there (an interior-point solution stops
# short of an active bound by its tolerance: 6e-6 of it on the Panda's log)


# J_i's sixteen entries as a linear map of the link's ten parameters (16, 10): the columns are
# pseudo_inertia of each unit parameter, so the map is harness/model/inertia.py's, written there once. One
# affine expression per link rather than sixteen of scalars: cvxpy compiles the Panda's fit 2 to 3
# times faster so.
PSEUDO_INERTIA_MAP = np.stack([pseudo_inertia(unit).ravel() for unit in np.eye(10)], axis=1)


# A link is judged physical when its pseudo-inertia's smallest eigenvalue is at least -PSD_TOLERANCE of
# its largest. A fit held to the cone by an interior-point solver ends on the cone's boundary to the
# solver's accuracy, not to round-off: FIGAROH's physical fit (cvxopt, feasibility tolerance 1e-7)
# leaves the Panda's links 4 to 7 at -4e-12 to -8e-12 (2e-12 to 7e-11 of their largest eigenvalue)
# on an Intel Xeon, above -1e-12 max(1, m) on an AMD EPYC; FIGAROH itself accepts -1e-8. Eigenvalues
# computed from J carry round-off of about 1e-16 of the largest, and a link past physical by
# anything a torque shows is far beyond 1e-9 (FIGAROH's least-squares split of the same log:
# -2e-3 to -1.1).
PSD_TOLERANCE = 1e-9


def consistency(theta: np.ndarray) -> dict:
    """One link's physical consistency: mass, principal moments about the centre of mass, the
    triangle inequality's slack, and the smallest eigenvalue of J (consistent: at least
    -PSD_TOLERANCE times its largest)."""
    m = float(theta[0])
    J = pseudo_inertia(theta)
    eigenvalues = np.linalg.eigvalsh(J)
    out = {"mass": m, "min_eig_pseudo_inertia": float(eigenvalues[0])}
    if m > 0:
        p = np.linalg.eigvalsh(about_centre_of_mass(theta)[2])
        out.update(principal_moments=[float(x) for x in p], triangle_slack=float(p[0] + p[1] - p[2]))
    out["consistent"] = bool(eigenvalues[0] >= -PSD_TOLERANCE * max(abs(eigenvalues[-1]), np.finfo(float).tiny))
    return out


@dataclass(frozen=True, eq=False)
class ConsistentFit:
    theta: np.ndarray  # (n_links, 10)
    friction: np.ndarray  # (n_joints, 4): armature, viscous, coulomb, offset
    status: str  # the solver's
    relative_residual: float  # ||W x - tau|| / ||tau|| on the training data
    solver: str = "CLARABEL"  # which gave it, or "projection" (no solver succeeded)
    fallback: int = 0  # 0 Clarabel to its tolerances, 1 SCS or Clarabel inaccurate, 2 projection (FALLBACKS)
    attempts: tuple[str, ...] = ()  # every solver tried and how it ended, in order
    margin: np.ndarray | None = None  # (n,) the smallest pseudo-inertia eigenvalue each link was held to (`margins`)
    extra: np.ndarray = field(default_factory=lambda: np.zeros(0))  # the friction families' coefficients (`fit`)
    held_at_band: tuple[int, ...] = ()  # links whose mass the band held at its edge (MASS_BAND)
    beyond_band: tuple[int, ...] = ()  # links whose mass the data demand beyond the band (DEMAND)
    free_residual: float | None = None  # the training residual of the fit free of the band, where it was made


def fit(W: np.ndarray | SideBySide, tau: np.ndarray, theta_model: np.ndarray, friction_model: np.ndarray,
        scale: np.ndarray, extra: tuple[tuple[int, str], ...] = (), extra_model: np.ndarray | None = None
        ) -> ConsistentFit:
    """W: (rows, 10 n + 4 n + e) regressor (inertial columns, then friction columns, joint by joint,
    harness/identify/torque_id.py, then the columns of the friction families' coefficients `extra`,
    (joint, harness/model/friction.py EXTRA_KEYS name) each), an array or blocks side by side never joined
    (harness/base/numerics.py, SideBySide); tau: (rows,); theta_model (n, 10),
    friction_model (n, 4) and extra_model (e,): the model's own values; scale: (14 n + e,) the
    magnitude of each parameter's kind in the model. The families' terms are held physical: an
    asymmetry no larger than its coefficient (so that both directions' coefficients stay
    non-negative), Stribeck and load terms non-negative. Each link's mass stays within MASS_BAND
    times its model's: what the data cannot see stays near the model rather than at whatever the
    margin allows. Where the fit puts a mass beyond the band, it is made again with the band and the
    fit free of it kept only where it explains the training torques DEMAND better (the data demand
    that mass: `beyond_band`), else the band's taken (`held_at_band`)."""
    n = len(theta_model)
    extra_model = np.zeros(len(extra)) if extra_model is None else extra_model
    x0 = np.concatenate([theta_model.ravel(), friction_model.ravel(), extra_model])
    col = column_scale(W)
    p = len(col)
    R, b, _ = triangle(W, tau, col)
    norm_tau = float(np.linalg.norm(tau))
    z = cp.Variable(p)  # x * col: the column-scaled unknowns, so that R is well scaled
    x = cp.multiply(z, 1.0 / col)
    pull = cp.sum_squares(cp.multiply(x - x0, 1.0 / scale)) / p
    # the fit term relative to the least-squares optimum (1 at best), so that the pull, PULL of it,
    # stays well above the solver's tolerances; on data a model fits exactly (a noise-free bench
    # log) the optimum is taken as RESIDUAL_FLOOR of the torques, or the objective's scale (1/r0)
    # grows past what an interior-point solver can take (Clarabel then fails on its PSD cones)
    r0 = max(float(np.linalg.norm(R @ np.linalg.lstsq(R, b, rcond=None)[0] - b) ** 2
                   + norm_tau**2 - float(b @ b)), (RESIDUAL_FLOOR * norm_tau) ** 2, 1e-300)
    objective = cp.sum_squares(R @ z - b) / r0 + PULL * pull
    eps = margins(theta_model)
    constraints = [cp.reshape(PSEUDO_INERTIA_MAP @ x[10 * i: 10 * i + 10], (4, 4), order="C") - eps[i] * np.eye(4) >> 0
                   for i in range(n)]
    # armature, viscous, Coulomb non-negative; the offset is free
    constraints.append(x[10 * n + (4 * np.arange(n)[:, None] + np.arange(3)).ravel()] >= 0)
    asymmetric = [(14 * n + c, 10 * n + 4 * k + ASYMMETRY[key]) for c, (k, key) in enumerate(extra) if key in ASYMMETRY]
    signed = [14 * n + c for c, (_, key) in enumerate(extra) if key not in ASYMMETRY]
    if asymmetric:  # an asymmetry no larger than its symmetric coefficient, either way
        e, bound = (np.array(a) for a in zip(*asymmetric, strict=True))
        constraints += [x[bound] - x[e] >= 0, x[bound] + x[e] >= 0]
    if signed:
        constraints.append(x[np.array(signed)] >= 0)
    massive = [i for i in range(n) if theta_model[i, 0] > 0]
    free = _solved(cp.Problem(cp.Minimize(objective), constraints), z, W, tau, col, R, b, r0, x0, scale, eps, n, extra)
    ratio = free[0][10 * np.arange(n)] / np.where(theta_model[:, 0] > 0, theta_model[:, 0], np.inf)
    beyond = tuple(i for i in massive if not MASS_BAND[0] <= ratio[i] <= MASS_BAND[1])
    if not beyond:
        return _result(free, n, eps)
    lo, hi = (np.array([MASS_BAND[k] * theta_model[i, 0] for i in massive]) for k in (0, 1))
    band = [x[10 * np.array(massive)] >= lo, x[10 * np.array(massive)] <= hi]
    # the band's fit may explain the torques far worse than the least squares (data that demand a mass
    # beyond it): its fit term is scaled by the least squares' optimum within the band on the masses
    # alone (scipy's bounded least squares), so that its objective stays of order one for the solver
    r0_band = _band_floor(R, b, col, norm_tau, massive, lo, hi, r0)
    objective_band = cp.sum_squares(R @ z - b) / r0_band + PULL * pull
    bounded = _solved(cp.Problem(cp.Minimize(objective_band), constraints + band), z, W, tau, col, R, b, r0_band,
                      x0, scale, eps, n, extra, (massive, lo, hi))
    if free[1] < (1.0 - DEMAND) * bounded[1]:  # the data demand the masses the band would hold
        return dataclasses.replace(_result(free, n, eps), beyond_band=beyond, free_residual=free[1])
    ratio = bounded[0][10 * np.arange(n)] / np.where(theta_model[:, 0] > 0, theta_model[:, 0], np.inf)
    held = tuple(i for i in massive
                 if ratio[i] <= MASS_BAND[0] * (1 + AT_BAND) or ratio[i] >= MASS_BAND[1] * (1 - AT_BAND))
    return dataclasses.replace(_result(bounded, n, eps), held_at_band=held, free_residual=free[1])


def margins(theta_model: np.ndarray) -> np.ndarray:
    """Each link's margin (n,): MARGIN of the largest eigenvalue of its own pseudo-inertia in the model, so
    that a small link beside a large one (a finger on an arm) is held as near singular as its own size
    allows; a link the model gives no mass, MARGIN of the model's largest."""
    sizes = np.array([float(np.max(np.linalg.eigvalsh(pseudo_inertia(t)))) for t in theta_model])
    return MARGIN * np.where(theta_model[:, 0] > 0, sizes, np.max(sizes, initial=0.0))


def _result(solved: tuple, n: int, eps: np.ndarray) -> ConsistentFit:
    xv, residual, status, solver, fallback, attempts = solved
    return ConsistentFit(xv[: 10 * n].reshape(n, 10), xv[10 * n: 14 * n].reshape(n, 4), status, residual, solver,
                         fallback, tuple(attempts), eps, xv[14 * n:])


def _band_floor(R: np.ndarray, b: np.ndarray, col: np.ndarray, norm_tau: float, massive: list[int], lo: np.ndarray,
                hi: np.ndarray, r0: float) -> float:
    """The squared residual of the least squares with the masses of `massive` links within [lo, hi]
    (scipy.optimize.lsq_linear on the column-scaled triangle R z = b), as the fit's r0 is: at least r0."""
    from scipy.optimize import lsq_linear

    lower, upper = np.full(R.shape[1], -np.inf), np.full(R.shape[1], np.inf)
    where = 10 * np.asarray(massive, dtype=int)
    lower[where], upper[where] = lo * col[where], hi * col[where]
    z = lsq_linear(R, b, bounds=(lower, upper)).x
    bounded = float(np.linalg.norm(R @ z - b) ** 2 + norm_tau**2 - float(b @ b))
    return bounded if bounded > (1.0 + DEMAND) * r0 else r0  # the band that binds the least squares rescales


def _solved(problem: cp.Problem, z: cp.Variable, W, tau: np.ndarray, col: np.ndarray, R: np.ndarray, b: np.ndarray,
            r0: float, x0: np.ndarray, scale: np.ndarray, eps: np.ndarray, n: int, extra: tuple, band=None) -> tuple:
    """`problem` solved by the first of SOLVERS that gives a solution (a looser one moved onto the
    constraints), or its objective's projection where none does, each mass then within `band` (its links,
    lower and upper masses) where one is given: (x, the training residual, status, solver, fallback,
    attempts)."""
    attempts: list[str] = []
    found = None  # (z, status, solver, fallback)
    for k, (solver, options) in enumerate(SOLVERS):
        # where a solver stops short of its tolerances, cvxpy warns; the status ("optimal_inaccurate")
        # is kept instead, into results.json and the report. A model whose links sit on the margin
        # (one exported by this fit, fitted again to the same log) can end there.
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message="Solution may be inaccurate", category=UserWarning)
            try:
                problem.solve(solver=solver, **options)
            except (KeyboardInterrupt, SystemExit):
                raise
            except BaseException as exc:  # a solver's own failure, a Rust panic of Clarabel's included
                attempts.append(f"{solver}: failed ({in_one_line(str(exc)) or type(exc).__name__})")
                continue
        attempts.append(f"{solver}: {problem.status}")
        if z.value is None or not np.all(np.isfinite(z.value)) or problem.status not in cp.settings.SOLUTION_PRESENT:
            continue
        found = (np.array(z.value), str(problem.status), solver, 0 if problem.status == cp.OPTIMAL and k == 0 else 1)
        break
    if found is None:
        xv = _projected(R, b, col, r0, x0, scale, eps, n, extra)
        status, solver, fallback = "projected", "projection", 2
    else:
        zv, status, solver, fallback = found
        xv = zv / col
        if fallback:  # a looser solution may sit just outside the constraints: moved onto them
            xv = _physical(xv, eps, n, extra)
    if band is not None and fallback:  # each link scaled whole into the band (a positive factor keeps it physical)
        massive, lo, hi = band
        for k, i in enumerate(massive):
            m = xv[10 * i]
            if m > 0 and not lo[k] <= m <= hi[k]:
                xv[10 * i: 10 * i + 10] *= np.clip(m, lo[k], hi[k]) / m
    return xv, relative_residual(W @ xv - tau, tau), status, solver, fallback, attempts


def _projected(R: np.ndarray, b: np.ndarray, col: np.ndarray, r0: float, x0: np.ndarray, scale: np.ndarray,
               eps: np.ndarray, n: int, extra: tuple = ()) -> np.ndarray:
    """The fit's objective minimised without its constraints (a linear system: the pull makes it
    definite), then each link moved to the nearest physical one and the friction terms but the
    offset clipped at zero."""
    p = len(col)
    d = np.sqrt(PULL / p) / (scale * col)  # the pull on each column-scaled unknown, as a row of its own
    # least squares of the stacked rows rather than the normal equations, whose condition is the
    # square of this one's (a noise-free log's r0 is round-off small)
    z = np.linalg.lstsq(np.vstack([R / np.sqrt(r0), np.diag(d)]),
                        np.concatenate([b / np.sqrt(r0), d * x0 * col]), rcond=None)[0]
    return _physical(z / col, eps, n, extra)


def _physical(x: np.ndarray, eps: np.ndarray, n: int, extra: tuple = ()) -> np.ndarray:
    """Each link's parameters moved to the nearest with every pseudo-inertia eigenvalue at least its eps,
    the friction terms but the offset clipped at zero, and the families' terms clipped as `fit`
    holds them: the constraints of the fit, made to hold."""
    theta = np.stack([nearest_physical(t, e) for t, e in zip(x[: 10 * n].reshape(n, 10), eps, strict=True)])
    friction = x[10 * n: 14 * n].reshape(n, 4).copy()
    friction[:, :3] = np.maximum(friction[:, :3], 0.0)
    terms = x[14 * n:].copy()
    for c, (k, key) in enumerate(extra):
        bound = friction[k, ASYMMETRY[key]] if key in ASYMMETRY else None
        terms[c] = np.clip(terms[c], -bound, bound) if bound is not None else max(terms[c], 0.0)
    return np.concatenate([theta.ravel(), friction.ravel(), terms])


# the asymmetry -> its symmetric coefficient's place in (n, 4) (friction.BOUNDED_BY)
ASYMMETRY = {key: IDENTIFIED_KEYS.index(bound) for key, bound in BOUNDED_BY.items()}


def fit_with_laws(W: np.ndarray, E: np.ndarray, tau: np.ndarray, laws: tuple[Law, ...], theta_model: np.ndarray,
                   friction_model: np.ndarray, extra_model: np.ndarray, transmission: Transmission | None = None,
                   reach: np.ndarray | None = None) -> tuple[ConsistentFit, tuple[JointFriction, ...]]:
    """The physically consistent fit (`fit`) of the torques tau (N, m) on the
    regressor W (N m, 14 n: every link's ten parameters, every joint's four drive terms at its law's
    velocities) and the families' columns E (N m, e, extra_terms(laws)), pulled towards the model's
    own values (theta_model (n, 10), friction_model (n, 4), extra_model (e,)) where the data cannot
    tell; and each drive's identified friction law (each joint's, or with a transmission each motor's).
    The torques' rows are every joint's (m = n), or `reach` (drives, m) says which of them each drive's
    columns reach: a transmission's (N != 0; of every joint where `reach` is not given), a closed
    chain's actuated joints, an open tree's measured joints (harness/stages/log_model.py)."""
    N, m = tau.shape
    n = len(theta_model)
    terms = extra_terms(laws)
    if transmission is not None and reach is None:
        reach = np.zeros((n, n), dtype=bool)  # (motors, joints): where each drive's columns are (drives.reach)
        for j, k, _ in drives.reach(transmission, n):
            reach[k, j] = True
    # magnitudes for the pull towards the model: the inertial parameters' kinds in the model; a
    # friction term's, the value that alone would carry its joint's whole torque (rms over rms)
    if reach is None:
        rms_cols = np.sqrt(_friction_squares(W, N, n, over_joints=False)).reshape(n, n, 4)
        cols = rms_cols[np.arange(n), np.arange(n)]  # joint j's own four columns, on its own rows
        rms_tau = np.sqrt(np.mean(tau**2, axis=0))
        extra_rms = np.sqrt(np.mean(E.reshape(N, n, -1) ** 2, axis=0))  # (n, e): each column's RMS on each joint's rows
        extra_rms = np.array([extra_rms[k, c] for c, (k, _) in enumerate(terms)])
    else:  # a drive's columns over every row they reach, against the torque of the rows they reach
        cols = np.sqrt(_friction_squares(W, N, n, over_joints=True, rows=m))
        rms_tau = np.sqrt(((tau**2).mean(axis=0) @ reach.T) / np.maximum(reach.sum(axis=1), 1))
        extra_rms = np.sqrt(np.sum(E**2, axis=0) / N)
    carry = rms_tau[:, None] / np.where(cols > 0, cols, 1.0)
    friction_scale = np.maximum(np.abs(friction_model), carry)
    friction_scale = np.maximum(friction_scale, PARAMETER_FLOOR * friction_scale.max(axis=0, initial=0.0))  # a joint
    # that carries nothing has no size of its own
    extra_scale = np.array([max(abs(extra_model[c]), rms_tau[k] / max(float(extra_rms[c]), 1e-300))
                            for c, (k, _) in enumerate(terms)])
    scale = np.concatenate([model_kind_scales(theta_model).ravel(), friction_scale.ravel(), extra_scale])
    result = fit(SideBySide((W, E)), tau.reshape(-1), theta_model, friction_model, scale, tuple(terms), extra_model)
    frictions = tuple(law.friction(*result.friction[k], **{key: result.extra[c] for c, (kk, key) in enumerate(terms)
                                                           if kk == k})
                      for k, law in enumerate(laws))
    return result, frictions


def _friction_squares(W, N: int, n: int, over_joints: bool, rows: int | None = None) -> np.ndarray:
    """The mean over the N samples of each friction column's square: on each joint's rows (n, 4 n), or
    `over_joints` summed over them (n, 4; `rows` per sample where they are not the n joints'); of a
    regressor held whole (numpy's reductions of the squares, as ever), or made on demand (summed a
    chunk of samples at a time: harness/identify/span_rows.py)."""
    if isinstance(W, np.ndarray):
        if over_joints:
            return np.sum(W[:, 10 * n:].reshape(N, rows or n, n, 4) ** 2, axis=(0, 1)) / N
        return np.mean(W[:, 10 * n:].reshape(N, n, -1) ** 2, axis=0)
    total = np.zeros((n, 4 * n))
    for a in range(0, N, SAMPLES_AT_A_TIME):
        F = W.samples(a, a + SAMPLES_AT_A_TIME)[:, :, 10 * n:]
        total += np.einsum("snc,snc->nc", F, F)
    return total.sum(axis=0).reshape(n, 4) / N if over_joints else total / N


PLAUSIBLE = 3.0  # a link's identified mass or inertia more than 3 times, or under a third of, the model's: warned
ON_MARGIN = 1.01  # a link whose smallest pseudo-inertia eigenvalue is within 1 % of the fit's margin sits on it


def plausibility(theta: np.ndarray, theta_model: np.ndarray, joints: list[str], margin: np.ndarray) -> dict:
    """Beside consistency, plausibility: per link (by its joint) the identified mass and the trace of
    the inertia about the centre of mass as ratios to the model's own; the links outside
    [1/PLAUSIBLE, PLAUSIBLE] on either; and the links on the fit's positive-definiteness margin
    (their smallest pseudo-inertia eigenvalue within ON_MARGIN of it), which the data pushed there. A
    link to which the model gives no inertia of its own (a point mass: its trace under MOMENT_FLOOR of
    the model's largest) has no inertia ratio: it is listed as not judged, and why."""
    ratios, outside, on_margin, unjudged = {}, [], [], []
    traces0 = [float(np.trace(about_centre_of_mass(th)[2])) if th[0] > 0 else 0.0 for th in theta_model]
    sized = MOMENT_FLOOR * max(traces0, default=0.0)
    for k, j in enumerate(joints):
        m, m0 = float(theta[k][0]), float(theta_model[k][0])
        tr = float(np.trace(about_centre_of_mass(theta[k])[2])) if m > 0 else float("nan")
        tr0 = traces0[k] if traces0[k] > sized else float("nan")
        if m0 > 0 and not traces0[k] > sized:
            unjudged.append(j)
        with np.errstate(divide="ignore", invalid="ignore"):
            r = {"mass": m / m0 if m0 > 0 else float("nan"), "inertia_trace": tr / tr0 if tr0 > 0 else float("nan")}
        ratios[j] = r
        if any(np.isfinite(v) and not 1 / PLAUSIBLE <= v <= PLAUSIBLE for v in r.values()):
            outside.append(j)
        if np.linalg.eigvalsh(pseudo_inertia(theta[k]))[0] <= ON_MARGIN * margin[k]:
            on_margin.append(j)
    return {"definition": f"per link, identified / model: its mass and the trace of its inertia about the centre "
                          f"of mass; implausible outside [1/{PLAUSIBLE:g}, {PLAUSIBLE:g}]; on_margin: links whose "
                          f"smallest pseudo-inertia eigenvalue is within {ON_MARGIN:g} x the fit's margin",
            "band": [1 / PLAUSIBLE, PLAUSIBLE], "ratios": ratios, "implausible": outside,
            "implausible_links": len(outside), "on_margin": on_margin, "links_on_margin": len(on_margin),
            "inertia_not_judged": unjudged}


def plausibility_warnings(p: dict) -> list[str]:
    """What the terminal and the report are told of `plausibility`'s findings, each saying how it stands
    beside physical consistency (the gate on inconsistent links), which it does not contradict: a link
    on the margin or far from the model's is a rigid body's all the same."""
    out = []
    if p["implausible"]:
        out.append(f"identified links far from the model's (mass or inertia beyond {PLAUSIBLE:g} times, or under "
                   f"1/{PLAUSIBLE:g} of, its own; physically consistent all the same: plausibility judges them against "
                   "the model, consistency against a rigid body's): " + ", ".join(
                       f"{j} (mass x{p['ratios'][j]['mass']:.3g}, inertia x{p['ratios'][j]['inertia_trace']:.3g})"
                       for j in p["implausible"]))
    if p["inertia_not_judged"]:
        out.append("the model gives no inertia of their own to " + ", ".join(p["inertia_not_judged"])
                   + " (a point mass): their identified inertia is judged against nothing (plausibility.ratios)")
    if p["on_margin"]:
        out.append(f"{len(p['on_margin'])} link(s) held on the fit's positive-definiteness margin: physically "
                   "consistent (as the consistency gate checks) because the fit holds them there, where the data alone "
                   f"would take them past physical: {', '.join(p['on_margin'])}")
    return out


def band_warnings(fit: ConsistentFit, joints: list[str], theta_model: np.ndarray) -> list[str]:
    """What the terminal and the report are told of the mass band (`fit`): the links it held, and those
    whose mass the data demand beyond it, each with its ratio to the model's."""
    lo, hi = MASS_BAND
    ratio = [float(fit.theta[k][0] / theta_model[k][0]) if theta_model[k][0] > 0 else float("nan")
             for k in range(len(joints))]
    out = []
    if fit.held_at_band:
        out.append(f"link masses held at the edge of [{lo:g}, {hi:g}] times the model's, where the data cannot tell "
                   f"them (free of the band, the training residual {fit.free_residual:.4g} against "
                   f"{fit.relative_residual:.4g}): " + ", ".join(f"{joints[k]} (mass x{ratio[k]:.3g})"
                                                                 for k in fit.held_at_band))
    if fit.beyond_band:
        out.append(f"link masses beyond [{lo:g}, {hi:g}] times the model's because the data demand them (held within "
                   f"it, the training residual would be more than {100 * DEMAND:g} % higher): " + ", ".join(
                       f"{joints[k]} (mass x{ratio[k]:.3g})" for k in fit.beyond_band))
    return out
