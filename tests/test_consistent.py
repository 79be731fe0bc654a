"""The physically consistent fit (harness/identify/consistent.py) never fails: where Clarabel fails,
SCS solves the same problem, and where every solver fails the unconstrained fit is moved to the
nearest physical one; `fallback` says which. The data: the UR5 with drives (models/ur5_friction.toml)
at 400 random states, torques from its own parameters plus 1 % noise, so the truth is physical and
known, and the model given to the fit is the truth with every mass and inertia 20 % off."""

from __future__ import annotations

import numpy as np
import pytest

from harness.base import numerics
from harness.base.numerics import column_scale
from harness.engines.pinocchio import build_model
from harness.identify import consistent
from harness.identify.torque_id import regressor, true_parameters
from harness.model.friction import values as friction_values
from harness.model.inertia import from_pseudo_inertia, kind_scale, pseudo_inertia
from harness.model.load import load_spec
from harness.model.states import random_states
from tests.conftest import SCENARIOS

NOISE = 0.01  # of each joint's RMS torque


@pytest.fixture(scope="module")
def problem():
    spec = load_spec(SCENARIOS.parent / "models" / "ur5_friction.toml")
    pm = build_model(spec, np.array([0.0, 0.0, -9.80665]))
    n = len(spec.joints)
    q, qd, qdd = random_states(-np.pi * np.ones(n), np.pi * np.ones(n), 2.0 * np.ones(n), 5.0 * np.ones(n), 400, 3)
    W = regressor(pm, q, qd, qdd, with_friction=True)
    x_true = true_parameters(pm, with_friction=True)
    tau = (W @ x_true).reshape(len(q), n)
    rng = np.random.default_rng(4)
    tau_noisy = tau + NOISE * np.sqrt(np.mean(tau**2, axis=0)) * rng.standard_normal(tau.shape)
    theta_true = x_true[: 10 * n].reshape(n, 10)
    theta_model = theta_true * np.where(np.arange(10) == 0, 1.2, 1.0) * np.where(np.arange(10) >= 4, 1.2, 1.0)
    friction_model = friction_values(spec.frictions)
    scale = np.concatenate([np.concatenate([kind_scale(t) for t in theta_model]),
                            np.maximum(np.abs(friction_model), 1.0).ravel()])
    return W, tau_noisy.reshape(-1), tau.reshape(-1), theta_model, friction_model, scale, n


def _fit(problem, monkeypatch, solvers):
    W, tau, _, theta_model, friction_model, scale, _ = problem
    if solvers is not None:
        monkeypatch.setattr(consistent, "SOLVERS", solvers)
    return consistent.fit(W, tau, theta_model, friction_model, scale)


def _physical(fit, theta_model) -> bool:
    eps = [consistent.MARGIN * np.max(np.linalg.eigvalsh(pseudo_inertia(t))) for t in theta_model]  # each its own
    return (all(np.linalg.eigvalsh(pseudo_inertia(t))[0] >= e * (1 - 1e-6) for t, e in zip(fit.theta, eps, strict=True))
            and np.all(fit.friction[:, :3] >= -1e-9))


def _prediction_error(problem, fit) -> float:
    """RMS |predicted - noise-free torque| over the RMS noise-free torque."""
    W, _, tau_clean, *_ = problem
    x = np.concatenate([fit.theta.ravel(), fit.friction.ravel()])
    return float(np.sqrt(np.mean((W @ x - tau_clean) ** 2) / np.mean(tau_clean**2)))


def _least_squares_error(problem) -> float:
    W, tau, tau_clean, *_ = problem
    x = np.linalg.lstsq(W, tau, rcond=None)[0]
    return float(np.sqrt(np.mean((W @ x - tau_clean) ** 2) / np.mean(tau_clean**2)))


MISSING = ("NOT_A_SOLVER", {})  # cvxpy raises SolverError: not installed


