"""How far the scenario's motion goes against the model's own limits: for every joint, the largest
ratio of the recorded motion to its position range, velocity limit and effort limit (where the
robot description states them). A motion beyond a limit still runs (the engines do not enforce
them), but a warning line says so, and `motion.limits` holds the ratios for a gate."""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from harness.base.plugins import Stage
from harness.model import quaternion
from harness.model.cardano import rotation

KINDS = ("position", "velocity", "effort")


@dataclass(frozen=True, eq=False)
class LimitRatios:
    joints: list[str]
    ratios: dict[str, np.ndarray]  # kind -> (n,) largest ratio over the run; NaN where no limit is stated

    def beyond(self) -> list[str]:
        """`joint kind ratio` for every limit the motion exceeds."""
        return [f"{j} {kind} {r[k]:.3g}x" for kind, r in self.ratios.items() for k, j in enumerate(self.joints)
                if r[k] > 1.0]

    def serialise(self, ctx, config) -> dict:
        """results.json's `motion`: each limit's largest ratio over the run."""
        def value(x: float) -> float | None:
            return None if np.isnan(x) else float(x)

        return {
            "definition": "per joint the largest over the run of |q - centre| / half range (position), |q'| / limit "
                          "(velocity) and |tau| / limit (effort), a ball joint's hinges the angle of its rotation / "
                          "its cone (position); null where the model states no such limit; above 1 the motion goes "
                          "beyond it",
            "limits": {j: {kind: value(self.ratios[kind][k]) for kind in KINDS} for k, j in enumerate(self.joints)},
            "largest": {kind: value(np.nanmax(self.ratios[kind])) if np.any(~np.isnan(self.ratios[kind])) else None
                        for kind in KINDS},
            "beyond": self.beyond(),
        }


def ratios(robot, q: np.ndarray, qd: np.ndarray, tau: np.ndarray) -> LimitRatios:
    """(N, n) motion and drive torques in the robot's joint order against its limits: position as
    |q - centre| / half range, velocity |q'| / limit, effort |tau| / limit; a ball joint's three hinges
    (RobotSpec.cones) each the angle of the ball's rotation over its cone."""
    n = len(robot.joint_names)
    out = {kind: np.full(n, np.nan) for kind in KINDS}
    for k, j in enumerate(robot.joint_names):
        lo, hi = (robot.limits or {}).get(j, (-np.inf, np.inf))
        if np.isfinite(lo) and np.isfinite(hi) and hi > lo:
            out["position"][k] = np.max(np.abs(q[:, k] - (hi + lo) / 2)) / ((hi - lo) / 2)
        drive = (robot.drive_limits or {}).get(j, {})
        for kind, x in (("velocity", qd[:, k]), ("effort", tau[:, k])):
            limit = drive.get(kind)
            if limit is not None and np.isfinite(limit) and limit > 0:
                out[kind][k] = np.max(np.abs(x)) / limit
    for hinges, cone in (robot.cones or {}).values():  # a ball joint: the angle of its rotation against its cone
        k = [robot.joint_names.index(h) for h in hinges]
        out["position"][k] = np.max(quaternion.angle(quaternion.from_matrix(rotation(q[:, k])))) / cone
    return LimitRatios(list(robot.joint_names), out)


def run(ctx, config) -> LimitRatios:
    sc, rec = ctx.scenario, ctx.truth
    cols = [rec.joint_index(j) for j in sc.robot.joint_names]
    result = ratios(sc.robot, rec.q[:, cols], rec.qd[:, cols], rec.tau[:, cols])
    beyond = result.beyond()
    if beyond:
        logging.getLogger("harness").warning(f"warning: {sc.name}: the motion goes beyond the model's limits: "
                                             f"{', '.join(beyond)} (results.json: motion.limits)")
    return result


STAGE = Stage("motion", "the motion against the model's limits", run, LimitRatios.serialise)
