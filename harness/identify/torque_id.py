"""Identification from joint torques alone, the standard method of the literature.

tau = W(q, q', q'') theta, with theta the 10 inertial parameters of every joint's body (Pinocchio's
computeJointTorqueRegressor: m, m c, and the inertia tensor about the joint frame origin, in
the joint frame: xx, xy, yy, xz, yz, zz). Not every parameter shows in the torques: QR with column
pivoting of the stacked, column-scaled regressor, W P = Q R, finds its rank r (|R_ii| >= RANK_TOL
|R_00|); the base parameters are beta = theta_1 + R11^-1 R12 theta_2 (theta_1 the r independent
columns' parameters, theta_2 the rest), and tau = W_1 beta. Least squares gives beta from the
recorded torques; the identified model then predicts the torques of a validation trajectory the
identification never saw.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from harness.base.numerics import (
    SideBySide,
    condition,
    live_columns,
    parameter_scale,
)
from harness.engines.pinocchio import PinocchioModel
from harness.identify.estimators import ols_of, reduced
from harness.identify.lstsq import Estimate, sensitivity, weakly_identifiable
from harness.model import drives, friction
from harness.model.drives import Transmission
from harness.model.inertia import PARAMETER_NAMES
from harness.model.regressor import joint_torque_regressor
from harness.model.regressor import supports as batched_supports
from harness.model.states import position_bounds

RANK_TOL = 1e-8  # |R_ii| / |R_00| below this: the column depends on the others (exact data: 1e-14)
# A column that is not live (harness/base/numerics.py, live_columns) is round-off: the parameter has no
# effect on any torque (e.g. a body's mass moment along its own joint axis); such columns sit at 1e-16,
# every other column at 1e-3 or more. Scaling them to unit norm would make them look independent.
DRIVE_TERMS = len(friction.IDENTIFIED_KEYS)  # a joint's drive columns, after every link's ten


def drive_columns(n: int, j: int) -> slice:
    """The columns of joint j's drive terms (friction.IDENTIFIED_KEYS, in that order) in a regressor
    with friction of n joints: after the 10 n of the links, DRIVE_TERMS per joint."""
    return slice(10 * n + DRIVE_TERMS * j, 10 * n + DRIVE_TERMS * (j + 1))


def drive_column(n: int, j: int, key: str) -> int:
    """The column of joint j's drive term `key` (friction.IDENTIFIED_KEYS)."""
    return drive_columns(n, j).start + friction.IDENTIFIED_KEYS.index(key)


def regressor(pm: PinocchioModel, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray,
              with_friction: bool = False) -> np.ndarray:
    """(N * n, 10 n [+ 4 n]): the joint torque regressor of every sample, rows sample by sample in
    the spec's joint order, columns joint by joint (the body each joint carries); with friction,
    then per joint the columns of [armature, viscous, coulomb, offset] (harness/model/friction.py)."""
    n, N = len(pm.joint_ids), len(q)
    out = np.empty((N, n, 14 * n if with_friction else 10 * n))
    for a in range(0, N, SAMPLES_AT_A_TIME):  # joint by joint, then transposed: a chunk at a time, not a copy
        out[a: a + SAMPLES_AT_A_TIME] = regressor_by_joint(pm, *(x[a: a + SAMPLES_AT_A_TIME] for x in (q, qd, qdd)),
                                                           with_friction).transpose(2, 0, 1)
    return out.reshape(N * n, -1)


SAMPLES_AT_A_TIME = 8192  # samples of the regressor made at a time (`regressor`)


def put_coulomb(W3: np.ndarray, S: np.ndarray, transmission: Transmission | None) -> None:
    """Each drive's Coulomb column of the regressor's rows W3 (N, n, 14 n) set to S (N, m), in place:
    on every joint j drive k reaches, times N[k, j] (harness/model/drives.py, `reach`)."""
    n = W3.shape[1]
    for j, k, factor in drives.reach(transmission, S.shape[1]):
        W3[:, j, drive_column(n, k, "coulomb")] = factor * S[:, k]


