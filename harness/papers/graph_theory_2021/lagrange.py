"""Sections 2.4, 2.5 and 3.2 on a recording: constraints, Eq. 111, multipliers, conditioning and
the forward simulation of the constrained model. Results are plain data for results.json."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from harness.base.series import TimeSeries
from harness.model.kinematics import cross
from harness.model.spec import RobotSpec
from harness.papers.graph_theory_2021.cardano import GIMBAL_COND_D, A_0i, D, cond_D
from harness.papers.graph_theory_2021.constrained import Constrained, solve_constrained
from harness.papers.graph_theory_2021.constraints import ConstraintSet, build_constraints
from harness.papers.graph_theory_2021.dynamics import BodySeries, GraphModel, body_series
from harness.papers.graph_theory_2021.forward import ForwardResult, forward_simulate
from harness.runner.scenario import Scenario
from harness.stages.metrics import largest


@dataclass(frozen=True, eq=False)
class Formulation:
    constraints: ConstraintSet
    solution: Constrained
    max_abs_phi: float  # on the recording
    max_abs_phi_dot: float | None  # Phi_q q' on the recording, where the Cardano angles are regular
    axis_rank_deficient: dict[str, int]  # joint -> rows where its two axis rows have rank < 2 (a hinge's)


@dataclass(frozen=True, eq=False)
class LagrangeOutput:
    formulations: dict[str, Formulation]  # "normal", "paper"
    time_row: int | None
    forward: ForwardResult | None  # with the correction
    open_loop: ForwardResult | None  # without it, stopped once 1e-6 away


FORMULATIONS = ("normal", "paper")


def _formulation(spec: RobotSpec, model: GraphModel, rec: TimeSeries, s: BodySeries, well: np.ndarray,
                 name: str) -> Formulation:
    """One formulation's constraints and Eq. 111 on the recording (`s` its body series, `well` the
    rows where every body's Cardano angles are regular)."""
    cs = build_constraints(spec, model.topology, name)
    sol = solve_constrained(spec, model, cs, rec, s)
    # axis-row rank wherever Cardano angles are regular (Eq. 111 may still be singular there)
    deficient = {}
    for joint in model.topology.joints:
        rows = [k for k, lab in enumerate(cs.labels) if lab.startswith(f"{joint}.axis")]
        if not rows:  # a chain of hinges (a ball or universal joint) has none
            continue
        sv = np.linalg.svd(sol.Phi_q[well][:, rows], compute_uv=False)
        deficient[joint] = int(np.sum(sv[:, -1] < 1e-8 * sv[:, 0]))
    return Formulation(cs, sol, float(np.max(np.abs(sol.phi))), largest(np.abs(sol.phi_dot[well])), deficient)


@dataclass(frozen=True)
class Settings:
    """Section 3.2 settings: the time at which the multipliers are reported (None: not reported),
    the paper's values to set beside them, and whether to integrate the constrained model."""

    time: float | None = None
    paper_lambda: str | None = None
    forward_simulation: bool = False


def lagrange(scenario: Scenario, spec: RobotSpec, lg: Settings, model: GraphModel, rec: TimeSeries,
             progress=None) -> LagrangeOutput:
    """Sections 2.4-2.5 on the recording of `scenario`, for the graph model of `spec`. The two
    formulations are independent and evaluated at once, on two threads: most of each is batched
    LAPACK (the condition numbers of Eq. 111 at every row), which runs without the interpreter's
    lock, and each is computed exactly as it would be alone."""
    s = body_series(rec, model.topology)
    well = np.all(cond_D(s.theta) <= GIMBAL_COND_D, axis=1)
    with ThreadPoolExecutor(len(FORMULATIONS)) as pool:
        forms = dict(zip(FORMULATIONS, pool.map(lambda name: _formulation(spec, model, rec, s, well, name),
                                                FORMULATIONS), strict=True))
    row = None if lg.time is None else round(lg.time / scenario.output_dt)
    forward = open_loop = None
    if lg.forward_simulation:
        args = (spec, model, forms["normal"].constraints, rec, rec.drive.stages,
                scenario.simulation.timestep, scenario.substeps)

        def report(what):
            return None if progress is None else (lambda fraction: progress(what, fraction))

        forward = forward_simulate(*args, reference=lambda t: scenario.prescribed(t)[:2],
                                   on_progress=report("constrained model, forward simulation"))
        open_loop = forward_simulate(*args, stop_above=1e-6,
                                     on_progress=report("constrained model, open-loop replay"))
    return LagrangeOutput(forms, row, forward, open_loop)


def reactions_at(out: LagrangeOutput, spec: RobotSpec, model: GraphModel, rec: TimeSeries, row: int
                 ) -> list[dict]:
    """Per joint at one row: its multipliers (normal formulation), the constraint force and moment
    (about the joint point) they exert on the outer body, world components, and the static weight
    of the bodies outboard, sum m_k |g| (what the paper's lambda_i3 equal)."""
    form = out.formulations["normal"]
    top = model.topology
    theta = rec.theta[row, [rec.body_index(x) for x in top.bodies]]
    A, Dm = A_0i(theta), D(theta)
    Phi_q, lam = form.solution.Phi_q[row], form.solution.lam[row]
    labels = form.constraints.labels
    out_rows = []
    for k, joint in enumerate(top.joints):
        idx = [m for m, lab in enumerate(labels) if lab.split(".")[0] == joint]
        j = k  # O_k is the inner joint of B_k
        gen = -(Phi_q[idx].T @ lam[idx]).reshape(top.n, 6)[j]  # on the outer body
        force = gen[:3]
        moment_cm = A[j] @ np.linalg.solve(Dm[j].T, gen[3:])  # D^-T back to a moment, world
        arm = A[j] @ top.c_B[j, k]  # centre of mass to joint point
        weight = sum(body.mass for body in spec.outboard_bodies(joint)) * np.linalg.norm(model.g_W)
        out_rows.append({
            "body": top.bodies[j], "joint": joint,
            "labels": [labels[m].split(".")[1] for m in idx], "lambda": lam[idx].tolist(),
            "constraint_force_W": force.tolist(),
            "constraint_moment_W": (moment_cm - cross(arm, force)).tolist(),
            "static_weight_outboard": float(weight),
        })
    return out_rows
