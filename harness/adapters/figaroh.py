"""FIGAROH (Nguyen et al., figaroh on PyPI, 1.0.x) as an identification method: its joint-torque
regressor, its elimination of unexcited columns, its QR base parameters and its least squares
(`fit = "least_squares"`, FIGAROH's `BaseIdentification.solve` without decimation), or its physically
consistent effort fit (`fit = "physical"`: `physical_fit.solve_direct_effort_fit`, a pseudo-inertia
LMI per link, cvxopt), on a Pinocchio model of the scenario's robot (harness/engines/pinocchio.py: the
same kinematics and parameter convention as the harness, so that only the method differs).

Per joint FIGAROH identifies viscous friction f_v q', a sharp Coulomb f_s sign(q'), the rotor inertia
I_a q'' and an offset: a smooth Coulomb law is not in its model, and its least squares reports base
parameters only, so the parameters handed back are its minimum-norm split of them
(`redistribute_min_norm`), which it does not claim to be physical; the physical fit bounds the link
masses and pseudo-inertias but not the rotor inertia or friction. The fitted model says so in its `notes`.

    [identification]
    name = "figaroh"
    plugin = "figaroh"          # pip install 'harness[figaroh]'
    fit = "least_squares"       # or "physical"
    zero_tolerance = 0.001      # a column whose squared norm is below this is dropped (BaseIdentification's)
    qr_tolerance = 1e-8         # the rank threshold of its QR

Where a tolerance is not given, FIGAROH's own default is used, read from the installed FIGAROH: the
QR's is its QRDecomposer's (`figaroh.tools.qrdecomposition.TOL_QR`, 1e-8 in 1.0.2), the physical
fit's its `build_problem`'s `qr_tol` (1e-6 in 1.0.2), the column elimination's BaseIdentification's
`zero_tolerance` (0.001; the function alone defaults to 1e-6). FIGAROH 1.0.2's BaseIdentification
itself ranks its QR at 1e-6 (a fallback inside its code, not a parameter).
"""

from __future__ import annotations

import logging
import warnings
from types import SimpleNamespace

import numpy as np

from harness.base.plugins import PluginError, ToolUnavailable
from harness.base.tomlio import in_one_line
from harness.engines.pinocchio import build_model

FITS = ("least_squares", "physical")
# FIGAROH's additional columns, in its order after the 10 inertial ones per joint, and where each goes in
# the harness's [armature, viscous, coulomb, offset]
EXTRA = (("fv", 1), ("fs", 2), ("Ia", 0), ("off", 3))
OPTIONS = ("fit", "zero_tolerance", "qr_tolerance")
ZERO_TOLERANCE = 1e-3  # FIGAROH's BaseIdentification's `zero_tolerance` (a keyword default of its, 1.0.2)