def chain_regressor(pm: PinocchioModel, chain, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray,
                    with_friction: bool = False, closed: bool = False, coulomb: np.ndarray | None = None) -> np.ndarray:
    """(N * n_a, p): a closed chain's actuated-torque regressor G^T Y (harness/model/closure.py): the
    tree's regressor (`regressor`, every joint's row) projected onto the actuated joints, rows sample
    by sample in the chain's actuated order. Exact where the tree's torques are Y theta: tau_a = G^T Y
    theta. `closed`: q closes every loop (G's null-space check is then made). `coulomb` (N, n): every
    joint's Coulomb column where it is not the law's at q' (a filtered log's: harness/identify/filtered.py)."""
    from harness.model.closure import projection

    N, n = len(q), len(pm.joint_ids)
    W = regressor(pm, q, qd, qdd, with_friction).reshape(N, n, -1)
    if coulomb is not None:
        put_coulomb(W, coulomb, None)
    G = projection(chain, q, closed=closed)
    return np.einsum("nja,njp->nap", G, W).reshape(N * len(chain.actuated), -1)


def regressor_by_joint(pm: PinocchioModel, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray,
                       with_friction: bool = False, out: np.ndarray | None = None) -> np.ndarray:
    """The same regressor as (n, p, N): out[i, :, k] is joint i's row at sample k, so each joint's
    rows are one contiguous (p, N) block (what a fold into normal equations reads). Batched
    (harness/model/regressor.py) where the model's joints allow, else Pinocchio's call sample by sample.
    `out`: a zeroed (n, p, N) array, reused from one call to the next (the entries written are the
    same every call, the others stay zero)."""
    model = pm.model
    n = len(pm.joint_ids)
    N = len(q)
    p = 14 * n if with_friction else 10 * n
    if out is None:
        out = np.zeros((n, p, N))
    cols = np.concatenate([np.arange(10 * (j - 1), 10 * j) for j in pm.joint_ids])
    # the model is the spec's joints, one coordinate each, in its order: no rows or columns to pick
    in_order = (model.nq == model.nv and np.array_equal(pm.q_index, np.arange(model.nv))
                and np.array_equal(cols, np.arange(10 * model.njoints - 10)))
    if in_order:
        qq, vv, aa = q, qd, qdd
    else:
        qq, vv, aa = (np.zeros((N, model.nq)) for _ in range(3))
        qq[:, pm.q_index], vv[:, pm.q_index], aa[:, pm.q_index] = q, qd, qdd
    if model.nq == model.nv and batched_supports(model):
        if in_order:  # written in place
            joint_torque_regressor(model, qq, vv, aa, out=out[:, : 10 * n])
        else:
            out[:, : 10 * n] = joint_torque_regressor(model, qq, vv, aa)[np.ix_(pm.q_index, cols)]
    else:
        data = model.createData()
        for k in range(N):
            out[:, : 10 * n, k] = pin.computeJointTorqueRegressor(model, data, qq[k], vv[k], aa[k])[
                np.ix_(pm.q_index, cols)]
    if with_friction:  # drive k's four columns, at its rates, on joint j's rows times N[k, j] (drives.reach)
        shapes = drives.columns(pm.frictions, pm.transmission, qd, qdd)  # (N, drives, 4)
        for j, k, factor in drives.reach(pm.transmission, n):
            out[j, drive_columns(n, k)] = factor * shapes[:, k].T
    return out


def true_parameters(pm: PinocchioModel, with_friction: bool = False) -> np.ndarray:
    inertial = np.concatenate([pm.model.inertias[j].toDynamicParameters() for j in pm.joint_ids])
    return np.concatenate([inertial, friction.values(pm.frictions).ravel()]) if with_friction else inertial


def parameter_names(joints: list[str], with_friction: bool = False, drives: list[str] | None = None) -> list[str]:
    """Each link's ten parameters by its joint, then with friction each drive's four ([armature,
    viscous, coulomb, offset]) by the joint or, with a transmission, the motor (`drives`) it belongs to."""
    names = [f"{j}.{p}" for j in joints for p in PARAMETER_NAMES]
    owners = joints if drives is None else drives
    return names + ([f"{d}.{k}" for d in owners for k in friction.IDENTIFIED_KEYS] if with_friction else [])


