"""The data flow of DESIGN.md for one scenario: record, then model checks and identification.

Each stage is a function from immutable inputs to an immutable output; this module only
chains them and gathers the results.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from harness.claims import design_claims
from harness.compare import joint_load_scale
from harness.engines.mujoco import simulate
from harness.engines.pinocchio import InverseDynamics, rnea_on_recording
from harness.engines.pinocchio import build_model as build_pinocchio
from harness.excitation import optimise as optimise_excitation
from harness.graph.dynamics import (
    GraphModel,
    Residual,
    body_series,
    build_graph_model,
    unconstrained_residual,
)
from harness.graph.full import FULL_PARAMETERS, full_form
from harness.graph.identification import PARAMETERS, id_Y, id_Z, stack_per_body, stack_system
from harness.graph.inverse import GraphInverse, inverse_dynamics
from harness.identify import LeastSquares, solve
from harness.lagrange import LagrangeOutput, lagrange
from harness.measurement import Measurement, dither, measure
from harness.recording import Recording
from harness.scenario import Scenario
from harness.torque_id import TorqueIdentification, identify_from_torques
from harness.yahya2012 import audit_inertia_matrix


@dataclass(frozen=True, eq=False)
class Identification:
    bodies: tuple[str, ...]
    per_body: tuple[LeastSquares, ...]
    system: LeastSquares | None  # Eqs. 57-64, all bodies at once (None when not asked for)
    true: np.ndarray  # (n, 6) the true values (m, m, m, J11, J22, J33)
    sample_times: np.ndarray
    resolution: float  # relative resolution of the measurement the floors were taken at


N_DITHER = 4  # draws for the regressor's measurement-error floor (a size, not a statistic)


def _regressor(model: GraphModel, rec: Recording, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The paper's identification form (Eqs. 49-51) at the given rows: id_Y, id_Z."""
    s = body_series(rec, model.topology, rows)
    return id_Y(s, model.g_W), id_Z(s)


def measured_rows(measured: Recording, times: np.ndarray) -> np.ndarray:
    """Rows of a (possibly subsampled) measured recording at the given times."""
    dt = measured.t[1] - measured.t[0] if len(measured.t) > 1 else 1.0
    return np.array([int(np.argmin(np.abs(measured.t - ts))) for ts in times
                     if np.min(np.abs(measured.t - ts)) <= 1e-9 * dt])


def _solve_per_body(form: Callable[[Recording], tuple[np.ndarray, np.ndarray]], measured: Recording,
                    measurement: Measurement, names: tuple[str, ...]):
    """Per-body least squares of a regressor form Y x = Z (Y: (N, n, rows, p)), each column judged
    against its measurement-error floor: Y rebuilt from the measured channels moved within the
    measurement's errors (fixed seed, so a run is reproducible), the rms change of each column.
    Returns Y, Z, the floors and the per-body solutions."""
    Y, Z = form(measured)
    rng = np.random.default_rng(0)
    dY = [form(dither(measured, measurement, rng))[0] - Y for _ in range(N_DITHER)]
    K, L = stack_per_body(Y, Z)
    floor = np.sqrt(np.mean([np.linalg.norm(stack_per_body(d, Z)[0], axis=1) ** 2 for d in dY], axis=0))
    N, n, k = Y.shape[:3]
    sample, channel = np.repeat(np.arange(N), k), np.tile(np.arange(k), N)  # rows of one body
    return Y, Z, floor, tuple(solve(K[i], L[i], names, floor[i], sample, channel) for i in range(n))


def identify(model: GraphModel, measured: Recording, rows: np.ndarray,
             measurement: Measurement, truth: GraphModel | None = None, with_system: bool = True) -> Identification:
    """Section 2.3: per body (Eq. 56) and for the whole system (Eq. 64)."""
    Y, Z, floor, per_body = _solve_per_body(lambda rec: _regressor(model, rec, rows), measured, measurement,
                                            PARAMETERS)
    N, n = Y.shape[:2]
    system = None
    if with_system:
        Ks, Ls = stack_system(Y, Z)
        names = [f"{b}.{p}" for b in model.topology.bodies for p in PARAMETERS]
        system = solve(Ks, Ls, names, floor.reshape(-1), np.repeat(np.arange(N), 6 * n),
                       np.tile(np.arange(6 * n), N))
    truth = truth or model
    true = np.column_stack([truth.m, truth.m, truth.m, truth.J])
    return Identification(model.topology.bodies, per_body, system, true, measured.t[rows], measurement.resolution)


@dataclass(frozen=True, eq=False)
class FullIdentification:
    bodies: tuple[str, ...]
    per_body: tuple[LeastSquares, ...]
    true: np.ndarray  # (n, 10) Pinocchio's dynamic parameters of the true robot


def identify_full(spec, model: GraphModel, measured: Recording, rows: np.ndarray, measurement: Measurement,
                  true: np.ndarray) -> FullIdentification:
    """All 10 inertial parameters per body (harness/graph/full.py), with the same excitation test
    and uncertainty as the paper's form."""
    *_, per_body = _solve_per_body(lambda rec: full_form(spec, model, rec, rows), measured, measurement,
                                   FULL_PARAMETERS)
    return FullIdentification(model.topology.bodies, per_body, true)


