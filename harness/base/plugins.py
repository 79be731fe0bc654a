"""The doors through which code plugs into the harness: models under test, identification methods
and studies. The paper packages (harness/papers/) use these doors exactly as a user's code does.

A plugin is named in a scenario by `python = "module:attribute"` (the module is looked for beside
the scenario file first, then on the import path) or by `plugin = "name"`, the name of an entry
point that an installed package declares:

    [project.entry-points."harness.models"]          # a model under test
    my_arm = "my_package.model:make"
    [project.entry-points."harness.identification"]  # an identification method
    [project.entry-points."harness.studies"]         # a study: its own stages and report sections

Model under test: the attribute is called with the robot description (a `harness.model.spec.RobotSpec`)
and, if its signature accepts them, keyword arguments `gravity_W` (the scenario's gravity, world
components, m/s^2) and `parameters` (the scenario's table for this model, as a dict). It returns an
object with

    joint_names: sequence of str                 the order of its columns
    inverse_dynamics(q, qd, qdd) -> tau          arrays (N, n), SI units: N m, or N for a prismatic joint

and optionally
    joint_wrenches(q, qd, qdd) -> (F_W, M_W)     (N, n, 3) each: the force of the inner body on the outer
                                                 one and its moment about the joint point, world components
    mass_matrix(q) -> M                          (N, n, n)

A closed chain's model (a model file with loops: harness/model/loops.py) is given every joint's
(q, q', q'') in its `joint_names` order and returns the actuated joints' torques (N, n_a), in the order
of its optional `actuated_joints` (by default the actuated ones in its `joint_names` order): what the
motors must give, the loops' share carried by the passive joints and the loops (G^T tau of the tree).

Identification method: the attribute is called in the same way and returns an object with
`joint_names` and `fit(q, qd, qdd, tau)` (arrays (N, n), measured; and `t`, the (N,) sample times in
s, passed by keyword where the signature names it) returning the identified model: an
object with `joint_names`, `inverse_dynamics` as above and, optionally, `parameters`: (n, 10), one row
per joint in the fitted model's `joint_names` order, the child body's
[m, m c_x, m c_y, m c_z, I_xx, I_xy, I_yy, I_xz, I_yz, I_zz] about the joint point, in world axes at
the initial pose (all q = 0) (Pinocchio's dynamic parameters of a frame at the joint point with
those axes). They are judged where the data determine them: reduced to the robot's structural base
parameters (harness/identify/torque_id.py, structural_base) and compared with the robot's own.
On a measured log (a scenario with `[data]`) the fitted model may also report `friction`: (n, 4), per
joint in its `joint_names` order [armature, viscous, coulomb, offset] (N m s^2/rad, N m s/rad, N m,
N m), and `notes`: a sequence of one-line statements of what the method could not do or assumed
(both shown in the log's method table). A factory that wraps a tool which is not installed raises
ToolUnavailable: the method is skipped, and said to be.
"""

from __future__ import annotations

import functools
import importlib
import inspect
import signal
import sys
import threading
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from importlib.metadata import entry_points
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import numpy as np

from harness.base.tomlio import in_one_line

MODEL_GROUP = "harness.models"
METHOD_GROUP = "harness.identification"
STUDY_GROUP = "harness.studies"