def test_clarabel_solves_it_and_says_so(problem, monkeypatch):
    fit = _fit(problem, monkeypatch, None)
    assert (fit.solver, fit.fallback, fit.status) == ("CLARABEL", 0, "optimal")
    assert _physical(fit, problem[3])
    # the noise is 1 % of the RMS torque per sample; 4000 samples fit 140 parameters: the
    # prediction's error is a fraction of the noise
    # the truth is feasible, so the constrained fit predicts the noise-free torques no worse than
    # least squares (measured 0.180 % against 0.182 %; 5 % allowed for the pull)
    assert _prediction_error(problem, fit) <= 1.05 * _least_squares_error(problem)


@pytest.mark.slow  # a few seconds: a whole pipeline or a subprocess
def test_where_clarabel_fails_scs_solves_the_same_problem(problem, monkeypatch):
    reference = _fit(problem, monkeypatch, None)
    fit = _fit(problem, monkeypatch, (MISSING, consistent.SOLVERS[1]))
    assert (fit.solver, fit.fallback) == ("SCS", 1)
    assert fit.attempts[0].startswith("NOT_A_SOLVER: failed")
    assert _physical(fit, problem[3])
    # the same optimum, to SCS's looser tolerance: the training residuals agree to 1e-3 of themselves
    assert abs(fit.relative_residual - reference.relative_residual) <= 1e-3 * reference.relative_residual


def test_where_every_solver_fails_the_projected_fit_is_physical_and_close(problem, monkeypatch):
    fit = _fit(problem, monkeypatch, (MISSING, MISSING))
    assert (fit.solver, fit.fallback, fit.status) == ("projection", 2, "projected")
    assert len(fit.attempts) == 2 and all("failed" in a for a in fit.attempts)
    assert _physical(fit, problem[3])
    # the truth is physical, so the unconstrained fit is nearly so: projected, it predicts the
    # noise-free torques within half the noise (measured 0.31 %; least squares 0.18 %, noise 1 %)
    assert _prediction_error(problem, fit) < NOISE / 2


@pytest.mark.parametrize(("depth", "physical"), [(0.0, True), (1e-11, True), (1e-7, False), (1e-3, False)])
def test_a_link_on_the_cones_boundary_is_physical_to_the_solvers_accuracy_and_one_past_it_is_not(problem, depth,
                                                                                                 physical):
    """A real link's pseudo-inertia J with its smallest eigenvalue moved to -depth of its largest (the
    eigenvector kept): what an interior-point solver leaves on the boundary (1e-11 of the scale) is
    judged physical; a link past the boundary by 1e-7 of its scale or more is not."""
    theta = problem[3][2]  # the UR5's elbow link
    w, V = np.linalg.eigh(pseudo_inertia(theta))
    w[0] = -depth * w[-1]
    moved = from_pseudo_inertia((V * w) @ V.T)
    verdict = consistent.consistency(moved)
    assert verdict["min_eig_pseudo_inertia"] == pytest.approx(-depth * w[-1], abs=1e-15 * w[-1])
    assert verdict["consistent"] is physical


