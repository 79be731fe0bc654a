"""Scenario: which model, how every joint moves, for how long, what is sampled; scenarios/*.toml.

A scenario names its model by a path relative to the scenario file, prescribes the motion of
every joint of that model (no joint is left implicit), and states the output grid: `duration`
split into `output_steps` equal steps, so the recording has output_steps + 1 rows from t = 0.
`sample_times` (the identification instants of the paper, section 3.1) must lie on that grid, or
be "all" for every output step. `[measurement]` states what the test bench reports
(harness.measurement); `[identification]` may name the paper's tables to compare with.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from importlib.resources import files
from pathlib import Path

import numpy as np

from harness.gates import Gate, read_gates
from harness.measurement import Measurement, read_measurement
from harness.motion import Motion, read_motion
from harness.spec import RobotSpec, load_spec
from harness.tomlio import InputError, Table, read_toml

INTEGRATORS = ("RK4", "Euler", "implicitfast")
_GRID_TOL = 1e-9  # relative to the output interval: a sample time on the grid, a timestep dividing it


@dataclass(frozen=True)
class Simulation:
    """How the reference engine integrates the motion.

    The joints are driven by computed torque (inverse dynamics of the prescribed acceleration)
    with a critically damped correction of bandwidth `tracking_bandwidth` rad/s on the tracking
    error: q''_cmd = q''_d + 2 w (q'_d - q') + w^2 (q_d - q).
    """

    integrator: str = "RK4"
    timestep: float = 5e-4
    tracking_bandwidth: float = 20.0


@dataclass(frozen=True)
class Lagrange:
    """Section 3.2 settings: the time at which the multipliers are reported (None: not reported),
    the paper's values to set beside them, and whether to integrate the constrained model."""

    time: float | None = None
    paper_lambda: str | None = None
    forward_simulation: bool = False


@dataclass(frozen=True, eq=False)
class DesignComparison:
    """Another design on the same path, and the joints that share one motor in this design."""

    baseline: Scenario
    shared_motor: tuple[str, ...]
    baseline_joint: str