@dataclass(frozen=True, eq=False)
class RunOutput:
    scenario: Scenario
    model: GraphModel
    recording: Recording  # the ideal recording: the truth
    measured: Recording  # what the identification sees
    residual: Residual  # Eq. 36 on the ideal recording
    identification: Identification
    lagrange: LagrangeOutput  # sections 2.4-2.5 on the ideal recording
    pinocchio: InverseDynamics  # RNEA on the recorded motion
    graph_inverse: GraphInverse  # the graph model's inverse dynamics on the recorded motion
    design_comparison: dict | None = None  # claims against another design on the same path
    audit: dict | None = None  # a paper's printed inertia matrix against CRBA
    torque_identification: TorqueIdentification | None = None
    identification_full: FullIdentification | None = None
    excitation: dict | None = None
    timings: dict | None = None  # seconds per stage


Progress = Callable[[str, float | None], None]


def _quiet(stage: str, fraction: float | None) -> None:
    pass


class _Timed:
    """Passes progress on and adds up the seconds spent in each stage."""

    def __init__(self, progress: Progress):
        self.progress, self.timings, self.stage, self.start = progress, {}, None, time.perf_counter()

    def __call__(self, stage: str, fraction: float | None) -> None:
        if fraction is None:
            self.close()
            self.stage, self.start = stage, time.perf_counter()
        self.progress(stage, fraction)

    def close(self) -> None:
        if self.stage is not None:
            self.timings[self.stage] = self.timings.get(self.stage, 0.0) + time.perf_counter() - self.start


def run(scenario: Scenario, progress: Progress = _quiet) -> RunOutput:
    """The engines are built from the scenario's model (the truth, what MuJoCo simulates); the
    graph model from the model under test. Identified parameters are compared with the truth."""
    timed = _Timed(progress)
    out = _run(scenario, timed)
    timed.close()
    return dataclasses.replace(out, timings=timed.timings)


def _run(scenario: Scenario, progress: Progress) -> RunOutput:
    excitation = None
    if scenario.excitation is not None:
        progress("optimising the excitation (Fourier series)", None)
        scenario, excitation = optimise_excitation(scenario, **scenario.excitation)
    progress("simulating in MuJoCo", None)
    recording = simulate(scenario)
    g = scenario.gravity_W
    model = build_graph_model(scenario.tested, g)
    truth = build_graph_model(scenario.robot, g)
    measured = measure(recording, scenario.measurement)
    progress("graph model: unconstrained dynamics", None)
    residual = unconstrained_residual(model, body_series(recording, model.topology))
    progress("identifying parameters", None)
    identification = identify(model, measured, measured_rows(measured, scenario.sample_times),
                              scenario.measurement, truth)
    progress("constraints and Lagrange multipliers", None)
    multipliers = lagrange(scenario, model, recording, progress)
    progress("joint torques: Pinocchio RNEA and graph model", None)
    pinocchio = rnea_on_recording(scenario.robot, g, recording)
    graph_inverse = inverse_dynamics(scenario.tested, model, recording)
    comparison = audit = None
    if scenario.design_comparison is not None:
        dc = scenario.design_comparison
        progress(f"baseline design: simulating {dc.baseline.name}", None)
        comparison = design_claims(scenario.robot, recording, simulate(dc.baseline), list(dc.shared_motor),
                                   dc.baseline_joint)
        comparison["baseline"] = dc.baseline.name
    if scenario.audit == "yahya2012":
        progress("auditing the printed inertia matrix", None)
        audit = audit_inertia_matrix(scenario.robot)
    progress("identifying all 10 inertial parameters per body", None)
    pm_true = build_pinocchio(scenario.robot, g)
    true10 = np.stack([pm_true.model.inertias[pm_true.joint_ids[scenario.robot.joint_names.index(
        scenario.robot.inner_joint(b).name)]].toDynamicParameters() for b in model.topology.bodies])
    full = identify_full(scenario.tested, model, measured, measured_rows(measured, scenario.sample_times),
                         scenario.measurement, true10)
    torque_id = None
    if scenario.torque_validation is not None:
        progress(f"joint-torque identification, validated on {scenario.torque_validation.name}", None)
        pm = build_pinocchio(scenario.tested, g)
        cols = [measured.joint_index(j) for j in scenario.robot.joint_names]
        val = simulate(scenario.torque_validation)
        torque_id = identify_from_torques(
            pm, scenario.robot.joint_names, measured.q[:, cols], measured.qd[:, cols], measured.qdd[:, cols],
            measured.tau[:, cols], (val.q[:, cols], val.qd[:, cols], val.qdd[:, cols], val.tau[:, cols]))
        torque_id.validation_scale = joint_load_scale(scenario.robot, val)
    return RunOutput(scenario, model, recording, measured, residual, identification, multipliers,
                     pinocchio, graph_inverse, comparison, audit, torque_id, full, excitation)