@pytest.mark.parametrize("rows_at_a_time", [1 << 15, 700, 97])
def test_the_triangle_of_the_regressor_reduced_in_pieces_holds_its_normal_equations(problem, monkeypatch,
                                                                                    rows_at_a_time):
    """The fit's R and b = Q^T tau, reduced a chunk of rows at a time from column blocks never joined
    (harness/base/numerics.py, `triangle` of a SideBySide), keep the normal equations of the column-scaled regressor A:
    R^T R = A^T A and R^T b = A^T tau to 1e-12 of their largest entry (Householder QR is backward stable:
    its R is the exact triangle of A plus a perturbation of a few eps |A|, 2,400 rows here), and the
    residual it reads off is numpy's least squares' to 1e-10, whatever the chunk (one chunk, 700 rows,
    fewer rows than columns plus one: 97)."""
    W, tau, _, theta_model, friction_model, scale, n = problem
    monkeypatch.setattr(numerics, "ROWS_AT_A_TIME", rows_at_a_time)
    blocks = (W[:, : 10 * n], W[:, 10 * n:])
    col = column_scale(W)  # each column's norm, 1 for a dead one
    R, b, rest = numerics.triangle(numerics.SideBySide(blocks), tau, col)
    A = W / col
    np.testing.assert_allclose(R.T @ R, A.T @ A, atol=1e-12 * np.abs(A.T @ A).max())
    np.testing.assert_allclose(R.T @ b, A.T @ tau, atol=1e-12 * np.abs(A.T @ tau).max())
    assert rest == pytest.approx(np.linalg.norm(A @ np.linalg.lstsq(A, tau, rcond=None)[0] - tau), rel=1e-10)
    # the fit from the blocks predicts the torques of the fit from the whole regressor to 1e-6 of their
    # norm (Clarabel's tolerances are 1e-7; along directions the data leave flat, held only by the weak
    # pull towards the model, the parameters move further with any round-off: the rows of tx40_motion's
    # consistent fit merely permuted move them by up to 0.4 %)
    whole = consistent.fit(W, tau, theta_model, friction_model, scale)
    split = consistent.fit(numerics.SideBySide(blocks), tau, theta_model, friction_model, scale)
    def torques(f):
        return W @ np.concatenate([f.theta.ravel(), f.friction.ravel()])
    assert np.linalg.norm(torques(split) - torques(whole)) <= 1e-6 * np.linalg.norm(torques(whole))
    assert split.relative_residual == pytest.approx(whole.relative_residual, rel=1e-6)


def test_a_link_on_the_margin_or_far_from_the_model_is_consistent_and_its_warning_says_so():
    """The TX40's report stood a passing consistency gate beside warnings of links 'on the margin' and
    'far from the model's' with nothing to reconcile them. A link held on the fit's margin (a body pushed
    past physical, `nearest_physical` at the margin) and a link nine times the model's mass are each
    consistent by the gate's own definition (`consistency`); `plausibility` finds the first on the margin
    and the second implausible, and the warning of each says it is physically consistent all the same."""
    from harness.identify import consistent
    from harness.model.inertia import from_pseudo_inertia, nearest_physical, parallel_axis, pseudo_inertia

    m, c = 2.0, np.array([0.1, 0.0, 0.05])
    inertia = np.diag([0.04, 0.05, 0.03]) + parallel_axis(m, c)  # about the origin: a rigid body's
    body = np.array([m, *(m * c), inertia[0, 0], inertia[0, 1], inertia[1, 1], inertia[0, 2], inertia[1, 2],
                     inertia[2, 2]])
    J = pseudo_inertia(body)
    w, V = np.linalg.eigh(J)
    past = from_pseudo_inertia(J - (w[0] + 1e-3) * np.outer(V[:, 0], V[:, 0]))  # the data's: past physical
    margin = consistent.MARGIN * w[-1]
    held, heavy = nearest_physical(past, margin), body * 9.0
    assert not consistent.consistency(past)["consistent"]
    assert consistent.consistency(held)["consistent"] and consistent.consistency(heavy)["consistent"]
    p = consistent.plausibility(np.stack([held, heavy]), np.stack([body, body]), ["j1", "j2"], np.array([margin] * 2))
    assert p["on_margin"] == ["j1"] and p["implausible"] == ["j2"]
    said = consistent.plausibility_warnings(p)
    assert "j2 (mass x9" in said[0] and "physically consistent all the same" in said[0]
    assert said[1].endswith("physically consistent (as the consistency gate checks) because the fit holds them "
                            "there, where the data alone would take them past physical: j1")


def _link(mass: float) -> np.ndarray:
    """One link's ten parameters about its joint: `mass` kg, its centre 0.1 m out, moments 0.01 to 0.025
    kg m^2 per kg about it."""
    from harness.model.inertia import parallel_axis

    c = np.array([0.1, 0.0, 0.0])
    I = mass * np.diag([0.01, 0.02, 0.025]) + parallel_axis(mass, c)
    return np.array([mass, *(mass * c), I[0, 0], I[0, 1], I[1, 1], I[0, 2], I[1, 2], I[2, 2]])


