"""An identification method plugged in (harness/base/plugins.py), fitted and read the same way on the
bench and on a log: its fit called on measured data in its own joint order, what its fitted model
reports (parameters, covariance, friction) checked and brought to the robot's order, and its
parameters reduced to the robot's structural base parameters (harness/identify/torque_id.py)."""

from __future__ import annotations

import inspect
from dataclasses import dataclass

import numpy as np

from harness.base.numerics import parameter_scale, relative_error
from harness.base.plugins import (
    ModelUnderTest,
    PluginError,
    check_array,
    check_protocol,
    column_maps,
    guard,
    invoke,
)
from harness.engines.pinocchio import build_model
from harness.identify.torque_id import describe_base, parameter_names, structural_base, true_parameters


@dataclass(frozen=True, eq=False)
class BaseTable:
    """A method's parameters reduced to the robot's structural base parameters (harness/identify/torque_id.py)."""

    expressions: list[str]  # each base parameter as the combination of standard parameters it stands for
    true: np.ndarray  # (r,) the robot's
    identified: np.ndarray  # (r,) the method's
    std: np.ndarray | None  # (r,) from the method's covariance, when it gives one

    @property
    def rel_error(self) -> np.ndarray:
        return relative_error(self.identified, self.true, parameter_scale(self.true))


@dataclass(frozen=True, eq=False)
class BaseMap:
    """The robot's structural base parameters as a map from a method's parameters: beta = T theta."""

    expressions: list[str]  # each base parameter as the combination of standard parameters it stands for
    T: np.ndarray  # (r, 10 n)
    true: np.ndarray  # (r,) the robot's own


def base_map(ctx, truth: bool = False, with_friction: bool = False) -> BaseMap:
    """The structural base parameters of the scenario's robot, or (`truth`) of the model that made a
    bench log (a log scenario's `[data] truth`), with that model's own values; `with_friction`: of the
    links' parameters and each joint's [armature, viscous, coulomb, offset] after them (T: (r, 14 n)). The
    base of every body's ten, a massless body's too (torque_id.structural_base, `known_zeros` off): a method
    takes them all as unknowns, and a massless body's that it finds apart from zero are its, not round-off."""
    sc = ctx.scenario
    robot = sc.truth if truth else sc.robot

    def make() -> BaseMap:
        pm = build_model(robot, sc.gravity_W)
        base = ctx.once(("truth's structural base" if truth else "every body's structural base", with_friction),
                        lambda: structural_base(pm, robot.limits, with_friction=with_friction, known_zeros=False))
        r = len(base.independent)
        T = np.zeros((r, len(base.independent) + len(base.dependent)))
        T[np.arange(r), base.independent] = 1.0
        T[:, base.dependent] = base.combination
        names = parameter_names(robot.joint_names, with_friction)
        return BaseMap([describe_base(names, base, k) for k in range(r)], T,
                       base.of(true_parameters(pm, with_friction)))

    return ctx.once(("base parameters of the methods", truth, with_friction), make)


def reported(plugin: str, fitted, what: str, joints: list[str], width: int) -> np.ndarray | None:
    """A fitted model's (n, width) `what` ("parameters", "friction"), checked and brought from its
    `joint_names` order to the robot's; None where it reports none."""
    with guard(plugin, f"reading the fitted model's {what}"):
        value = getattr(fitted, what, None)
    if value is None:
        return None
    _, back = column_maps(fitted.joint_names, joints)
    return check_array(plugin, what, value, (len(joints), width))[back]


COVARIANCE_ROUND_OFF = 1e-9  # of a covariance's largest entry: what its products leave of asymmetry or of a
# negative eigenvalue (a method's sigma^2 (W^T W)^-1 turned to world axes: about 1e-16); beyond it, no covariance


def base_table(plugin: str, fitted, joints: list[str], bm: BaseMap) -> BaseTable | None:
    """The fitted model's `parameters` ((n, 10), its joint order) and, when given, `covariance`
    ((10 n, 10 n), of those parameters flattened row by row) as the robot's structural base
    parameters beta = T theta, with covariance T Sigma T^T. None: it reports no parameters."""
    theta = reported(plugin, fitted, "parameters", joints, 10)
    if theta is None:
        return None
    with guard(plugin, "reading the fitted model's covariance"):
        cov = getattr(fitted, "covariance", None)
    std = None
    if cov is not None:
        n = len(joints)
        _, fit_to_robot = column_maps(fitted.joint_names, joints)
        order = (np.asarray(fit_to_robot)[:, None] * 10 + np.arange(10)).reshape(-1)  # its entries, robot order
        cov = check_array(plugin, "covariance", cov, (10 * n, 10 * n))[np.ix_(order, order)]
        size = np.max(np.abs(cov), initial=0.0)
        asymmetry = np.max(np.abs(cov - cov.T), initial=0.0)
        if asymmetry > COVARIANCE_ROUND_OFF * size:
            raise PluginError(plugin, f"covariance is not symmetric (largest |C - C^T| is {asymmetry / size:.2g} of "
                                      "its largest entry)")
        base = bm.T @ cov @ bm.T.T
        var = np.diag(base)
        lowest = np.linalg.eigvalsh(0.5 * (base + base.T))[0] if base.size else 0.0
        if (np.any(var < -1e-12 * np.max(np.abs(var), initial=0.0))
                or lowest < -COVARIANCE_ROUND_OFF * np.max(np.abs(var), initial=0.0)):
            raise PluginError(plugin, "covariance is not positive semidefinite on the base parameters (lowest "
                                      f"eigenvalue {lowest:.3g}, largest variance {np.max(var, initial=0.0):.3g})")
        std = np.sqrt(np.maximum(var, 0.0))
    return BaseTable(bm.expressions, bm.true, bm.T @ theta.reshape(-1), std)


def fit_method(plugin: str, method, joints: list[str], q, qd, qdd, tau, t=None):
    """A method's fit on measured (q, q', q'', tau) in the robot's joint order, and the sample times
    `t` (s) where its fit takes a parameter `t`; the fitted model, checked against the
    model-under-test protocol."""
    to_method, _ = column_maps(method.joint_names, joints)
    args = (q[:, to_method], qd[:, to_method], qdd[:, to_method], tau[:, to_method])
    with guard(plugin, "reading its fit's signature"):
        takes_t = "t" in inspect.signature(method.fit).parameters
    fitted = invoke(plugin, "fit", (lambda *a: method.fit(*a, t=t)) if takes_t else method.fit, *args)
    check_protocol(f"{plugin} (its fitted model)", fitted, ModelUnderTest, joints)
    return fitted


@dataclass(frozen=True, eq=False)
class SkippedMethod:
    """A method whose tool is not installed (harness/base/plugins.py, ToolUnavailable)."""

    name: str
    reference: str
    reason: str

    @classmethod
    def of(cls, entry) -> SkippedMethod:
        return cls(entry.name, entry.reference, entry.skipped)

    def serialise(self) -> dict:
        return {"plugin": self.reference, "skipped": self.reason}
