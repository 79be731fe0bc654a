"""A payload's inertial parameters from two runs of the same motion, without and with it:

    tau_with = W(q, q', q'') theta_robot + W_b(q, q', q'') theta_payload

where W_b holds the 10 columns of the body that carries the payload. The robot's own part is
predicted at the loaded run's states from the base parameters identified on the run without it
(harness/identify/torque_id.py), and least squares of the difference on W_b gives the payload's ten
parameters (m, m c, inertia about the joint point, world axes at q = 0, as the body's own in
Pinocchio's joint frame), by the ordinary least squares of harness/identify/estimators.py (CR3 standard
deviations clustered by sample).
A scenario asks for it with

    [payload]
    without = "ur5_sines.toml"   # the same motion of the robot without the payload
    body = "wrist_3_link"        # the body carrying it

The truth is the difference of the two models' parameters of that body.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from harness.base.numerics import relative_residual
from harness.base.plugins import Stage
from harness.engines.pinocchio import build_model
from harness.identify.estimators import ols
from harness.identify.torque_id import regressor, structural_base, true_parameters
from harness.model.inertia import PARAMETER_NAMES, kind_scale
from harness.sources.bench import Setup
from harness.sources.measurement import measure
from harness.stages.shared import with_friction


@dataclass(frozen=True, eq=False)
class Payload:
    body: str
    joint: str
    true: np.ndarray  # (10,)
    identified: np.ndarray
    std: np.ndarray
    ci_half_width: np.ndarray
    residual_rel: float  # ||delta tau - W_b theta|| / ||delta tau||

    def serialise(self, ctx, config) -> dict:
        """results.json's `payload`: the payload's ten parameters against the truth."""
        scale = kind_scale(self.true)
        rel = np.abs(self.identified - self.true) / np.where(scale > 0, scale, 1.0)
        inside = np.abs(self.identified - self.true) <= self.ci_half_width
        return {
            "method": "least squares of the torques the robot without the payload does not explain, on the 10 columns "
                      "of the body carrying it (harness/stages/payload.py)",
            "body": self.body, "joint": self.joint,
            "rel_error_definition": "|identified - true| / the largest true value of its kind (m; m c, at least m r_g; "
                                    "inertia) in the payload",
            "max_rel_error": float(rel.max()),
            "all_within_ci95": bool(inside.all()),
            "outside_ci95": int((~inside).sum()),
            "residual_rel": self.residual_rel,
            "parameters": [{"name": name, "true": float(self.true[c]), "identified": float(self.identified[c]),
                            "rel_error": float(rel[c]), "std": float(self.std[c]),
                            "ci95_half_width": float(self.ci_half_width[c]), "within_ci95": bool(inside[c])}
                           for c, name in enumerate(PARAMETER_NAMES)],
        }


@dataclass(frozen=True, eq=False)
class PayloadConfig:
    """`[payload]`: the same motion without the payload, and the body that carries it."""

    without: Setup  # the same motion of the robot without the payload (a scenario)
    body: str


def configure(t, scenario) -> PayloadConfig:
    """`[payload] without = "ur5_sines.toml", body = "wrist_3_link"`, validated (one-line errors
    naming the key): the run without it moves the same robot, and the body has mass."""
    without = scenario.related(t, "without")
    body = t.string("body")
    robot = scenario.robot
    if without.robot.joint_names != robot.joint_names:
        raise t.error("without", f"{t.data['without']!r} moves another robot than {robot.name!r}")
    if body not in {b.name for b in robot.massive_bodies}:
        raise t.error("body", f"no body {body!r} with mass in {robot.name!r}")
    return PayloadConfig(without, body)


def run(ctx, config: PayloadConfig | None) -> Payload | None:
    sc = ctx.scenario
    if config is None:
        return None
    friction = with_friction(sc)
    without = config.without
    body = config.body
    joints = sc.robot.joint_names
    n = len(joints)
    k = joints.index(sc.robot.inner_joint(body).name)
    pm_with = build_model(sc.robot, sc.gravity_W)
    pm_without = build_model(without.robot, sc.gravity_W)
    base = structural_base(pm_without, without.robot.limits, with_friction=friction)
    # the run without the payload, measured as this one is (its own noise draws)
    rec0 = ctx.recorded(without)
    m = sc.measurement
    meas0 = measure(rec0, m.with_seed(m.seed + 1))
    q0, qd0, qdd0, tau0 = meas0.joint_data(joints)
    W0 = regressor(pm_without, q0, qd0, qdd0, friction)[:, base.independent]
    beta0 = ols(W0, tau0.reshape(-1), n).beta
    q, qd, qdd, tau = ctx.training.joint_data(joints)
    W = regressor(pm_without, q, qd, qdd, friction)
    delta = tau.reshape(-1) - W[:, base.independent] @ beta0
    Wb = W[:, 10 * k: 10 * k + 10]
    est = ols(Wb, delta, n)
    r = delta - Wb @ est.beta
    true = true_parameters(pm_with)[10 * k: 10 * k + 10] - true_parameters(pm_without)[10 * k: 10 * k + 10]
    return Payload(body, joints[k], true, est.beta, est.std, est.ci_half_width, relative_residual(r, delta))


STAGE = Stage("payload", "payload from the runs with and without it", run, Payload.serialise, "Payload",
              table="payload", configure=configure, recordings=lambda c, sc: (c.without,) if c is not None else ())