def test_masses_the_data_cannot_tell_stay_within_the_band(problem):
    """The model given with the forearm 20 times the truth's mass and inertia, the truth's noise-free
    torques: the base parameters regroup the masses, so many physical links explain the torques to
    round-off; every identified mass stays within MASS_BAND times the model's, any held at its edge
    said (held_at_band) with the free fit's residual, which is no better beyond round-off."""
    W, _, tau_clean, theta_model, friction_model, scale, _ = problem
    heavy = theta_model.copy()
    heavy[2] = theta_model[2] / 1.2 * 20.0  # theta_model is the truth 20 % off: the truth, times 20
    fit = consistent.fit(W, tau_clean, heavy, friction_model, scale)
    ratio = fit.theta[:, 0] / heavy[:, 0]
    lo, hi = consistent.MASS_BAND
    assert np.all((ratio >= lo * (1 - 1e-9)) & (ratio <= hi * (1 + 1e-9))) and fit.beyond_band == ()
    assert fit.held_at_band and all(min(abs(ratio[k] / lo - 1), abs(ratio[k] / hi - 1)) <= consistent.AT_BAND
                                    for k in fit.held_at_band)
    assert fit.relative_residual < 1e-12 and fit.free_residual < 1e-12


@pytest.mark.parametrize("demand", [consistent.DEMAND, 1.0])
def test_a_mass_the_data_demand_goes_beyond_the_band_and_is_said(demand, monkeypatch):
    """One link whose ten parameters a random regressor (600 rows) sees one by one, the model 20 times the
    truth's mass: the noise-free torques demand 0.05 of the model's mass, the band's fit cannot explain
    them (its residual far more than DEMAND above the free fit's round-off), so the free fit is taken and
    the link named (beyond_band). Were the bar one no fit can pass (DEMAND = 1: data that could not
    tell), the band holds the mass at 0.1 of the model's (held_at_band), its fit far worse than the free one."""
    rng = np.random.default_rng(11)
    W = rng.standard_normal((600, 14))
    truth, model = _link(0.5), _link(10.0)
    friction = np.array([[0.01, 0.1, 0.2, 0.0]])
    tau = W @ np.concatenate([truth, friction.ravel()])
    scale = np.concatenate([kind_scale(model), np.ones(4)])
    monkeypatch.setattr(consistent, "DEMAND", demand)
    fit = consistent.fit(W, tau, model[None], friction, scale)
    ratio = fit.theta[0][0] / model[0]
    if demand < 1.0:
        assert fit.beyond_band == (0,) and fit.held_at_band == () and ratio == pytest.approx(0.05, rel=1e-4)
        assert fit.relative_residual == fit.free_residual < 1e-6
    else:
        assert fit.held_at_band == (0,) and fit.beyond_band == ()
        assert ratio == pytest.approx(consistent.MASS_BAND[0], rel=consistent.AT_BAND)
        assert fit.free_residual < 1e-6 < fit.relative_residual


