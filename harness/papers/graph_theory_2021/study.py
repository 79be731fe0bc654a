"""The paper's study as stages of a run, asked for by a scenario:

    [studies.graph_theory_2021]
    model = "../models/kr500.toml"          # optional: the graph model's parameters (default: the robot)
    paper_identified = "kr500_table3_identified_by_paper.csv"   # optional: Table 3, set beside ours
    paper_abs_error = "kr500_table4_paper_abs_errors.csv"        # optional: Table 4
    lagrange = { time = 1.5, paper_lambda = "kr500_lambda_at_1p5s_paper.csv", forward_simulation = false }

Stages: the unconstrained dynamics on the recording (section 2.2, Eq. 36), the identification of
section 2.3 at the scenario's sample times, all 10 inertial parameters per body, and constraints,
Eq. 111 and the multipliers (sections 2.4, 2.5, 3.2). Table names are files of this package's
reference/ folder.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from harness.base.plugins import Stage, Study, Sweep
from harness.base.reference import has_reference_table
from harness.base.tomlio import InputError, Table
from harness.engines.pinocchio import build_model as build_pinocchio
from harness.model.spec import RobotSpec
from harness.papers.graph_theory_2021 import report
from harness.papers.graph_theory_2021.dynamics import (
    D_error,
    GraphModel,
    Residual,
    body_series,
    build_graph_model,
    unconstrained_residual,
)
from harness.papers.graph_theory_2021.lagrange import LagrangeOutput, Settings, lagrange
from harness.papers.graph_theory_2021.readings import ANGLES_FILE, Readings, angles_csv, exact, read
from harness.papers.graph_theory_2021.solve import (
    PACKAGE,
    FullIdentification,
    Identification,
    graph_section,
    identify,
    identify_full,
    lagrange_section,
    measured_rows,
)
from harness.papers.graph_theory_2021.sweep import run_sweep
from harness.runner.scenario import load_variant

_GRID_TOL = 1e-9


@dataclass(frozen=True, eq=False)
class Config:
    tested: RobotSpec  # the graph model is built from it; the engines from the scenario's robot
    paper_identified: str | None
    paper_abs_error: str | None
    lagrange: Settings


def _table_name(t: Table, key: str) -> str | None:
    name = t.string(key, default=None) if t.has(key) else None
    if name is not None and not has_reference_table(PACKAGE, name):
        raise t.error(key, f"no reference table {name!r} in {PACKAGE}'s reference folder")
    return name


MIN_SAMPLE_TIMES = 2  # the uncertainty of section 2.3's estimates is taken over the sample times (CR3)


def configure(t: Table, scenario) -> Config:
    if len(scenario.sample_times) < MIN_SAMPLE_TIMES:
        raise InputError(scenario.source, "scenario.sample_times",
                         f"the graph-theory study identifies the parameters at the sample times: give at least "
                         f"{MIN_SAMPLE_TIMES} (or \"all\"), found {len(scenario.sample_times)}")
    tested = load_variant(t, "model", scenario)
    lt = t.table("lagrange", default={})
    time = lt.number("time", default=None, nonnegative=True) if lt.has("time") else None
    dt = scenario.output_dt
    if time is not None and (time > scenario.duration or abs(time / dt - round(time / dt)) > _GRID_TOL):
        raise lt.error("time", f"{time:g} s is not an output step of the run (every {dt:g} s up to "
                               f"{scenario.duration:g} s)")
    settings = Settings(time, _table_name(lt, "paper_lambda"), lt.boolean("forward_simulation", default=False))
    if settings.forward_simulation and not all(f.none for f in scenario.robot.frictions):
        raise lt.error("forward_simulation", "the constrained model is integrated without the joints' friction and "
                                             "rotor inertia, which this robot's model declares")
    robot = scenario.robot
    chains = [j.name for j in robot.joints if j.revolute and robot.body(j.child).massless]
    if settings.forward_simulation and chains:
        raise lt.error("forward_simulation", f"the constrained model's integration reads each joint's angle off its "
                                             f"two bodies, and hinge {chains[0]!r} turns a massless carriage (a ball "
                                             "or universal joint): its angle has no body to be read from")
    lt.finish()
    return Config(tested, _table_name(t, "paper_identified"), _table_name(t, "paper_abs_error"), settings)


def _readings(ctx) -> tuple[Readings, Readings]:
    """The paper's readings of the run (harness/papers/graph_theory_2021/readings.py): of the truth,
    and as measured."""
    sc = ctx.scenario
    arms = sc.robot.inner_joint_arms_B()
    def make() -> tuple[Readings, Readings]:
        truth = exact(ctx.truth, arms)
        return truth, read(truth, ctx.training, sc.measurement, arms)

    return ctx.once("graph_theory_2021 readings", make)


def _models(ctx, config: Config) -> tuple[GraphModel, GraphModel]:
    """The graph model of the model's parameters, and of the robot (the truth)."""
    g = ctx.scenario.gravity_W
    return ctx.once(("graph models", id(config)),
                    lambda: (build_graph_model(config.tested, g), build_graph_model(ctx.scenario.robot, g)))


