"""Identification of a floating-base robot from the world's wrench on its base and, where asked, its
joint torques.

With the base free the inverse dynamics is linear in the inertial parameters of every body, the base's
own included (harness/model/floating.py, the harness's convention):

    [w_W; tau] = Y(base, q, q', q'') theta,    w_W = [F_W, M_W] the world's wrench on the base

theta the ten parameters of the base's body, then of each joint's body (Pinocchio's
computeJointTorqueRegressor on the free-flyer model: m, m c and the inertia about the joint frame's
origin, in that frame), Y's six base rows turned from Pinocchio's base axes to the world's. The base
rows carry no actuator and no joint friction: what the world exerts on the base (a legged robot's
contact wrenches, summed; the moving bench's applied wrench) identifies every body's parameters that
move the base, without a joint torque sensor (`rows = "base"`); with the joint torques too (`"all"`),
what only the joints see as well, and the joints' friction and rotor inertia, which only their own rows
carry. The base parameters are found as for a fixed base
(harness/identify/torque_id.py, base_parameters: QR with column pivoting of the regressor at random
states, here with the base's pose uniform on SO(3)); a floating base has more of them than the same
robot bolted down (the base's own parameters, and those the base's motion excites), counted side by side
(`fixed_base_parameters`). The rows are of kinds whose noise no one scale serves (a force, a moment, a
motor's torque): the fits may weight each by the inverse of its residual variance (`row_weights`).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from harness.engines.pinocchio import PinocchioModel, states
from harness.identify.estimators import row_variance
from harness.identify.torque_id import (
    STRUCTURAL_STATES,
    BaseParameters,
    base_parameters,
    fit_base,
    known_zero,
    with_structure,
)
from harness.model import drives, friction
from harness.model.floating import BaseMotion, random_base_motion
from harness.model.inertia import PARAMETER_NAMES
from harness.model.spec import RobotSpec
from harness.model.states import position_bounds, random_states

ROWS = ("base", "all")  # which rows a fit reads: the base's six alone, or the joints' torques too
BASE_ROWS = ("base.Fx", "base.Fy", "base.Fz", "base.Mx", "base.My", "base.Mz")


def _free_flyer(pm: PinocchioModel) -> None:
    if pm.model.joints[1].shortname() != "JointModelFreeFlyer":
        raise ValueError("a floating-base regressor needs the model built with its floating base "
                         "(harness/engines/pinocchio.py, build_model(..., floating=True))")


def regressor(pm: PinocchioModel, base: BaseMotion, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray,
              with_friction: bool = False) -> np.ndarray:
    """(N, 6 + n, 10 (njoints - 1) [+ 4 n]): Y at each state, rows [F_W, M_W] then the joints in the spec's
    order, columns ten per Pinocchio joint (the free-flyer's body, the base, first; `parameter_names`);
    with friction, then each joint's drive columns [armature, viscous, coulomb, offset] at its rates
    (harness/model/drives.py, as a fixed base's: harness/identify/torque_id.py), on its own row alone:
    a drive's friction and rotor inertia act between its joint's bodies, never on the base rows."""
    _free_flyer(pm)
    model, data = pm.model, pm.model.createData()
    qq, vv, aa, v_index = states(pm, q, qd, qdd, base)
    rows = np.r_[0:6, v_index]
    Y = np.stack([pin.computeJointTorqueRegressor(model, data, qq[k], vv[k], aa[k])[rows] for k in range(len(q))])
    R = base.R_WB  # Pinocchio's base rows [F_B, M_B]: to world axes
    Y[:, 0:3], Y[:, 3:6] = R @ Y[:, 0:3], R @ Y[:, 3:6]
    if not with_friction:
        return Y
    n = len(pm.joint_ids)
    D = np.zeros((len(q), 6 + n, 4 * n))
    shapes = drives.columns(pm.frictions, pm.transmission, qd, qdd)  # (N, drives, 4)
    for j, k, factor in drives.reach(pm.transmission, n):
        D[:, 6 + j, 4 * k: 4 * k + 4] = factor * shapes[:, k]
    return np.concatenate([Y, D], axis=2)


def parameter_names(spec: RobotSpec, pm: PinocchioModel, with_friction: bool = False) -> list[str]:
    """Ten names per column block of `regressor`: the base's body, then each Pinocchio joint's body (by
    the spec body it carries); with friction, each joint's drive terms."""
    body = {pid: spec.joints[k].child for k, pid in enumerate(pm.joint_ids)}
    owners = [spec.floating.body.name] + [body[j] for j in range(2, pm.model.njoints)]
    names = [f"{b}.{p}" for b in owners for p in PARAMETER_NAMES]
    return names + ([f"{j}.{k}" for j in spec.joint_names for k in friction.IDENTIFIED_KEYS] if with_friction else [])


def true_parameters(pm: PinocchioModel, with_friction: bool = False) -> np.ndarray:
    inertial = np.concatenate([pm.model.inertias[j].toDynamicParameters() for j in range(1, pm.model.njoints)])
    return np.concatenate([inertial, friction.values(pm.frictions).ravel()]) if with_friction else inertial


def read_rows(rows, n: int) -> np.ndarray:
    """The indices of the rows (of 6 + n) a fit reads: `rows` one of ROWS (the base's six, or every row), or
    the indices themselves (the base's and the joints' whose torque a log measures)."""
    if isinstance(rows, str):
        if rows not in ROWS:
            raise ValueError(f"rows {rows!r}: one of {', '.join(ROWS)}")
        return np.arange(6 if rows == "base" else 6 + n)
    return np.asarray(rows, dtype=int)


def selected(Y: np.ndarray, rows) -> np.ndarray:
    """(N k, p) the rows a fit reads (`read_rows`), sample by sample."""
    return Y[:, read_rows(rows, Y.shape[1] - 6)].reshape(-1, Y.shape[-1])


def structural_base(pm: PinocchioModel, limits: dict | None, rows, seed: int = 0,
                    with_friction: bool = False) -> BaseParameters:
    """The base parameters of the floating robot's structure (`rows` of its regressor, at STRUCTURAL_STATES
    random states: the base uniform on SO(3), its twist and acceleration within +-1 and +-5; the joints
    within their limits, q' and q'' standard-normal-sized within +-1)."""
    names = [pm.model.names[j] for j in pm.joint_ids]
    revolute = [pm.model.joints[j].shortname().startswith("JointModelR") for j in pm.joint_ids]
    lo, hi = position_bounds(names, revolute, limits)
    ones = np.ones(len(names))
    q, qd, qdd = random_states(lo, hi, ones, ones, STRUCTURAL_STATES, seed)
    Y = regressor(pm, random_base_motion(STRUCTURAL_STATES, seed), q, qd, qdd, with_friction)
    known_zero(pm.model, range(1, pm.model.njoints), Y)  # the base's body, then each joint's (`regressor`)
    return base_parameters(selected(Y, rows), with_friction)


def measured(base_wrench_W: np.ndarray, tau: np.ndarray, rows) -> np.ndarray:
    """(N, k): what a fit of `rows` (`read_rows`) reads, of the world's wrench on the base (N, 6) and the joints'
    rows (N, n)."""
    return np.concatenate([base_wrench_W, tau], axis=1)[:, read_rows(rows, tau.shape[1])]


def base_columns(pm: PinocchioModel, structure: BaseParameters, rows, Y: np.ndarray) -> np.ndarray:
    """(N k, r): the rows a fit reads (`selected`) of the base parameters `structure`, from the states' `regressor`
    with the drives' columns."""
    return selected(Y if structure.with_friction else Y[..., :rigid_columns(pm)], rows)[:, structure.independent]


WEIGHT_ITERATIONS = 10  # the weights' passes at most (measured: 3 to 5 settle within WEIGHT_SETTLED)
WEIGHT_SETTLED = 1e-3  # relative change of every row's residual variance between passes that ends them


def row_weights(pm: PinocchioModel, structure: BaseParameters, rows, training: tuple,
                Y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(k,) each read row's weight in a weighted fit, the inverse of its residual variance (harness/identify/
    estimators.py, row_variance: Gautier and Poignet's per-joint weighting), the largest 1; and (k,) that
    residual's standard deviation, the row's noise as the data show it. A floating base's rows are of three
    kinds that no one scale serves: the contacts' force on the base (N), their moment about its origin (N m,
    each foot's force noise at the foot's lever) and the motors' torques (N m, their own sensors'). The
    ordinary least squares' residual carries the noisiest rows' noise into the others' (its fit follows the
    forces' noise, which the moments' rows then miss): the variances are found again after the fit they
    weight, until they settle (iterated feasible generalised least squares)."""
    return _settled_weights(base_columns(pm, structure, rows, Y), training[4])


def _settled_weights(W1: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """`row_weights` of the regressor W1 (N k, p) and the rows y (N, k)."""
    tau, k = y.reshape(-1), y.shape[1]
    var = row_variance(W1, tau, k)
    for _ in range(WEIGHT_ITERATIONS):
        again = row_variance(W1, tau, k, var.min() / var)
        settled = np.all(np.abs(again - var) <= WEIGHT_SETTLED * var)
        var = again
        if settled:
            break
    return var.min() / var, np.sqrt(var)


def torque_factors(pm: PinocchioModel, structure: BaseParameters, rows, training: tuple, Y: np.ndarray,
                   motor: np.ndarray, weighted: bool = True):
    """Each read joint's torque factor c_j, the torque its motor gives over the torque its currents give with
    the declared constant, identified with the base parameters beta from every read row (`rows`: the base's six
    and the joints'): joint j's rows Y_j beta - c_j tau_j = (J^T F)_j, the base's Y_base beta = w. The contacts'
    wrench, read in newtons by no motor constant, fixes the scale that a log of currents alone leaves free (an
    arm needs a known payload for it: harness/identify/scale.py). `training` = (base, q, q', q'', y), y (N, 6 + m)
    the read rows as measured (each joint's its motor's torque at the declared constant plus the contacts' J^T F);
    `motor` (N, m) the motors' part; `Y` the states' `regressor` with the drives' columns. Weighted by each row's
    residual variance as the fits are (`row_weights`, on this problem), or alike. The Estimate of (beta, c) and
    m, the number of factors at its end."""
    y = training[4]
    N, k = y.shape
    m = motor.shape[1]
    if k != 6 + m:
        raise ValueError(f"the constants are read from the base's rows and every measured joint's: {k} rows, "
                         f"{m} joints")
    C = np.zeros((N, k, m))
    C[:, 6 + np.arange(m), np.arange(m)] = -motor
    W = np.concatenate([base_columns(pm, structure, rows, Y), C.reshape(N * k, m)], axis=1)
    rhs = y.copy()
    rhs[:, 6:] -= motor  # the joints' rows less their motors' part: the contacts' J^T F
    weights = _settled_weights(W, rhs)[0] if weighted else None
    beta_model = np.concatenate([structure.of(true_parameters(pm, structure.with_friction)), np.ones(m)])
    return fit_base(*_weighted(W, rhs, weights), beta_model)


def _weighted(W: np.ndarray, y: np.ndarray, weights: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """W (N k, p) and y (N, k) with each sample's row i multiplied by sqrt(weights[i]) (None: as they are)."""
    if weights is None:
        return W, y
    root = np.sqrt(weights)
    return W * np.tile(root, len(y))[:, None], y * root


def identify(pm: PinocchioModel, structure: BaseParameters, rows, training: tuple, validation: tuple | None,
             Y: np.ndarray | None = None, weights: np.ndarray | None = None):
    """Least squares of the base parameters `structure` from `training` = (base, q, q', q'', y), y (N, k)
    the measured rows (`measured`), judged on `validation` (the same, another motion): the fit
    (harness/identify/lstsq.py Estimate, with the structure's weak parameters) and the validation's
    predicted less measured rows (N_v, k), None without one. `Y`: the training states' `regressor` with
    friction, where the caller has it. `weights` (k,): each read row's (`row_weights`), a weighted least
    squares (its intervals the weighted problem's); None, the ordinary one."""
    base, q, qd, qdd, y = training
    friction_too = structure.with_friction
    Y = regressor(pm, base, q, qd, qdd, True) if Y is None else Y
    W1 = base_columns(pm, structure, rows, Y)
    beta_model = structure.of(true_parameters(pm, friction_too))
    fit = with_structure(fit_base(*_weighted(W1, y, weights), beta_model), structure)
    if validation is None:
        return fit, beta_model, None
    base_v, q_v, qd_v, qdd_v, y_v = validation
    pred = selected(regressor(pm, base_v, q_v, qd_v, qdd_v, friction_too), rows)[:, structure.independent] @ fit.beta
    return fit, beta_model, pred.reshape(y_v.shape) - y_v


def link_blocks(pm: PinocchioModel) -> list[int]:
    """The consistent fit's links, each as its block of `regressor`'s columns: the base's body, then each spec
    joint's body in the spec's order."""
    return [0] + [pid - 1 for pid in pm.joint_ids]


def link_parameters(pm: PinocchioModel) -> np.ndarray:
    """(1 + n, 10) the model's parameters of the consistent fit's links (`link_blocks`)."""
    return np.stack([pm.model.inertias[b + 1].toDynamicParameters() for b in link_blocks(pm)])


def rigid_columns(pm: PinocchioModel) -> int:
    """How many of `regressor`'s columns are the bodies' (ten per Pinocchio joint's body), before the drives'."""
    return 10 * (pm.model.njoints - 1)


def consistent(pm: PinocchioModel, spec: RobotSpec, rows, training: tuple, with_friction: bool,
               Y: np.ndarray | None = None, weights: np.ndarray | None = None):
    """The physically consistent fit of the floating robot (harness/identify/consistent.py: every body's
    pseudo-inertia positive definite, the base's included; the drives' rotor inertia, viscous and Coulomb
    friction non-negative; what the data cannot see pulled to the model's values) on the same rows as the
    least squares: (the fit, its links' order). Its links are the base's body, then each joint's body in
    the spec's order; its drives a placeholder for the base (no columns: it stays at zero) and the joints'
    (their columns where `with_friction`, else at the model's values). `Y`: the training states' `regressor`
    with friction, where the caller has it; `weights` (k,), each read row's, as the least squares' (`identify`)."""
    from harness.identify import consistent as sdp
    from harness.model.inertia import model_kind_scales

    base, q, qd, qdd, y = training
    n, J = len(spec.joints), pm.model.njoints - 1
    Y = regressor(pm, base, q, qd, qdd, with_friction=True) if Y is None else Y
    inertial = np.concatenate([Y[:, :, 10 * b: 10 * b + 10] for b in link_blocks(pm)], axis=2)
    drive = Y[:, :, 10 * J:] if with_friction else np.zeros((len(q), 6 + n, 4 * n))
    W = selected(np.concatenate([inertial, np.zeros((len(q), 6 + n, 4)), drive], axis=2), rows)
    theta_model = link_parameters(pm)
    friction_model = np.vstack([np.zeros(4), friction.values(spec.frictions)])
    # the pull's magnitudes: the inertial parameters' kinds in the model; a drive term's own value in the
    # model, at least 1e-3 of the largest (or of 1 where the model declares none: the terms then stay at zero)
    scale = np.concatenate([model_kind_scales(theta_model).ravel(),
                            np.maximum(np.abs(friction_model), 1e-3 * np.abs(friction_model).max(initial=1.0)).ravel()])
    W, y = _weighted(W, y, weights)
    fit = sdp.fit(W, y.reshape(-1), theta_model, friction_model, scale)
    return fit, [spec.floating.body.name, *(j.child for j in spec.joints)]


def consistent_rows(pm: PinocchioModel, fit, rows, data: tuple, with_friction: bool) -> np.ndarray:
    """(N, k): the rows (`rows`) the consistent fit predicts at the states of `data` (base, q, q', q'', ...)."""
    base, q, qd, qdd = data[:4]
    J = pm.model.njoints - 1
    Y = regressor(pm, base, q, qd, qdd, with_friction=True)
    theta = np.zeros(10 * J)
    for k, b in enumerate(link_blocks(pm)):
        theta[10 * b: 10 * b + 10] = fit.theta[k]
    x = np.concatenate([theta, fit.friction[1:].ravel() if with_friction else friction.values(pm.frictions).ravel()])
    out = Y @ x
    return out[:, read_rows(rows, out.shape[1] - 6)]
