"""Scenario: which model, how every joint moves, for how long, what is sampled; scenarios/*.toml.

A scenario names its model by a path relative to the scenario file, prescribes the motion of every
joint of that model (no joint is left implicit; a floating base's in `[base_motion]`), and states the
output grid: `duration` split into `output_steps` equal steps, so the recording has output_steps + 1
rows from t = 0. `sample_times` (the identification instants of the paper, section 3.1) must lie on
that grid, or be "all". `[measurement]` states what the bench reports (harness.sources.measurement).

What is judged is named, never implied: `[model_under_test]` (one table, or `[[model_under_test]]`
for several) names each model under test, `[identification]` each identification method, both
plugins (harness/base/plugins.py); `[studies.NAME]` asks for a study's stages (a paper's, or a user's)
and holds its settings. `[scenario] gate_sets` includes shared gate files; the scenario's own
`[[gates]]` add to them and replace an included gate on the same metric."""

from __future__ import annotations

import copy
import dataclasses
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from harness.base.plugins import (
    METHOD_GROUP,
    MODEL_GROUP,
    IdentificationMethod,
    ModelUnderTest,
    PluginError,
    Study,
    ToolUnavailable,
    call_factory,
    check_protocol,
    guard,
    load_entry_point,
    load_reference,
    load_study,
)
from harness.base.tomlio import InputError, Table, parse_toml, read_toml, read_toml_text
from harness.engines.simulation import INTEGRATORS, Simulation
from harness.model.contacts import read_contacts
from harness.model.load import load_spec
from harness.model.spec import RobotSpec
from harness.runner.gates import Gate, read_gates
from harness.runner.judging import check_names
from harness.sources.base_motion import read_scenario_base_motion, refuse_fixed_base_tables
from harness.sources.log import DataSource, check_columns, read_source
from harness.sources.log.channels import logged, supported
from harness.sources.log.floating import read_floating_log, refuse_on_floating
from harness.sources.measurement import Measurement, read_measurement
from harness.sources.motion import Motion, read_scenario_motions

if TYPE_CHECKING:
    from harness.identify.excitation import Excitation

_GRID_TOL = 1e-9  # relative to the output interval: a sample time on the grid, a timestep dividing it
MAX_OUTPUT_STEPS = 1_000_000  # rows of a recording: about 1 GB for an arm of ten joints
MAX_SIMULATION_STEPS = 20_000_000  # MuJoCo steps of one run, each with a Python drive callback (hours)


@dataclass(frozen=True, eq=False)
class Recipe:
    """How a scenario names a plugin, enough to build it again in another process (a Dask worker)."""

    key: str  # "python" (module:attribute, looked for in `folder` first) or "plugin" (an entry point of `group`)
    ref: str
    folder: Path
    group: str
    gravity_W: np.ndarray
    parameters: dict

    def build(self, robot: RobotSpec) -> Any:
        factory = load_reference(self.ref, self.folder) if self.key == "python" else \
            load_entry_point(self.ref, self.group)
        return call_factory(self.ref, factory, robot, gravity_W=self.gravity_W.copy(), parameters=self.parameters)