@dataclass(frozen=True, eq=False)
class GraphChecks:
    """Section 2.2 on the recording: the graph model's unconstrained residual and its D matrix."""

    model: GraphModel  # of the tested parameters
    residual: Residual  # Eq. 36 on the recording
    D_error: float  # Eq. 33's D against a rotation library at every recorded orientation
    gimbal_rows: dict[str, list[float]]  # per body, the times of the rows near gimbal lock
    truth: Readings  # the paper's readings of the recording: its bodies' Cardano angles (Eq. 29)

    def serialise(self, ctx, config: Config) -> dict:
        """results.json's `graph`: the graph's matrices, the residual of Eq. 36 and the check of Eq. 33,
        and the file of the bodies' Cardano angles."""
        return {**graph_section(self.model, self.residual, self.D_error), "gimbal_lock_rows": self.gimbal_rows,
                "angles_file": ANGLES_FILE}

    def files(self) -> dict[str, str]:
        """cardano.csv beside recording.csv: every body's Cardano angles, row by row (readings.angles_csv)."""
        return {ANGLES_FILE: angles_csv(self.truth)}


@dataclass(frozen=True, eq=False)
class Constraints:
    """Sections 2.4, 2.5 and 3.2 on the recording: Eq. 111 and the Lagrange multipliers."""

    output: LagrangeOutput
    model: GraphModel  # of the tested parameters
    truth: Readings  # the paper's readings of the recording

    def serialise(self, ctx, config: Config) -> dict:
        """results.json's `lagrange`: the constraint residuals, the multipliers against Table 5's and,
        when asked, the forward simulation of the constrained model."""
        return lagrange_section(self.output, config.lagrange.paper_lambda, config.tested, self.model, self.truth)


def _graph_checks(ctx, config) -> GraphChecks:
    model, _ = _models(ctx, config)
    truth = _readings(ctx)[0]
    s = body_series(truth, model.topology)
    gimbal = {b: [float(x) for x in truth.t[truth.gimbal[:, i]]] for i, b in enumerate(truth.bodies)
              if truth.gimbal[:, i].any()}
    return GraphChecks(model, unconstrained_residual(model, s), D_error(s.theta), gimbal, truth)


def _identification(ctx, config):
    model, truth = _models(ctx, config)
    sc = ctx.scenario
    measured = _readings(ctx)[1]
    return identify(model, measured, measured_rows(measured, sc.sample_times), sc.measurement, truth)


def _identification_full(ctx, config):
    model, _ = _models(ctx, config)
    sc = ctx.scenario
    pm = build_pinocchio(sc.robot, sc.gravity_W)
    true10 = np.stack([pm.model.inertias[pm.joint_ids[sc.robot.joint_names.index(
        sc.robot.inner_joint(b).name)]].toDynamicParameters() for b in model.topology.bodies])
    measured = _readings(ctx)[1]
    return identify_full(config.tested, model, measured, measured_rows(measured, sc.sample_times), sc.measurement,
                         true10)


def _lagrange(ctx, config) -> Constraints:
    model, _ = _models(ctx, config)
    truth = _readings(ctx)[0]
    return Constraints(lagrange(ctx.scenario, config.tested, config.lagrange, model, truth, ctx.progress), model, truth)


def _sweep(scenario, trials, workers, progress) -> dict:
    return run_sweep(scenario, trials, workers, progress.counting(f"sweep ({workers.describe()})"))


def _render_sweep(sweep: dict) -> str:
    from harness.papers.graph_theory_2021.report_sweep import render_sweep

    return render_sweep(sweep)


def _sweep_summary(sweep: dict) -> list[str]:
    low, high = sweep["coverage_min"], sweep["coverage_max"]
    coverage = ("no parameter was identified in every trial" if low is None else
                f"coverage of the 95 % intervals {low:.3f} to {high:.3f} over the parameters identified in every trial")
    return [f"{sweep['scenario']}: {sweep['trials']} trials; {coverage}"]


STUDY = Study(
    name="graph_theory_2021",
    configure=configure,
    stages=(
        Stage("graph", "graph model: unconstrained dynamics", _graph_checks, GraphChecks.serialise,
              "Cardano angles", report.cardano_angles, files=GraphChecks.files),
        Stage("identification", "identifying parameters (section 2.3)", _identification, Identification.serialise,
              "Identification", lambda res, rec: report.identification(res)),
        Stage("identification_full", "identifying all 10 inertial parameters per body", _identification_full,
              FullIdentification.serialise, "10 parameters", lambda res, rec: report.identification_full(res)),
        Stage("lagrange", "constraints and Lagrange multipliers", _lagrange, Constraints.serialise,
              "Constraints", report.lagrange),
    ),
    sweep=Sweep(_sweep, _render_sweep, _sweep_summary),
)
