"""The paper's study as stages of a run:

    [studies.yahya2012]
    inertia_matrix_audit = true     # the printed inertia matrix (Appendix, Eq. A27 ff.) against CRBA
    design_comparison = { baseline = "planar6_case1_conventional.toml", shared_motor = ["J3", "J4", "J5", "J6"],
                          shared_motor_baseline_joint = "J3" }

`baseline` is another scenario (relative to this one) that moves the other design along the same
path (recorded by the bench before the stages run); `shared_motor` are the joints that one motor drives in this design.
"""

from __future__ import annotations

from dataclasses import dataclass

from harness.base.plugins import Stage, Study
from harness.base.tomlio import Table
from harness.papers.yahya2012 import report
from harness.papers.yahya2012.audit import audit_inertia_matrix
from harness.papers.yahya2012.claims import design_claims
from harness.runner.scenario import Scenario, load_related


@dataclass(frozen=True, eq=False)
class Config:
    audit: bool
    baseline: Scenario | None
    shared_motor: tuple[str, ...] = ()
    baseline_joint: str = ""


def configure(t: Table, scenario) -> Config:
    audit = t.boolean("inertia_matrix_audit", default=False)
    if not t.has("design_comparison"):
        return Config(audit, None)
    dc = t.table("design_comparison")
    robot = scenario.robot
    baseline = load_related(dc, "baseline", scenario.source)
    if baseline.robot.joint_names != robot.joint_names:
        raise dc.error("baseline", f"{dc.data['baseline']!r} has other joints than {robot.name!r}")
    shared = dc.strings("shared_motor", choices=tuple(robot.joint_names))
    joint = dc.string("shared_motor_baseline_joint", choices=tuple(robot.joint_names))
    dc.finish()
    return Config(audit, baseline, shared, joint)


def _claims(ctx, c: Config):
    if c.baseline is None:
        return None
    out = design_claims(ctx.scenario.robot, ctx.truth, ctx.recorded(c.baseline), list(c.shared_motor),
                        c.baseline_joint)
    out["baseline"] = c.baseline.name
    return out


def _audit(ctx, c: Config):
    return audit_inertia_matrix(ctx.scenario.robot) if c.audit else None


def _section(result: dict, ctx, config: Config) -> dict:
    """The stages of this study compute their results.json section directly (plain numbers)."""
    return result


STUDY = Study(
    name="yahya2012",
    configure=configure,
    stages=(
        Stage("design_comparison", "the paper's design claims", _claims, _section, "Claims",
              lambda res, rec: report.design_comparison(res),
              recordings=lambda c, sc: (c.baseline,) if c.baseline is not None else ()),
        Stage("inertia_matrix_audit", "auditing the printed inertia matrix", _audit, _section,
              "Inertia matrix audit", lambda res, rec: report.inertia_audit(res)),
    ),
)