@dataclass(frozen=True, eq=False)
class BaseParameters:
    independent: np.ndarray  # (r,) column indices of theta_1
    dependent: np.ndarray  # (p - r,) column indices of theta_2
    combination: np.ndarray  # (r, p - r): beta = theta_1 + combination theta_2
    with_friction: bool = False  # theta holds each joint's [armature, viscous, coulomb, offset] too
    weak: np.ndarray | None = None  # (r,) bool: exists only through a feature of the robot far below its size

    def of(self, theta: np.ndarray) -> np.ndarray:
        return theta[self.independent] + self.combination @ theta[self.dependent]

    def link_part(self, theta: np.ndarray, links: int) -> tuple[np.ndarray, np.ndarray]:
        """Which base parameters hold a link's inertial parameter (the first `links` = 10 n of theta),
        (r,) bool, and in each of those the drive parameters' share at theta's values, (r,): beta_k less
        it is base parameter k's part in the rigid-body torque. Where a rotor inertia is regrouped with a
        link's inertia (the UR5's shoulder lift: I_a + I_yy + ...; a vertical first joint: its I_a in a
        link's mass term) the torques cannot tell the two apart, and the drive's share is theta's."""
        dep_link = self.dependent < links
        held = np.abs(self.combination) > COEFFICIENT_FLOOR
        link = (self.independent < links) | np.any(held & dep_link, axis=1)
        share = (np.where(self.independent >= links, theta[self.independent], 0.0)
                 + self.combination[:, ~dep_link] @ theta[self.dependent[~dep_link]])
        return link, np.where(link, share, 0.0)