@runtime_checkable
class ModelUnderTest(Protocol):
    joint_names: Sequence[str]

    def inverse_dynamics(self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray: ...


@runtime_checkable
class IdentificationMethod(Protocol):
    joint_names: Sequence[str]

    def fit(self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, tau: np.ndarray) -> ModelUnderTest: ...


class PluginError(Exception):
    """A plugin could not be loaded, or broke its protocol or raised while running. The CLI turns
    it into one line naming the plugin and exit status 2."""

    def __init__(self, plugin: str, message: str):
        super().__init__(f"{plugin}: {message}")
        self.plugin, self.message = plugin, message

    def __reduce__(self):  # from a worker process, with both fields
        return type(self), (self.plugin, self.message)


class PluginRaised(PluginError):
    """The plugin's own code raised an exception (not SystemExit, not KeyboardInterrupt) while it ran:
    bad input like any PluginError, unless the caller can make it a result of its own (an identification
    method on a log whose fit raises becomes its row: harness/stages/log_methods.py)."""


class ToolUnavailable(PluginError):
    """Raised by a method's factory when the tool it wraps is not installed (an optional extra, e.g.
    `pip install 'harness[figaroh]'`). The method is skipped, with this message on the terminal, in
    results.json (`identification_methods.<name>.skipped`) and on each of its gates; the rest of the
    scenario runs and is judged as usual."""


def _exception(exc: BaseException) -> str:
    return in_one_line(f"{type(exc).__name__}: {exc}")


# Set by the harness's own SIGINT and SIGTERM handlers (user_interrupts): a KeyboardInterrupt that
# arrives while it is set is the user's Ctrl-C (exit 130); one that plugin code raises itself is the
# plugin's failure (exit 2), like any other exception it raises.
_USER_INTERRUPT = threading.Event()


def _interrupt(signum, frame):
    if _USER_INTERRUPT.is_set():  # the same interrupt again (the terminal's and a forwarded one): already unwinding
        return
    _USER_INTERRUPT.set()
    raise KeyboardInterrupt


@contextmanager
def user_interrupts() -> Iterator[None]:
    """While the harness runs: Ctrl-C (and SIGTERM, where nothing else handles it) marked as the
    user's, so that `guard` can tell it from a KeyboardInterrupt raised by plugin code. Outside the
    main thread signals cannot be handled, and nothing changes."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    kept = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    signal.signal(signal.SIGINT, _interrupt)
    if kept[signal.SIGTERM] is signal.SIG_DFL:  # unwind on SIGTERM, so that no temporary folder is left
        signal.signal(signal.SIGTERM, _interrupt)
    _USER_INTERRUPT.clear()
    try:
        yield
    finally:
        for s, handler in kept.items():
            signal.signal(s, handler)


def interrupted_by_user() -> bool:
    return _USER_INTERRUPT.is_set()


@contextmanager
def guard(plugin: str, what: str) -> Iterator[None]:
    """Plugin code runs inside this: whatever it raises, SystemExit and KeyboardInterrupt included,
    becomes a PluginError naming the plugin and what it was doing (exit status 2), so that only the
    harness chooses its exit status. The user's own Ctrl-C passes through; so do the harness's own
    PluginError and InputError (a study's configuration refusing a key)."""
    from harness.base.tomlio import InputError

    try:
        yield
    except (PluginError, InputError):
        raise
    except KeyboardInterrupt:
        if interrupted_by_user():
            raise
        raise PluginError(plugin, f"{_doing(what)} KeyboardInterrupt (not the user's Ctrl-C)") from None
    except SystemExit as exc:
        raise PluginError(plugin, f"{_doing(what)} SystemExit: sys.exit({exc.code!r}) (a plugin cannot end "
                                  "the run)") from None
    except Exception as exc:  # a plugin may raise anything
        raise PluginRaised(plugin, f"{_doing(what)} {_exception(exc)}") from None
    except BaseException as exc:
        raise PluginError(plugin, f"{_doing(what)} {_exception(exc)}") from None


def _doing(what: str) -> str:
    """'inverse_dynamics' -> 'inverse_dynamics raised'; 'cannot import module x:' stays as it is."""
    return what if what.endswith(":") else f"{what} raised"


def _import_beside(module: str, folder: Path):
    """Import `module` from `folder` if it is there (a file or a package), else from the path."""
    head = module.split(".")[0]
    local = folder / f"{head}.py"
    package = folder / head / "__init__.py"
    if local.is_file() or package.is_file():
        origin = (local if local.is_file() else package).resolve()
        loaded = sys.modules.get(head)
        if loaded is not None and Path(getattr(loaded, "__file__", "") or "").resolve() != origin:
            for name in [m for m in sys.modules if m == head or m.startswith(head + ".")]:
                del sys.modules[name]  # another folder's module of the same name
        sys.path.insert(0, str(folder))
        try:
            return importlib.import_module(module)
        finally:
            sys.path.remove(str(folder))
    return importlib.import_module(module)


def load_reference(ref: str, folder: Path) -> Any:
    """`module:attribute` (attribute may be dotted) -> the object. Raises PluginError."""
    module, sep, attr = ref.partition(":")
    if not sep or not module or not attr:
        raise PluginError(ref, "expected 'module:attribute'")
    with guard(ref, f"cannot import module {module!r}:"):
        obj = _import_beside(module, folder)
    with guard(ref, f"looking up {attr!r}"):
        for part in attr.split("."):
            if not hasattr(obj, part):
                raise PluginError(ref, f"module {module!r} has no attribute {attr!r}")
            obj = getattr(obj, part)
    return obj


@functools.cache
def _installed(group: str) -> tuple:
    """The entry points of `group` installed, read once per process: importlib.metadata reads every installed
    distribution's metadata at each call (9 ms here, with this project's dependencies), and every scenario
    names its plugins so."""
    return tuple(entry_points(group=group))


def load_entry_point(name: str, group: str) -> Any:
    found = [ep for ep in _installed(group) if ep.name == name]
    if not found:
        known = sorted(ep.name for ep in _installed(group))
        raise PluginError(name, f"no installed plugin of that name in {group!r} (installed: "
                                f"{', '.join(known) or 'none'})")
    with guard(name, f"loading entry point {found[0].value!r}"):
        return found[0].load()


def call_factory(plugin: str, factory: Callable, robot, **options) -> Any:
    """Call a plugin's factory with the robot and those keyword options its signature accepts."""
    if not callable(factory):
        raise PluginError(plugin, "is not callable")
    with guard(plugin, "building it"):
        params = inspect.signature(factory).parameters
        takes_all = any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params.values())
        kwargs = {k: v for k, v in options.items() if takes_all or k in params}
        return factory(robot, **kwargs)


def check_protocol(plugin: str, obj: Any, protocol: type, joint_names: Sequence[str]) -> None:
    """The object has the protocol's members and names exactly the robot's joints."""
    with guard(plugin, "reading its members"):
        missing = [m for m in ("joint_names", *(n for n in protocol.__dict__ if not n.startswith("_")
                                                 and callable(protocol.__dict__[n])))
                   if not hasattr(obj, m)]
        names = None if missing else [str(n) for n in obj.joint_names]
    if missing:
        raise PluginError(plugin, f"the object it returned has no {', '.join(missing)} "
                                  f"(see the {protocol.__name__} protocol in harness/base/plugins.py)")
    if sorted(names) != sorted(joint_names) or len(set(names)) != len(names):
        raise PluginError(plugin, f"joint_names {names} must be the robot's joints {list(joint_names)}, "
                                  "each once, in any order")


def column_maps(plugin_joints: Sequence[str], joints: Sequence[str]) -> tuple[list[int], list[int]]:
    """Index lists between the robot's joint order and a plugin's: x[:, to_plugin] gives a plugin
    its columns, y[:, to_robot] brings its output back to the robot's order."""
    plugin_joints, joints = list(plugin_joints), list(joints)
    return [joints.index(j) for j in plugin_joints], [plugin_joints.index(j) for j in joints]


def invoke(plugin: str, what: str, fn: Callable, *args) -> Any:
    """Call one of a plugin's methods; whatever it raises becomes a PluginError naming it."""
    with guard(plugin, what):
        return fn(*args)


def check_array(plugin: str, what: str, value: Any, shape: tuple[int, ...]) -> np.ndarray:
    """What a plugin returned must be a finite real array of the shape (a complex one is refused, not
    cut to its real part)."""
    try:
        out = np.asarray(value)
        if out.dtype.kind == "c":
            raise PluginError(plugin, f"{what} returned complex numbers ({out.dtype}): real values expected")
        out = np.asarray(out, dtype=float)
    except (TypeError, ValueError) as exc:
        raise PluginError(plugin, f"{what} returned something that is not an array ({_exception(exc)})") from None
    if out.shape != shape:
        raise PluginError(plugin, f"{what} returned shape {out.shape}, expected {shape}")
    if not np.all(np.isfinite(out)):
        raise PluginError(plugin, f"{what} returned values that are not finite")
    return out


def call(plugin: str, what: str, fn: Callable, *args, shape: tuple[int, ...]) -> np.ndarray:
    return check_array(plugin, what, invoke(plugin, what, fn, *args), shape)


def inverse_dynamics(plugin: str, what: str, model, joints: Sequence[str], q: np.ndarray, qd: np.ndarray,
                     qdd: np.ndarray) -> np.ndarray:
    """A model's torques at states (N, n) in the robot's joint order `joints`: the columns given in
    the model's `joint_names` order, its (N, n) answer checked and brought back to the robot's."""
    to_model, back = column_maps(model.joint_names, joints)
    return call(plugin, what, model.inverse_dynamics, q[:, to_model], qd[:, to_model], qdd[:, to_model],
                shape=q.shape)[:, back]


def actuated_torques(plugin: str, what: str, model, joints: Sequence[str], actuated: Sequence[str], q: np.ndarray,
                     qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
    """A closed chain's model (harness/model/closure.py): given every joint's states (N, n) in the
    robot's order `joints`, its answer is the actuated joints' torques (N, n_a), its columns in the
    order of its `actuated_joints` (by default the robot's `actuated` joints in its `joint_names`
    order), brought back to `actuated`'s order."""
    to_model, _ = column_maps(model.joint_names, joints)
    names = list(getattr(model, "actuated_joints", None) or [j for j in model.joint_names if j in actuated])
    if sorted(names) != sorted(actuated):
        raise PluginError(plugin, f"actuated_joints {names} are not the robot's actuated joints {list(actuated)}")
    out = call(plugin, what, model.inverse_dynamics, q[:, to_model], qd[:, to_model], qdd[:, to_model],
               shape=(len(q), len(actuated)))
    return out[:, [names.index(a) for a in actuated]]


@dataclass(frozen=True, eq=False)
class Stage:
    """One step of a run. `run(context, config)` returns a typed result, or None when the stage has
    nothing to do for this scenario; `serialise(result, context, config)` turns it into its part of
    results.json, under `key` (the core's stages pass their result type's own method, e.g.
    `TorqueComparison.serialise`). `render(results, recording)` draws that part of the report, titled
    `title` in the report's navigation. `files(result)`, when given, returns files to write into the
output folder ({relative path: text}, e.g. an exported model). `context` is a harness.stages.Context:
a stage reads its data there and computes; it neither simulates nor reads a file."""

    key: str
    progress: str
    run: Callable[[Any, Any], Any]
    serialise: Callable[[Any, Any, Any], dict]
    title: str = ""
    render: Callable[[dict, Any], str] | None = None
    files: Callable[[Any], dict[str, str]] | None = None  # files it adds beside results.json: {path: text}
    table: str | None = None  # the scenario's table that configures it, as `[studies.NAME]` configures a study
    configure: Callable[[Any, Any], Any] | None = None  # (table, scenario) -> its configuration, validated
    recordings: Callable[[Any, Any], Any] | None = None  # (config, scenario) -> the other scenarios whose bench
    # recordings it reads (a validation trajectory, the same motion without a payload), recorded once by the
    # source before any stage runs (harness.stages.Context.recorded)


@dataclass(frozen=True, eq=False)
class Sweep:
    """What `harness sweep` runs: `run(scenario, trials, workers, progress)` repeats an identification
    under `trials` draws of the scenario's measurement noise on `workers` (a harness.base.workers.Workers),
    reporting to `progress` (a harness.base.progress.Progress), and returns what sweep.json holds;
    `render(sweep)` draws sweep.html; `summary(sweep)` gives the lines printed on the terminal. The
    core's sweep (the joint-torque estimators and the identification methods) and a study's are alike."""

    run: Callable[[Any, int, Any, Any], dict]
    render: Callable[[dict], str]
    summary: Callable[[dict], list[str]]


@dataclass(frozen=True, eq=False)
class Study:
    """A package of stages that a scenario asks for by name (`[studies.NAME]`): `configure(table,
    scenario)` validates the scenario's table (raising harness.base.tomlio.InputError) and returns the
    configuration its stages receive. `sweep`, when given, is what `harness sweep` runs for it."""

    name: str
    configure: Callable[[Any, Any], Any]
    stages: tuple[Stage, ...]
    sweep: Sweep | None = None


def load_study(name: str) -> Study:
    study = load_entry_point(name, STUDY_GROUP)
    if not isinstance(study, Study):
        raise PluginError(name, f"entry point must name a harness.base.plugins.Study, found {type(study).__name__}")
    return study