@dataclass(frozen=True, eq=False)
class PluginEntry:
    """A model under test or an identification method, as the scenario names it, built."""

    name: str  # names its metrics: torques.<name>_vs_mujoco
    reference: str  # "module:attribute" or the entry point's name
    robot: RobotSpec  # the description it was built from
    instance: Any  # what the factory returned (checked against the protocol)
    validation: Scenario | None = None  # identification methods: the trajectory they are judged on
    recipe: Recipe | None = None  # how to build it again elsewhere; None for an object handed to the API
    skipped: str | None = None  # why it is not run: the tool it wraps is not installed (instance None)

    def rebuilt(self) -> Any:
        """The plugin built again from what the scenario names (in another process), else the instance."""
        return self.instance if self.recipe is None else self.recipe.build(self.robot)


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
    gates: tuple[Gate, ...] = ()
    text: str = ""  # the scenario file as read, for the report
    excitation: Excitation | None = None  # a Fourier-series motion to optimise (harness/identify/excitation.py)
    models: tuple[PluginEntry, ...] = ()  # models under test
    methods: tuple[PluginEntry, ...] = ()  # identification methods under test
    studies: tuple[tuple[Study, Any], ...] = ()  # (study, its configuration), in the file's order
    configs: dict[str, Any] = field(default_factory=dict)  # a core stage's key -> its configuration, from its table
    base_motion: Any = None  # a floating base's [base_motion] (harness/sources/base_motion.py), else None
    contacts: tuple = ()  # the points it stands on, [[contacts]] (harness/model/contacts.py)

    def related(self, t: Table, key: str) -> Scenario:
        """Another scenario this one names under `key` of table `t` (relative to this file)."""
        return load_related(t, key, self.source)

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
        if self.contacts:  # the joints holding a contact follow it as the base moves
            from harness.model.contacts import stance

            return stance(self.robot, self.contacts, self.base_motion.evaluate, self._given, self.source)(t)
        if not self.robot.loops:
            return self._given(t)
        from harness.model.closure import ClosedChain, ClosureError, along  # of a closed chain, the actuated

        try:  # joints' motions are given and the passive joints' follow from the loops
            return along(ClosedChain.of(self.robot), t, self._given)
        except ClosureError as exc:
            raise _unfollowed(self.source, exc) from None

    def _given(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The [motion] tables' (q, q', q''), each (len(t), joints with a motion), in their order."""
        parts = [m.evaluate(t) for m in self.motion.values()]
        return tuple(np.stack([p[k] for p in parts], axis=-1) for k in range(3))


def _relative_file(t: Table, key: str, rel: str, base: Path) -> Path:
    """A file named relative to the scenario file; it must exist."""
    path = Path(os.path.normpath(base.parent / rel))
    if not path.is_file():
        raise t.error(key, f"file {rel!r} not found (looked for {path})")
    return path


START_GATE = Gate("start", "log_identification.start.findings", 0)  # every log scenario's (stages/log_judge.py)
FLOATING_START_GATE = Gate("start", "floating_log.start.findings", 0)  # a floating base's (stages/floating_log.py)
BUILTIN_GATES = "harness:"  # a gate set named "harness:NAME" is the package's scenarios/gates/NAME.toml


def _gate_set_files(s: Table, path: Path) -> list[Path]:
    """`[scenario] gate_sets`: files relative to the scenario, or built-in sets by name ("harness:engines")."""
    from harness.base.builtin import DATA

    out = []
    for rel in s.strings("gate_sets", choices=None) if s.has("gate_sets") else ():
        if not rel.startswith(BUILTIN_GATES):
            out.append(_relative_file(s, "gate_sets", rel, path))
            continue
        folder = DATA / "scenarios" / "gates"
        found = folder / f"{rel.removeprefix(BUILTIN_GATES)}.toml"
        if not found.is_file():
            names = ", ".join(f'"{BUILTIN_GATES}{f.stem}"' for f in sorted(folder.glob("*.toml")))
            raise s.error("gate_sets", f"no built-in gate set {rel!r} (there are {names})")
        out.append(found)
    return out


_LOADING: list[Path] = []  # the scenarios being loaded, outermost first: a cycle is refused


def load_related(t: Table, key: str, path: Path) -> Scenario:
    """Another scenario that the scenario at `path` names under `key` of table `t`, relative to
    it (a validation trajectory, a baseline design)."""
    other = _relative_file(t, key, t.string(key), path)
    if other.resolve() in _LOADING:
        chain = " -> ".join(p.name for p in (*_LOADING, other.resolve()))
        raise t.error(key, f"scenarios name each other in a cycle ({chain})")
    return load_scenario(other)


def load_variant(t: Table, key: str, scenario: Scenario) -> RobotSpec:
    """Another description of the scenario's robot (same bodies and joints, other parameters),
    named under `key` of table `t` relative to the scenario file; the robot itself without it."""
    if not t.has(key):
        return scenario.robot
    variant = load_spec(_relative_file(t, key, t.string(key), scenario.source))
    if (variant.joint_names != scenario.robot.joint_names
            or [b.name for b in variant.bodies] != [b.name for b in scenario.robot.bodies]):
        raise t.error(key, f"model {variant.name!r} must have the bodies and joints of {scenario.robot.name!r} "
                           "(it describes the same robot)")
    return variant


def load_scenario(path: Path | str) -> Scenario | DataScenario:
    """Load and validate a scenario, its model and its plugins; raises `InputError` naming the
    file and key (a plugin that cannot be imported or built is named in the message)."""
    path = Path(path)
    _LOADING.append(path.resolve())
    try:
        text = read_toml_text(path)
        return _load(parse_toml(text, path), path, text)
    finally:
        _LOADING.pop()


def scenario_from_dict(data: dict, name: str = "scenario", folder: Path | str = ".") -> Scenario | DataScenario:
    """A scenario given as a dict with the layout of a scenario file, validated the same way; the
    files it names (model, gate sets, plugins' modules) are relative to `folder`, and errors name
    `folder/NAME.toml` (which need not exist)."""
    import tomli_w

    if not isinstance(data, dict):
        raise InputError(name, "", f"a scenario is a dict of tables, got {type(data).__name__}")
    path = Path(folder).resolve() / f"{name}.toml"
    try:
        text = tomli_w.dumps(data)
    except (TypeError, ValueError) as exc:
        raise InputError(path, "", f"not a scenario's layout ({exc})") from None
    return _load(copy.deepcopy(data), path, text)


@dataclass(frozen=True, eq=False)
class DataScenario:
    """A scenario whose data come from a measured log (`[data]`, harness/sources/log/) instead of the bench."""

    name: str
    description: str
    source: Path
    robot: RobotSpec
    gravity_W: np.ndarray
    data: DataSource
    gates: tuple[Gate, ...]
    text: str = ""
    models: tuple[PluginEntry, ...] = ()  # never filled: a log is judged by identification
    methods: tuple[PluginEntry, ...] = ()
    studies: tuple[tuple[Study, Any], ...] = ()
    truth: RobotSpec | None = None  # the model that made the log, where it is known (a bench log)
    configs: dict[str, Any] = field(default_factory=dict)  # a log stage's key -> its configuration, from its table


def _configured(root: Table, scenario, stages):
    """The scenario with each stage's own table read by that stage (`Stage.table`, `configure`), as a
    study reads its own; in order, so that a stage's configuration may read those before it."""
    for stage in stages:
        if stage.table is not None and root.has(stage.table):
            table = root.table(stage.table)
            config = stage.configure(table, scenario)
            table.finish()
            scenario = dataclasses.replace(scenario, configs={**scenario.configs, stage.key: config})
    return scenario


def _load_data(root: Table, path: Path, text: str) -> DataScenario:
    s = root.table("scenario")
    description = s.string("description", default="")
    model_rel = s.string("model")
    gravity = s.vector("gravity") if s.has("gravity") else None  # default: the model's, else standard gravity
    gate_files = _gate_set_files(s, path)
    s.finish()
    robot = load_spec(_relative_file(s, "model", model_rel, path))
    if not robot.joints:
        raise s.error("model", f"model {robot.name!r} has no moving joint: nothing to simulate or identify")
    gravity = _gravity(gravity, robot)
    dt = root.table("data")
    read_as = logged(robot)  # a closed chain's log holds its actuated joints' channels (sources/log/closed.py)
    floating = read_floating_log(dt, robot)  # a floating base's channels (sources/log/floating.py)
    source = read_source(dt, path, len(read_as.joints), read_as.joint_names, list(robot.drive_names))
    if floating is not None:
        source = dataclasses.replace(source, floating=refuse_on_floating(dt, source, root, floating))
    source = supported(root, dt, robot, source)  # what a closed chain's log, or unmeasured channels, do not allow
    if source.side == "motor" and robot.transmission is None:
        raise dt.error("side", f'"motor": the log is mapped to the joints through the model\'s drives, and '
                               f"{robot.source} states none ([drives])")
    if source.side == "motor" and source.identify_constants and not robot.transmission.diagonal:
        raise dt.error("payload" if source.payload is not None else "identify_torque_constants",
                       "the torque constants are identified joint by joint, and a coupled motor "
                       f"({', '.join(robot.transmission.motors[k] for k, _ in robot.transmission.coupled)}) "
                       "drives more than one joint: give each motor's torque_constant")
    check_columns(source, read_as, dt)
    if source.payload is not None and source.payload.body not in {b.name for b in robot.massive_bodies}:
        raise dt.error("payload.body", f"no body {source.payload.body!r} with mass in {robot.name!r}")
    truth = None
    if source.truth is not None:
        truth = load_spec(source.truth)
        if truth.joint_names != robot.joint_names:
            raise dt.error("truth", f"model {truth.name!r} has other joints than {robot.name!r}")
        if (truth.actuated, [lp.name for lp in truth.loops]) != (robot.actuated, [lp.name for lp in robot.loops]):
            raise dt.error("truth", f"model {truth.name!r} has other loops or actuated joints than {robot.name!r}")
    gates = _read_all_gates(root, gate_files)
    start = START_GATE if floating is None else FLOATING_START_GATE
    if start.metric not in {g.metric for g in gates}:  # every log is read against its model: a scenario's own
        gates += (start,)  # gate on the metric replaces it
    for table in ("motion", "simulation", "measurement", "model_under_test", "studies", "torque_identification",
                  "excitation"):
        if root.has(table):
            raise root.error(table, "a scenario with [data] is judged on its log: it has no simulated motion, "
                                    "measurement, studies or models under test")
    scenario = DataScenario(path.stem, description, path, robot, np.asarray(gravity), source, gates, text,
                            truth=truth)
    methods = []
    for t in (root.one_or_many("identification") if root.has("identification") else ()):
        if t.has("validation"):
            raise t.error("validation", "a method on a log is judged on the log's validation span ([data] validation)")
        methods.append(_read_plugin(t, path, scenario, METHOD_GROUP, IdentificationMethod))
    check_names(path, "identification", methods, gates, on_log=True)
    if methods and source.units["tau"] == "current" and source.identify_constants:
        raise root.error("identification", "the methods are given joint torques, and this log's currents become "
                                           "torques only in the harness's own fit (identify_torque_constants)")
    from harness.stages import log_stages

    scenario = _configured(root, dataclasses.replace(scenario, methods=tuple(methods)), log_stages())
    root.finish()
    return scenario


def _load(data: dict, path: Path, text: str) -> Scenario | DataScenario:
    root = Table(data, path)
    if root.has("data"):
        return _load_data(root, path, text)
    s = root.table("scenario")
    description = s.string("description", default="")
    model_rel = s.string("model")
    if s.has("model_under_test"):
        raise s.error("model_under_test", "a model under test is a table of its own: [model_under_test] with "
                                          "name, python (or plugin) and model (see README, 'Plugging in')")
    gravity = s.vector("gravity") if s.has("gravity") else None  # default: the model's, else standard gravity
    duration = s.number("duration", positive=True)
    output_steps = s.integer("output_steps", minimum=1)
    if output_steps > MAX_OUTPUT_STEPS:
        raise s.error("output_steps", f"{output_steps} rows cannot be held: at most {MAX_OUTPUT_STEPS:,} (split the "
                                      "run, or record less often)")
    output_dt = duration / output_steps
    if s.data.get("sample_times") == "all":
        s.string("sample_times")
        sample_times = np.arange(output_steps + 1) * output_dt
    else:
        sample_times = s.vector("sample_times", length=None, default=[])
    gate_files = _gate_set_files(s, path)
    s.finish()

    robot = load_spec(_relative_file(s, "model", model_rel, path))
    if not robot.joints:
        raise s.error("model", f"model {robot.name!r} has no moving joint: nothing to simulate or identify")
    gravity = _gravity(gravity, robot)
    for table in CLOSED_CHAIN_LATER if robot.loops else ():  # they read an open tree
        if root.has(table):
            raise root.error(table, f"model {robot.name!r} is a closed chain (loop {robot.loops[0].name!r}): "
                                    f"[{table}] is not supported on closed chains (docs/closed_chains.md)")
    refuse_fixed_base_tables(root)
    simulation = _read_simulation(root.table("simulation", default={}))
    measurement = read_measurement(root.table("measurement", default={}))
    gates = _read_all_gates(root, gate_files)
    excitation = None
    if root.has("excitation"):
        from harness.identify.excitation import read_excitation  # loads the engines: only when asked

        et = root.table("excitation")
        excitation = read_excitation(et)
        et.finish()
        if root.has("motion"):
            raise root.error("motion", "a scenario with [excitation] gets its motion from the optimisation: "
                                       "leave [motion] out")
        root.data["motion"] = {j: {"type": "locked"} for j in robot.joint_names}  # replaced when run
    motion = read_scenario_motions(root.table("motion"), robot, duration, output_steps)
    _check_grid(path, s, sample_times, duration, output_steps, measurement, simulation)
    scenario = Scenario(path.stem, description, path, robot, gravity, duration, output_steps,
                        np.asarray(sample_times), motion, simulation, measurement, gates, text, excitation)
    if robot.loops:  # the loops followed along the motion now: a singular or unreachable motion is bad input
        scenario = _charted(scenario)
        robot = scenario.robot  # its passive balls' charts turned to the motion, for every table read after
        scenario.prescribed(np.linspace(0.0, duration, output_steps + 1))
    models = tuple(_read_plugin(t, path, scenario, MODEL_GROUP, ModelUnderTest)
                   for t in (root.one_or_many("model_under_test") if root.has("model_under_test") else ()))
    methods = tuple(_read_plugin(t, path, scenario, METHOD_GROUP, IdentificationMethod)
                    for t in (root.one_or_many("identification") if root.has("identification") else ()))
    for kind, entries in (("model_under_test", models), ("identification", methods)):
        check_names(path, kind, entries, gates)
    from harness.stages import LOG_TABLES, core_stages

    scenario = _configured(root, scenario, core_stages())
    for table in LOG_TABLES:  # a log's stage's table in a simulated scenario: said, not "unknown key"
        if root.has(table):
            raise root.error(table, "a table of a run on a measured log: the scenario needs [data]")
    studies = _read_studies(root, scenario, path)
    base_motion = read_scenario_base_motion(root, robot, models, scenario.configs)
    contacts = read_contacts(root, robot, motion, scenario.t_out)
    root.finish()
    scenario = dataclasses.replace(scenario, models=models, methods=methods, studies=tuple(studies),
                                   base_motion=base_motion, contacts=contacts)
    if contacts:  # the stance followed along the motion now: a point out of reach is bad input
        scenario.prescribed(scenario.t_out)
    return scenario


def _charted(scenario: Scenario) -> Scenario:
    """The closed chain's passive ball joints in charts that keep the motion (its output rows, from q = 0)
    away from their locks (harness/model/charts.py); the scenario itself where the file's charts do."""
    from harness.model.charts import fitted
    from harness.model.closure import ClosedChain, ClosureError

    chain = ClosedChain.of(scenario.robot)
    q_a = scenario._given(np.concatenate([[0.0], scenario.t_out]))[0]
    try:
        turned = fitted(chain, q_a).spec
    except ClosureError as exc:
        raise _unfollowed(scenario.source, exc) from None
    return scenario if turned is chain.spec else dataclasses.replace(scenario, robot=turned)


def _unfollowed(source: Path, exc: Exception) -> InputError:
    """A closed chain's motion its loops cannot follow (closure.ClosureError), as the scenario's bad input."""
    return InputError(source, "motion", f"the motion of the actuated joints cannot be followed: {exc}")


# a closed chain's scenario judges its actuated torques, its loops and its joint-torque identification
# (through G^T Y); these tables read an open tree
CLOSED_CHAIN_LATER = ("excitation", "identification", "studies", "estimators", "payload")


def _check_grid(path: Path, s: Table, sample_times, duration: float, output_steps: int, measurement: Measurement,
                simulation: Simulation) -> None:
    """The sample times on the output grid and measured; the measurement's filter within the rows;
    the simulation's timestep dividing the output interval, and its steps within reach."""
    output_dt = duration / output_steps
    for ts in sample_times:
        if not 0.0 <= ts <= duration:
            raise s.error("sample_times", f"sample time {ts:g} s is outside the run [0, {duration:g}] s")
        if abs(ts / output_dt - round(ts / output_dt)) > _GRID_TOL:
            raise s.error("sample_times", f"sample time {ts:g} s is not on the output grid "
                                          f"(every {output_dt:g} s)")
    measured_rows = output_steps // measurement.every + 1
    if measurement.differentiate and measurement.filter_window > measured_rows:
        raise InputError(path, "measurement.filter_window", f"{measurement.filter_window} samples, but the "
                                                            f"measurement has only {measured_rows} rows")
    if measurement.every > 1:
        for ts in sample_times:
            k = round(ts / output_dt)
            if k % measurement.every:
                raise s.error("sample_times", f"sample time {ts:g} s is not measured (measurement.every = "
                                              f"{measurement.every} keeps every {measurement.every}th output step)")
    steps = duration / simulation.timestep
    if not np.isfinite(steps) or steps > MAX_SIMULATION_STEPS:
        raise InputError(path, "simulation.timestep", f"{duration:g} s in steps of {simulation.timestep:g} s is "
                                                      f"{steps:.3g} steps: at most {MAX_SIMULATION_STEPS:,}")
    ratio = output_dt / simulation.timestep
    if ratio < 1.0 - _GRID_TOL or abs(ratio - round(ratio)) > _GRID_TOL * ratio:
        raise InputError(path, "simulation.timestep",
                         f"{simulation.timestep:g} s must divide the output interval {output_dt:g} s")


def _read_studies(root: Table, scenario: Scenario, path: Path) -> list:
    """`[studies.NAME]`: each study (a paper's by name, or `python = "module:attribute"`) with the
    configuration its own `configure` reads from its table."""
    studies = []
    if root.has("studies"):
        st = root.table("studies")
        for name in list(st.data):
            table = st.table(name)
            ref = table.string("python", default=None) if table.has("python") else None
            try:
                study = load_reference(ref, path.parent) if ref else load_study(name)
            except PluginError as exc:
                raise table.error("python" if ref else "", exc.message if ref else str(exc)) from None
            if not isinstance(study, Study):
                raise table.error("python", f"{ref!r} must be a harness.base.plugins.Study")
            with guard(f"study {name}", "configure"):
                studies.append((study, study.configure(table, scenario)))
            table.finish()
        st.finish()
    return studies


def _read_all_gates(root: Table, gate_files: list[Path]) -> tuple[Gate, ...]:
    """The included gate sets, then the scenario's own gates, which replace an included gate on the
    same metric. A scenario must declare at least one gate."""
    included: list[Gate] = []
    for f in gate_files:
        t = Table(read_toml(f), f)
        head = t.table("gate_set")
        head.string("description", default="")
        head.finish()
        included += read_gates(t.tables("gates"))
        t.finish()
    own = read_gates(root.tables("gates")) if root.has("gates") else ()
    mine = {g.metric for g in own}
    gates = tuple(g for g in included if g.metric not in mine) + tuple(own)
    if not gates:
        raise root.error("gates", "the scenario declares no gates: add [[gates]] or [scenario] gate_sets "
                                  "(a run with nothing to check cannot pass)")
    return gates


STANDARD_GRAVITY_W = (0.0, 0.0, -9.80665)


def _gravity(given: list | None, robot: RobotSpec) -> np.ndarray:
    """The scenario's `gravity`, else the model's (an MJCF file's <option gravity>), else standard
    gravity along -z (m/s^2, world components)."""
    if given is not None:
        return np.asarray(given, dtype=float)
    return np.asarray(robot.gravity_W if robot.gravity_W is not None else STANDARD_GRAVITY_W, dtype=float)


def _read_plugin(t: Table, path: Path, scenario: Scenario, group: str, protocol: type) -> PluginEntry:
    """[model_under_test] / [identification]: name; python = "module:attribute" or plugin = entry
    point name; model = a robot description file to build it from (default: the scenario's robot);
    validation = another scenario (identification methods); further keys: the factory's `parameters`."""
    name = t.string("name")
    if not name.isidentifier():
        raise t.error("name", f"{name!r} must be a plain identifier (letters, digits, _): it names metrics")
    if t.has("python") == t.has("plugin"):
        raise t.error("python", "give exactly one of python = \"module:attribute\" or plugin = \"name\"")
    key = "python" if t.has("python") else "plugin"
    ref = t.string(key)
    robot = load_variant(t, "model", scenario)
    validation = load_related(t, "validation", path) if t.has("validation") else None
    if validation is not None and validation.robot.joint_names != scenario.robot.joint_names:
        raise t.error("validation", "simulates another robot")
    parameters = t.remaining(exclude=("python", "plugin"))
    recipe = Recipe(key, ref, path.parent, group, scenario.gravity_W.copy(), parameters)
    try:
        instance = recipe.build(robot)
        check_protocol(ref, instance, protocol, robot.joint_names)
    except ToolUnavailable as exc:
        if group != METHOD_GROUP:  # a model under test is the thing judged: it cannot be left out
            raise t.error(key, f"plugin {exc}") from None
        t.finish()
        return PluginEntry(name, ref, robot, None, validation, recipe, skipped=exc.message)
    except PluginError as exc:
        raise t.error(key, f"plugin {exc}") from None
    t.finish()
    return PluginEntry(name, ref, robot, instance, validation, recipe)


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
