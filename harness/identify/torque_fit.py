"""The joint-torque identification of a bench scenario (`[torque_identification]`): least squares of the
base parameters (harness/identify/torque_id.py) and, with friction, of each drive's friction family's
coefficients (harness/model/friction.py, FAMILIES) at the model's own velocities, in columns after them
(harness/identify/laws.py, extra_regressor); judged on a validation trajectory the fit never saw."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from harness.engines.pinocchio import PinocchioModel
from harness.identify.laws import Law, extra_regressor, extra_terms
from harness.identify.lstsq import Estimate
from harness.identify.torque_id import (
    BaseParameters,
    TorqueIdentification,
    chain_regressor,
    fit_base,
    links_weights,
    parameter_names,
    regressor,
    structural_base,
    true_parameters,
    with_structure,
)


def identify_from_torques(pm: PinocchioModel, joints: list[str], q, qd, qdd, tau,
                          validation: tuple | None = None, base: BaseParameters | None = None,
                          chain=None) -> TorqueIdentification:
    """Least squares of the base parameters (default: the structural ones of `pm`) from joint torques;
    of a closed chain (`chain`), from its actuated joints' torques tau (N, n_a) through G^T Y. With
    friction, the coefficients of a drive's friction family (harness/model/friction.py, FAMILIES: a
    Stribeck term, asymmetries, a load-dependent Coulomb term, a spring) are identified too, at the
    model's own velocities (v_c, v_s): columns after the base parameters (`TorqueRows`)."""
    base = base or structural_base(pm, chain=chain)
    rows = TorqueRows.of(pm, base, joints, chain)
    theta = true_parameters(pm, base.with_friction)
    # the model's own values: the magnitudes of the parameters
    beta_model = np.concatenate([base.of(theta), rows.values])
    fit = with_structure(rows.fit(q, qd, qdd, tau, beta_model), base)
    err = None
    if validation is not None:
        qv, qdv, qddv, tauv = validation
        err = rows.predict(fit.beta, qv, qdv, qddv).reshape(tauv.shape) - tauv
    names = parameter_names(joints, base.with_friction, rows.owners)
    return TorqueIdentification(names, base, beta_model, fit.beta, fit.condition_number, fit.std, fit.ci_half_width,
                                fit.sensitivity, fit.weak, err, families=rows.names)


FIXED_POINT_TOL = 1e-13  # a load-dependent term's rigid torque: iterated until it moves by less than this of itself
FIXED_POINT_ITERATIONS = 100


@dataclass(frozen=True, eq=False)
class TorqueRows:
    """The regressor of a joint-torque fit: the base parameters' columns (`regressor`, a closed chain's
    `chain_regressor`), then each drive's family terms (laws.extra_terms of the model's own laws,
    laws.extra_regressor: a closed chain's through G^T as the rest). A load-dependent term's column
    |tau_R| s reads the rigid-body torque of the fit itself (the base parameters that hold a link's
    inertia, less the drive's share: BaseParameters.link_part), so that fit is a fixed point: from the fit
    without those terms, iterated until tau_R moves by less than FIXED_POINT_TOL of itself (`fit`)."""

    pm: PinocchioModel
    base: BaseParameters
    chain: object
    laws: tuple  # laws.Law per drive; empty without friction
    terms: tuple[tuple[int, str], ...]  # (drive, EXTRA_KEYS key) of each family column
    owners: list[str]  # each drive's name: its joint's, or a transmission's motor's
    link_part: tuple[np.ndarray, np.ndarray]

    @classmethod
    def of(cls, pm: PinocchioModel, base: BaseParameters, joints: list[str], chain=None) -> TorqueRows:
        laws = tuple(Law.of(f) for f in pm.frictions) if base.with_friction else ()
        owners = list(pm.transmission.motors) if pm.transmission is not None else list(joints)
        theta = true_parameters(pm, base.with_friction)
        return cls(pm, base, chain, laws, tuple(extra_terms(laws)), owners,
                   base.link_part(theta, 10 * len(pm.joint_ids)))

    @property
    def values(self) -> np.ndarray:
        """(e,) the model's own coefficients of the family columns."""
        return np.array([getattr(self.pm.frictions[k], key) for k, key in self.terms], dtype=float)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(f"{self.owners[k]}.{key}" for k, key in self.terms)

    @property
    def load(self) -> np.ndarray:
        return np.array([key == "load_coulomb" for _, key in self.terms], dtype=bool)

    def base_rows(self, q, qd, qdd) -> np.ndarray:
        """(N n, r): the base parameters' columns (a closed chain's actuated rows, through G^T)."""
        pm, base = self.pm, self.base
        W = (regressor(pm, q, qd, qdd, base.with_friction) if self.chain is None else
             chain_regressor(pm, self.chain, q, qd, qdd, base.with_friction))
        return W[:, base.independent]

    def rigid_torque(self, W: np.ndarray, beta: np.ndarray) -> np.ndarray:
        """(N n,) the rigid-body torque of the fit beta at the states whose base rows are W: the base
        parameters that hold a link's inertia, less the drive's share (links_weights)."""
        return W @ links_weights(beta[: len(self.base.independent)], self.link_part)

    def family_rows(self, q, qd, W: np.ndarray, rigid: np.ndarray | None = None) -> np.ndarray:
        """(N n, e): the families' columns at the states whose base rows are W, a load term's from the
        rigid-body torque `rigid` (`rigid_torque`; zero where none is given). A load term is a tree's: a
        closed chain's law cannot depend on the load (harness/model/load.py)."""
        N, n = qd.shape
        E = extra_regressor(self.laws, qd, None if rigid is None else rigid.reshape(N, n), self.pm.transmission, q=q)
        if self.chain is None:
            return E
        from harness.model.closure import projection

        return np.einsum("nja,nje->nae", projection(self.chain, q), E.reshape(N, n, -1)).reshape(len(W), -1)

    def rows(self, q, qd, qdd, beta: np.ndarray | None = None) -> np.ndarray:
        """(N n, r + e): the base parameters' columns, then the families' (a load term's at the rigid torque
        of the fit `beta`)."""
        W = self.base_rows(q, qd, qdd)
        if not self.terms:
            return W
        rigid = None if beta is None or not self.load.any() else self.rigid_torque(W, beta)
        return np.hstack([W, self.family_rows(q, qd, W, rigid)])

    def predict(self, beta: np.ndarray, q, qd, qdd) -> np.ndarray:
        return self.rows(q, qd, qdd, beta) @ beta

    def fit(self, q, qd, qdd, tau, beta_model: np.ndarray) -> Estimate:
        """fit_base of the rows; with load-dependent terms, the fixed point of the class docstring (the base
        rows made once, the families' columns again at each step)."""
        W = self.base_rows(q, qd, qdd)
        if not self.load.any():
            return fit_base(np.hstack([W, self.family_rows(q, qd, W)]) if self.terms else W, tau, beta_model)
        keep = np.concatenate([np.ones(W.shape[1], dtype=bool), ~self.load])
        fit = fit_base(np.hstack([W, self.family_rows(q, qd, W)])[:, keep], tau, beta_model[keep])
        beta = np.zeros(len(beta_model))
        beta[keep] = fit.beta
        rigid = self.rigid_torque(W, beta)
        for _ in range(FIXED_POINT_ITERATIONS):
            fit = fit_base(np.hstack([W, self.family_rows(q, qd, W, rigid)]), tau, beta_model)
            rigid, before = self.rigid_torque(W, fit.beta), rigid
            if np.max(np.abs(rigid - before)) <= FIXED_POINT_TOL * np.max(np.abs(rigid)):
                break
        return fit