@dataclass(frozen=True, eq=False)
class Scenario:
    name: str
    description: str
    source: Path
    robot: RobotSpec
    gravity_W: np.ndarray  # (3,) m/s^2, world components
    duration: float
    output_steps: int
    sample_times: np.ndarray
    motion: dict[str, Motion]  # in the robot's joint order
    simulation: Simulation
    measurement: Measurement = field(default_factory=Measurement)
    paper_identified: str | None = None  # reference CSV (harness/reference) of identified values
    paper_abs_error: str | None = None  # reference CSV of the paper's absolute errors
    lagrange: Lagrange = field(default_factory=lambda: Lagrange())
    gates: tuple[Gate, ...] = ()
    model_under_test: RobotSpec | None = None  # the model checked against the engines; default: robot
    text: str = ""  # the scenario file as read, for the report
    design_comparison: DesignComparison | None = None
    audit: str | None = None  # a paper's printed inertia matrix to audit ("yahya2012")
    torque_validation: Scenario | None = None  # joint-torque identification, validated on this scenario
    excitation: dict | None = None  # Fourier-series excitation to optimise (harness/excitation.py)

    @property
    def tested(self) -> RobotSpec:
        """The model under test: the graph model is built from it, the engines from `robot`."""
        return self.model_under_test or self.robot

    @property
    def output_dt(self) -> float:
        return self.duration / self.output_steps

    @property
    def t_out(self) -> np.ndarray:
        return np.linspace(0.0, self.duration, self.output_steps + 1)

    @property
    def substeps(self) -> int:
        """Simulation steps per output step."""
        return round(self.output_dt / self.simulation.timestep)

    def prescribed(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Prescribed (q, q', q''), each of shape (len(t), n_joints), robot joint order."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        parts = [m.evaluate(t) for m in self.motion.values()]
        return tuple(np.stack([p[k] for p in parts], axis=-1) for k in range(3))


def load_scenario(path: Path | str) -> Scenario:
    """Load and validate a scenario and its model; raises `InputError` naming the file and key."""
    path = Path(path)
    root = Table(read_toml(path), path)
    s = root.table("scenario")
    description = s.string("description", default="")
    model_rel = s.string("model")
    tested_rel = s.string("model_under_test", default=None) if s.has("model_under_test") else None
    gravity = s.vector("gravity", default=[0.0, 0.0, -9.80665])
    duration = s.number("duration", positive=True)
    output_steps = s.integer("output_steps", minimum=1)
    output_dt = duration / output_steps
    if s.data.get("sample_times") == "all":
        s.string("sample_times")
        sample_times = np.arange(output_steps + 1) * output_dt
    else:
        sample_times = s.vector("sample_times", length=None, default=[])
    s.finish()

    model_path = Path(os.path.normpath(path.parent / model_rel))
    if not model_path.is_file():
        raise s.error("model", f"model file {model_rel!r} not found (looked for {model_path})")
    robot = load_spec(model_path)
    tested = None
    if tested_rel is not None:
        tested_path = Path(os.path.normpath(path.parent / tested_rel))
        if not tested_path.is_file():
            raise s.error("model_under_test", f"model file {tested_rel!r} not found (looked for {tested_path})")
        tested = load_spec(tested_path)
        if (tested.joint_names != robot.joint_names
                or [b.name for b in tested.bodies] != [b.name for b in robot.bodies]):
            raise s.error("model_under_test", f"model {tested.name!r} must have the bodies and joints of "
                                              f"{robot.name!r} (it describes the same robot)")

    simulation = _read_simulation(root.table("simulation", default={}))
    measurement = read_measurement(root.table("measurement", default={}))
    paper_identified, paper_abs_error = _read_identification(root.table("identification", default={}))
    lagrange = _read_lagrange(root.table("lagrange", default={}), duration, output_steps)
    gates = read_gates(root.tables("gates")) if root.has("gates") else ()
    comparison = (_read_comparison(root.table("design_comparison"), path, robot)
                  if root.has("design_comparison") else None)
    torque_validation = None
    if root.has("torque_identification"):
        ti = root.table("torque_identification")
        rel = ti.string("validation")
        vpath = Path(os.path.normpath(path.parent / rel))
        if not vpath.is_file() or vpath.resolve() == path.resolve():
            raise ti.error("validation", f"{rel!r} must be another scenario file (looked for {vpath})")
        torque_validation = load_scenario(vpath)
        if torque_validation.robot.joint_names != robot.joint_names:
            raise ti.error("validation", f"{rel!r} simulates another robot than {robot.name!r}")
        ti.finish()
    audit = None
    if root.has("audit"):
        at = root.table("audit")
        audit = at.string("inertia_matrix", choices=("yahya2012",))
        at.finish()
    excitation = None
    if root.has("excitation"):
        et = root.table("excitation")
        excitation = {"harmonics": et.integer("harmonics", default=2, minimum=1),
                      "base_frequency": et.number("base_frequency", positive=True),
                      "evaluations": et.integer("evaluations", default=400, minimum=10),
                      "seed": et.integer("seed", default=0, minimum=0)}
        et.finish()
        if root.has("motion"):
            raise root.error("motion", "a scenario with [excitation] gets its motion from the optimisation: "
                                       "leave [motion] out")
        root.data["motion"] = {j: {"type": "locked"} for j in robot.joint_names}  # replaced when run
    motion_table = root.table("motion")
    motion = {}
    for name in motion_table.data:
        if name not in robot.joint_names:
            raise motion_table.error(name, f"joint {name!r} is not in model {robot.name!r} "
                                           f"(joints: {', '.join(robot.joint_names)})")
    for j in robot.joint_names:
        if j not in motion_table.data:
            raise motion_table.error(j, f"missing: every joint of model {robot.name!r} needs a "
                                        "motion (use type = \"locked\" to hold it)")
        motion[j] = read_motion(motion_table.table(j))
    motion_table.finish()
    root.finish()

    for ts in sample_times:
        if not 0.0 <= ts <= duration:
            raise s.error("sample_times", f"sample time {ts:g} s is outside the run [0, {duration:g}] s")
        if abs(ts / output_dt - round(ts / output_dt)) > _GRID_TOL:
            raise s.error("sample_times", f"sample time {ts:g} s is not on the output grid "
                                          f"(every {output_dt:g} s)")
    if measurement.every > 1:
        for ts in sample_times:
            k = round(ts / output_dt)
            if k % measurement.every:
                raise s.error("sample_times", f"sample time {ts:g} s is not measured (measurement.every = "
                                              f"{measurement.every} keeps every {measurement.every}th output step)")
    ratio = output_dt / simulation.timestep
    if ratio < 1.0 - _GRID_TOL or abs(ratio - round(ratio)) > _GRID_TOL * ratio:
        raise InputError(path, "simulation.timestep",
                         f"{simulation.timestep:g} s must divide the output interval {output_dt:g} s")
    return Scenario(path.stem, description, path, robot, gravity, duration, output_steps,
                    np.asarray(sample_times), motion, simulation, measurement, paper_identified,
                    paper_abs_error, lagrange, gates, tested, path.read_text(), comparison, audit,
                    torque_validation, excitation)


def _reference(t: Table, key: str) -> str | None:
    name = t.string(key, default=None) if t.has(key) else None
    if name is not None and not files("harness").joinpath("reference", name).is_file():
        raise t.error(key, f"no reference table {name!r} in harness/reference")
    return name


def _read_identification(t: Table) -> tuple[str | None, str | None]:
    names = _reference(t, "paper_identified"), _reference(t, "paper_abs_error")
    t.finish()
    return names


def _read_lagrange(t: Table, duration: float, output_steps: int) -> Lagrange:
    time = t.number("time", default=None, nonnegative=True) if t.has("time") else None
    output_dt = duration / output_steps
    if time is not None and (time > duration or abs(time / output_dt - round(time / output_dt)) > _GRID_TOL):
        raise t.error("time", f"{time:g} s is not an output step of the run (every {output_dt:g} s "
                              f"up to {duration:g} s)")
    out = Lagrange(time, _reference(t, "paper_lambda"), t.boolean("forward_simulation", default=False))
    t.finish()
    return out


def _read_simulation(t: Table) -> Simulation:
    default = Simulation()
    sim = Simulation(
        integrator=t.string("integrator", default=default.integrator, choices=INTEGRATORS),
        timestep=t.number("timestep", default=default.timestep, positive=True),
        tracking_bandwidth=t.number("tracking_bandwidth", default=default.tracking_bandwidth,
                                    nonnegative=True),
    )
    t.finish()
    return sim


def _read_comparison(t: Table, path: Path, robot: RobotSpec) -> DesignComparison:
    rel = t.string("baseline")
    base_path = Path(os.path.normpath(path.parent / rel))
    if not base_path.is_file():
        raise t.error("baseline", f"scenario file {rel!r} not found (looked for {base_path})")
    if base_path.resolve() == path.resolve():
        raise t.error("baseline", "a scenario cannot be its own baseline")
    baseline = load_scenario(base_path)
    if baseline.robot.joint_names != robot.joint_names:
        raise t.error("baseline", f"{rel!r} has other joints than {robot.name!r}")
    shared = t.strings("shared_motor", choices=tuple(robot.joint_names))
    joint = t.string("shared_motor_baseline_joint", choices=tuple(robot.joint_names))
    t.finish()
    return DesignComparison(baseline, shared, joint)