def links_weights(beta: np.ndarray, link_part: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """(r,): the weights of the base parameters' columns in the links' part of a fit's torque (beta (r,)
    their values, link_part from BaseParameters.link_part: which of them hold a link's inertia, and the
    drive's share in each, taken out)."""
    link, share = link_part
    return np.where(link, beta - share, 0.0)


def base_parameters(W: np.ndarray, with_friction: bool = False) -> BaseParameters:
    from scipy.linalg import qr, solve_triangular  # pivoted QR: numpy has none; imported where needed

    norms = np.linalg.norm(W, axis=0)
    live = np.flatnonzero(live_columns(norms))
    dead = np.flatnonzero(~live_columns(norms))
    scale = norms[live]
    _, R, P = qr(W[:, live] / scale, mode="economic", pivoting=True)
    d = np.abs(np.diag(R))
    r = int(np.sum(d >= RANK_TOL * d[0]))
    comb = solve_triangular(R[:r, :r], R[:r, r:])  # in scaled columns
    # unscale: W_s = W / s, so theta_s = s theta and beta_s = theta_1 s_1 + comb (theta_2 s_2)
    comb = comb * scale[P[r:]][None, :] / scale[P[:r]][:, None]
    # parameters whose column is zero enter no base parameter
    comb = np.concatenate([comb, np.zeros((r, len(dead)))], axis=1)
    independent = live[P[:r]]
    return BaseParameters(independent, np.concatenate([live[P[r:]], dead]), comb, with_friction,
                          structurally_weak(W, independent, norms, with_friction))


WEAK_STRUCTURE = 1e-4  # a base parameter's column, or its part apart from the others, below this of its kind's


def structurally_weak(W: np.ndarray, independent: np.ndarray, norms: np.ndarray, with_friction: bool) -> np.ndarray:
    """(r,) bool: the base parameters that exist only through a feature of the robot far smaller than
    the robot (an axis tilted by a rounded angle): identifiable in exact arithmetic, but carried by a
    column that is WEAK_STRUCTURE or less of what parameters of its kind have (its column against the
    median column of the same kind: mass, first moment, inertia, or one drive term), or by the
    difference between columns (a right singular vector with sigma / sigma_max below WEAK_STRUCTURE
    of the column-scaled base regressor, weight above 0.1). The directions are the model's
    structure, not the base's: whichever column stands for such a direction is tiny, or nearly
    collinear with the others. How many base parameters carry them is the base's, and round-off
    can decide the pivoting's choice: one direction can then be shared by two base parameters
    (so100: two weak on an AMD EPYC, three on an Intel Xeon, for the tilt's two directions).
    so100's pan axis, 3e-6 rad off the vertical: its columns at 4e-6 of their kind's; every other
    column of so100, the Panda, the UR5, the KR500 and the planar arm at 6e-4 or more, and their
    scaled singular values at 0.1 or more of the largest."""
    n10 = W.shape[1] // 14 * 10 if with_friction else W.shape[1]  # columns of the links; the drives after them
    c = np.arange(W.shape[1])
    kind = np.where(c < n10, np.array([0, 1, 1, 1, 2, 2, 2, 2, 2, 2])[c % 10], 3 + (c - n10) % 4)
    live = live_columns(norms)
    median = {k: float(np.median(norms[live & (kind == k)])) for k in np.unique(kind[live])}
    small = np.array([norms[j] < WEAK_STRUCTURE * median[kind[j]] for j in independent], bool)
    _, S, Vt = np.linalg.svd(W[:, independent] / norms[independent], full_matrices=False)
    near = S < WEAK_STRUCTURE * S[0]
    collinear = np.any(np.abs(Vt[near]) > 0.1, axis=0) if near.any() else np.zeros(len(independent), bool)
    return small | collinear


STRUCTURAL_STATES = 200  # random states for the structural base: 2 x 10 n rows and more for n <= 9 joints


def gravity_rows(pm: PinocchioModel, q: np.ndarray, joints: tuple[int, ...]) -> np.ndarray:
    """(N, len(joints), 10 n): the rows of `joints` of the gravity regressor Y(q, 0, 0), whose product with
    the links' parameters is their gravity torque."""
    rest = np.zeros_like(q)
    return regressor(pm, q, rest, rest).reshape(*q.shape, -1)[:, list(joints)]


def without_gravity(pm: PinocchioModel, q: np.ndarray, W: np.ndarray, joints: tuple[int, ...]) -> np.ndarray:
    """The regressor's rows W (N n, c) with the links' columns of the rows of `joints` (counterbalanced:
    a spring or counterweight holds their weight) less the gravity regressor's (`gravity_rows`); in place."""
    if joints:
        N, n = q.shape
        W.reshape(N, n, -1)[:, list(joints), : 10 * n] -= gravity_rows(pm, q, joints)
    return W


def selected_rows(W: np.ndarray, per_sample: int, joints: tuple[int, ...]) -> np.ndarray:
    """Rows (N per_sample, c), sample by sample, of each sample's `joints` alone: (N len(joints), c)."""
    N, c = len(W) // per_sample, W.shape[1]  # c may be 0 (no family's columns): no -1 in the shapes
    return W.reshape(N, per_sample, c)[:, list(joints)].reshape(N * len(joints), c)


def structural_base(pm: PinocchioModel, limits: dict | None = None, seed: int = 0,
                    with_friction: bool = False, chain=None, channels: tuple[int, ...] | None = None,
                    weightless: tuple[int, ...] = (), known_zeros: bool = True) -> BaseParameters:
    """The base parameters of the model's structure, chosen once: QR with column pivoting of the
    noise-free regressor at STRUCTURAL_STATES random states (q uniform within the joint limits, or
    +-pi, +-1 m; q', q'' standard normal), not of a measured trajectory, whose noise or poor
    excitation would change which combinations are chosen. For the same model and seed it is the
    same every time it is asked for. Of a closed chain (`chain`, harness/model/closure.py): its
    actuated-torque regressor G^T Y at random consistent states (the actuated joints' q uniform within
    their limits, q'_a and q''_a within +-1, the passive joints' from the loops). `channels`: the joints
    whose rows a log holds (an open tree's measured joints, a closed chain's measured actuated joints:
    harness/stages/log_model.py): the base of their rows alone, every joint's motion in them;
    `weightless`: joints whose rows carry no gravity (`without_gravity`); `known_zeros`: a massless body's
    parameters in no base parameter (`known_zero`; without, the base of every body's ten, what a method
    that takes each body's parameters as unknowns is judged on)."""
    if chain is not None:
        from harness.model.closure import random_within_limits

        m = random_within_limits(chain, limits, STRUCTURAL_STATES, seed)
        W = chain_regressor(pm, chain, m.q, m.qd, m.qdd, with_friction, closed=True)
        W = known_zero(pm.model, pm.joint_ids, W) if known_zeros else W
        return base_parameters(W if channels is None else selected_rows(W, len(chain.actuated), channels),
                               with_friction)
    rng = np.random.default_rng(seed)
    n = len(pm.joint_ids)
    lo, hi = position_bounds([pm.model.names[jid] for jid in pm.joint_ids],
                             [pm.model.joints[jid].shortname().startswith("JointModelR") for jid in pm.joint_ids],
                             limits)
    q = rng.uniform(lo, hi, (STRUCTURAL_STATES, n))
    qd, qdd = rng.standard_normal((2, STRUCTURAL_STATES, n))
    W = without_gravity(pm, q, regressor(pm, q, qd, qdd, with_friction), weightless)
    W = known_zero(pm.model, pm.joint_ids, W) if known_zeros else W
    return base_parameters(W if channels is None else selected_rows(W, n, channels), with_friction)


def known_zero(model, joint_ids, W: np.ndarray) -> np.ndarray:
    """W (..., 10 per joint of `joint_ids` [+ drives]) with the ten columns of each massless body zeroed,
    in place (`massless`)."""
    for k in massless(model, joint_ids):
        W[..., 10 * k: 10 * k + 10] = 0.0
    return W


def massless(model, joint_ids) -> list[int]:
    """The places k in `joint_ids` (joint ids of the Pinocchio model `model`, whose ten regressor columns are
    the body each carries) of the joints that carry a massless body (a carriage: between a ball's hinges, a
    universal joint's cross, a rail's): its parameters are known to be zero, and its columns, zeroed, enter
    no base parameter."""
    return [k for k, jid in enumerate(joint_ids) if model.inertias[jid].mass == 0.0]


@dataclass(eq=False)
class TorqueIdentification:
    names: list[str]  # parameter names, joint by joint
    base: BaseParameters
    beta_true: np.ndarray
    beta: np.ndarray
    condition_number: float  # of the column-scaled base regressor
    std: np.ndarray  # (r,) standard deviation of each base parameter (CR3 over the samples; inf: undetermined)
    ci_half_width: np.ndarray  # (r,) half width of its 95 % interval
    sensitivity: np.ndarray  # (r,) kappa relative to the model's own base parameters (harness/identify/lstsq.py)
    weak: np.ndarray  # (r,) bool: weakly identifiable
    validation_error: np.ndarray | None  # (N_val, n) predicted - recorded torques, validation trajectory
    validation_scale: np.ndarray | None = None  # (n,) joint loads L_J of the validation recording
    torque_joints: list[str] | None = None  # the torques' joints where they are not every joint (a closed chain's)
    families: tuple[str, ...] = ()  # the friction families' coefficients after the base parameters ("joint.key")

    def expression(self, k: int) -> str:
        """Column k of the fit: a base parameter as the combination it stands for, or a family's coefficient."""
        r = len(self.base.independent)
        return describe_base(self.names, self.base, k) if k < r else self.families[k - r]


def fit_base(W1: np.ndarray | SideBySide, tau: np.ndarray, beta_model: np.ndarray) -> Estimate:
    """Least squares of the base parameters from torques tau (N, n) and their regressor W1 (N n, r):
    ordinary least squares on the column-scaled regressor with CR3 intervals clustered by sample (a
    sample's joints share noise; harness/identify/estimators.py), the scaled regressor's condition number,
    and each parameter's sensitivity relative to its size in the model or, where the model has it
    zero (a friction the model does not declare), in the estimate."""
    L = tau.reshape(-1)
    red = reduced(W1, L)  # the scaled regressor's triangle and its SVD, made once for all three
    est = ols_of(red, W1, L, tau.shape[1])
    s, sv = red.s, red.sv
    kappa = sensitivity(W1, L, (sv, red.Vt)) / (s * parameter_scale(np.maximum(np.abs(beta_model), np.abs(est.beta))))
    return dataclasses.replace(est, sensitivity=kappa, weak=weakly_identifiable(kappa), condition_number=condition(sv))


def with_structure(fit: Estimate, base: BaseParameters) -> Estimate:
    """The fit with the structurally weak base parameters (`structurally_weak`) also weak: the data's
    verdict (sensitivity) or the robot's, whichever says so. Columns after the base parameters (a
    friction family's) keep the data's verdict."""
    if base.weak is None:
        return fit
    weak = fit.weak.copy()
    weak[: len(base.weak)] |= base.weak
    return dataclasses.replace(fit, weak=weak)


COEFFICIENT_FLOOR = 1e-12  # coefficients of the base combinations below this are QR round-off


def describe_base(names: list[str], base: BaseParameters, k: int) -> str:
    """beta_k as a combination of the physical parameters `names`."""
    terms = [names[base.independent[k]]]
    for c, j in zip(base.combination[k], base.dependent, strict=True):
        if abs(c) > COEFFICIENT_FLOOR:
            terms.append(f"{c:+.6g} {names[j]}")
    return " ".join(terms)