@pytest.mark.parametrize("asymmetry", [0.3, -0.3])
def test_drive_terms_the_data_push_past_physical_are_held_where_bounded_least_squares_puts_them(asymmetry):
    """One link and its drive seen by a random regressor (600 rows, orthogonal columns, so that the link,
    well inside physical, takes none of the drive's misfit), its armature and Coulomb friction demanded
    negative by the torques and its viscous asymmetry demanded larger than its viscous term (either sign): the fit holds
    armature, viscous and Coulomb non-negative and the asymmetry within +-viscous (each direction's
    coefficient, viscous +- asymmetry, non-negative), where scipy's bounded least squares on those
    directions' coefficients (an independent solver of the same bounds) puts them, to 1e-6 of the largest
    drive term: the solver stops within 1e-7 of the optimum, and the pull towards the model (PULL of the
    least-squares residual) moves a term by about 1e-9 here."""
    from scipy.optimize import lsq_linear

    rng = np.random.default_rng(5)
    W = np.sqrt(600) * np.linalg.qr(rng.standard_normal((600, 15)))[0]  # the link's ten, the drive's four, asymmetry
    drive = np.array([-0.05, 0.1, -0.2, 0.4, asymmetry])  # armature < 0, Coulomb < 0, |viscous asymmetry| > viscous
    tau = W @ np.concatenate([_link(1.0), drive]) + 0.01 * rng.standard_normal(600)
    fit = consistent.fit(W, tau, _link(1.0)[None], np.zeros((1, 4)), np.ones(15), ((0, "viscous_asymmetry"),),
                         np.zeros(1))
    T = np.eye(15)  # the reference's unknowns y: x = T y, y's viscous and asymmetry each direction's coefficient
    T[11, [11, 14]], T[14, [11, 14]] = (0.5, 0.5), (0.5, -0.5)
    lower = np.full(15, -np.inf)
    lower[[10, 11, 12, 14]] = 0.0
    reference = (T @ lsq_linear(W @ T, tau, bounds=(lower, np.inf)).x)[10:]
    got = np.concatenate([fit.friction[0], fit.extra])
    assert got[:3].min() >= -1e-9 and abs(got[4]) <= got[1] * (1 + 1e-7)
    assert max(abs(reference[0]), abs(reference[2])) < 1e-9 and abs(reference[4]) == pytest.approx(reference[1])  # held
    assert np.abs(got - reference).max() <= 1e-6 * np.abs(reference).max()


def test_a_small_link_beside_a_large_one_is_held_to_a_margin_of_its_own_size(monkeypatch):
    """A 20 kg link and a 10 g one (second moments of 1e-6 kg m^2 about its centre: its pseudo-inertia's
    smallest eigenvalue under 1e-6 of the large link's largest, above 1e-6 of its own), each seen by a random
    regressor, noise-free torques, the model the truth: the truth is inside the fit's set, which finds it
    (6.5e-14 of the torques measured, 1e-9 allowed). One margin for both, of the large link's size, leaves the small
    link's truth outside, and the fit misses the torques by more than 1e-6 (3.4e-6 measured)."""
    from harness.model.inertia import parallel_axis

    m, c = 0.01, np.array([0.01, 0.0, 0.0])
    second = np.diag([2e-6, 1e-6, 1.5e-6])  # integral of x x^T dm about the centre of mass
    I = np.trace(second) * np.eye(3) - second + parallel_axis(m, c)
    small = np.array([m, *(m * c), I[0, 0], I[0, 1], I[1, 1], I[0, 2], I[1, 2], I[2, 2]])
    large = _link(20.0)
    own, largest = (np.max(np.linalg.eigvalsh(pseudo_inertia(t))) for t in (small, large))
    assert consistent.MARGIN * own < np.linalg.eigvalsh(pseudo_inertia(small))[0] < consistent.MARGIN * largest
    theta = np.stack([large, small])
    friction = np.array([[0.01, 0.1, 0.2, 0.0], [0.001, 0.01, 0.02, 0.0]])
    W = np.random.default_rng(12).standard_normal((600, 28))
    tau = W @ np.concatenate([theta.ravel(), friction.ravel()])
    scale = np.concatenate([kind_scale(large), kind_scale(small), np.ones(8)])
    fit = consistent.fit(W, tau, theta, friction, scale)
    assert fit.relative_residual < 1e-9 and np.allclose(fit.margin, consistent.MARGIN * np.array([largest, own]))
    monkeypatch.setattr(consistent, "margins", lambda t: np.full(len(t), consistent.MARGIN * largest))
    assert consistent.fit(W, tau, theta, friction, scale).relative_residual > 1e-6