def _figaroh():
    """FIGAROH's functions, imported quietly (it logs and warns on import); ToolUnavailable when absent."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            from figaroh.identification.parameter import add_standard_additional_parameters, get_standard_parameters
            from figaroh.identification.physical_fit import build_problem, solve_direct_effort_fit
            from figaroh.tools.qrdecomposition import TOL_QR, QRDecomposer, redistribute_min_norm
            from figaroh.tools.regressor import build_regressor_basic, build_regressor_reduced, get_index_eliminate
    except ImportError as exc:
        raise ToolUnavailable("figaroh", f"FIGAROH is not installed ({exc}); pip install 'harness[figaroh]'") from None
    logging.getLogger("figaroh").setLevel(logging.ERROR)
    return SimpleNamespace(**{f.__name__: f for f in (
        add_standard_additional_parameters, get_standard_parameters, build_problem, solve_direct_effort_fit,
        redistribute_min_norm, build_regressor_basic, build_regressor_reduced, get_index_eliminate)},
        QRDecomposer=QRDecomposer, TOL_QR=float(TOL_QR))


class Figaroh:
    """The method: `fit(q, q', q'', tau)` in the robot's joint order -> a fitted model."""

    def __init__(self, robot, gravity_W, parameters: dict):
        unknown = sorted(set(parameters) - set(OPTIONS))
        if unknown:
            raise PluginError("figaroh", f"unknown option(s) {', '.join(unknown)} (known: {', '.join(OPTIONS)})")
        self.fit_kind = parameters.get("fit", "least_squares")
        if self.fit_kind not in FITS:
            raise PluginError("figaroh", f"fit = {self.fit_kind!r}: one of {', '.join(FITS)}")
        self.fg = _figaroh()
        self.zero_tolerance = float(parameters.get("zero_tolerance", ZERO_TOLERANCE))
        self.qr_tolerance = float(parameters.get("qr_tolerance", self.fg.TOL_QR))
        self.physical_qr = {"qr_tol": self.qr_tolerance} if "qr_tolerance" in parameters else {}
        self.pm = build_model(robot, gravity_W)
        self.joint_names = list(robot.joint_names)
        model = self.pm.model
        self.config = {"has_friction": True, "has_actuator_inertia": True, "has_joint_offset": True,
                       "is_joint_torques": True, "act_idxv": list(range(model.nv))}
        self.robot = SimpleNamespace(model=model, data=model.createData())
        std = self.fg.get_standard_parameters(model, self.config)
        std.update(self.fg.add_standard_additional_parameters(model, self.config))
        self.standard = std  # FIGAROH's names -> the model's own values (its prior)

    def regressor(self, q, qd, qdd) -> np.ndarray:
        """FIGAROH's regressor, rows joint by joint (row j N + i: joint j at sample i, its stacking)."""
        model = self.pm.model
        Q, V, A = (np.zeros((len(q), model.nq)) for _ in range(3))
        Q[:, self.pm.q_index], V[:, self.pm.q_index], A[:, self.pm.q_index] = q, qd, qdd
        return self.fg.build_regressor_basic(self.robot, Q, V, A, self.config)

    def stacked(self, tau: np.ndarray) -> np.ndarray:
        full = np.zeros((len(tau), self.pm.model.nv))
        full[:, self.pm.q_index] = tau
        return full.T.ravel()

    def fit(self, q, qd, qdd, tau):
        W = self.regressor(q, qd, qdd)
        names = list(self.standard)
        if self.fit_kind == "physical":
            prior = np.array([self.standard[k] for k in names])
            joints = [self.pm.model.names[j] for j in range(1, self.pm.model.njoints)]
            problem = self.fg.build_problem(W, self.stacked(tau), names, joints, prior=prior, **self.physical_qr)
            record = self.fg.solve_direct_effort_fit(problem, solver="cvxopt")
            if not record.accepted:
                raise RuntimeError(f"FIGAROH's physical fit was not accepted: {_why_rejected(record)}")
            x = np.array([self.standard[k] for k in names], dtype=float)
            x[[names.index(k) for k in problem.params_std]] = record.theta
            return Fitted(self, x, "all parameters by FIGAROH's physical fit (pseudo-inertia LMI per link); rotor "
                                   "inertia and friction unbounded")
        idx_e, active = self.fg.get_index_eliminate(W, self.standard, tol_e=self.zero_tolerance)
        W_e = self.fg.build_regressor_reduced(W, idx_e)
        qr = self.fg.QRDecomposer(tolerance=self.qr_tolerance)
        _, _, _, phi_base, _ = qr.double_decomposition(self.stacked(tau), W_e, active, self.standard)
        M = qr.get_M()  # phi_base = M theta_active
        x = np.array([self.standard[k] for k in names], dtype=float)  # eliminated columns: the model's values
        x[[names.index(k) for k in (qr.get_M_labels()[1] or active)]] = self.fg.redistribute_min_norm(M, phi_base)
        return Fitted(self, x, "parameters: FIGAROH's minimum-norm split of its base parameters (not a physical "
                               "claim); columns it eliminated keep the model's values")


def _why_rejected(record) -> str:
    """Why FIGAROH refused its own physical fit, from its SolveRecord (figaroh 1.0: solver_status,
    exception, the links failing its pseudo-inertia test, the relative base residual)."""
    failing = [name for name, f in (record.feasibility or {}).items() if not f.get("ok", True)]
    parts = [f"solver status {record.solver_status}"]
    if record.exception:
        parts.append(f"exception {in_one_line(str(record.exception))}")
    if failing:
        parts.append(f"links failing its physical test: {', '.join(failing)}")
    residual = (record.base_residual or {}).get("relative")
    if residual is not None:
        parts.append(f"relative base residual {residual:.3g}")
    return "; ".join(parts)


class Fitted:
    """FIGAROH's identified model: torques W(q, q', q'') x from its parameter vector x."""

    def __init__(self, method: Figaroh, x: np.ndarray, how: str):
        self.method, self.x = method, x
        self.joint_names = method.joint_names
        n, pm = len(self.joint_names), method.pm
        per_joint = x[: 10 * pm.model.nv].reshape(-1, 10)  # Pinocchio's joint order
        self.parameters = per_joint[np.asarray(pm.joint_ids, int) - 1]  # the robot's joint order
        extra = x[10 * pm.model.nv:].reshape(len(EXTRA), pm.model.nv)
        self.friction = np.zeros((n, 4))
        for row, (_, col) in enumerate(EXTRA):
            self.friction[:, col] = extra[row, pm.q_index]
        self.notes = (how, "Coulomb friction as a sharp sign(q') (FIGAROH's law), not a smooth one")

    def inverse_dynamics(self, q, qd, qdd) -> np.ndarray:
        m = self.method
        return (m.regressor(q, qd, qdd) @ self.x).reshape(m.pm.model.nv, -1).T[:, m.pm.q_index]


def make(robot, gravity_W, parameters) -> Figaroh:
    return Figaroh(robot, gravity_W, parameters)
