"""`harness audit`: a collection of robot descriptions read as the harness reads them, and each read
model checked against readers and engines that share none of its code.

Per robot (a URDF, an MJCF file, a model file (.toml) around one, or a robot of example-robot-data by
name):
- read or refused: the harness's own reader (harness/model/load.py), and the one line why;
- degrees of freedom, and whether the root was fixed (a URDF's root link is the ground; an MJCF
  file's free joint is fixed to the world, said so);
- joint torques (RNEA) and the mass matrix (CRBA) of the harness's model against Pinocchio's own
  parser of the same file (harness/engines/pinocchio_file.py: `buildModelFromUrdf` /
  `buildModelFromMJCF`, given an MJCF file with what it cannot read made readable, each said), at
  STATES random states within the joint limits (q' within +-2 rad/s or m/s, q'' within +-5), rigid
  bodies only (the drives' friction and rotor inertia are compared by the scenarios, not here); and
  against MuJoCo's inverse dynamics (mj_inverse) of the model the harness builds for it;
- MuJoCo's own reading of the file: an MJCF file compiled by MuJoCo (`file_inverse_dynamics`: its loops
  and contacts off, a free joint held at the file's pose); a URDF converted by MuJoCo's compiler (visual
  and collision geometry and <mimic> left out) and read back as the harness reads an MJCF file, the
  torques of the two readings at the same states. MuJoCo's converted model is read from memory: its XML
  writer keeps six digits, which would bound the parity at 1e-6;
- physical validity of every moving body: mass > 0, principal moments > 0, triangle inequality;
- the structural base-parameter count (harness/identify/torque_id.py) beside the rank of Pinocchio's
  own joint-torque regressor, of the model its parser builds, stacked over RANK_STATES random states;
- with drives or joint friction in the model file (`[drives]`, `[joints.NAME]`, a URDF's <dynamics>):
  the torques with them, MuJoCo's inverse dynamics of the bench's model (rotor inertia and viscous
  friction on each joint, or on each motor's tendon through N) plus the dry terms the bench applies,
  against Pinocchio's RNEA with the drives' law, at the same states.
A model file that fixes joints of its URDF (`fixed`) is not compared with Pinocchio's parse of the URDF,
in which they move (said in its notes).

Errors are relative to each joint's largest |torque| over the states (the mass matrix: to its largest
entry over the states). The verdicts: `agrees`, every figure within TOLERANCE and the two base counts
equal; `disagrees`, the dynamics differ; `not compared`, a reference parser cannot represent the file
(Pinocchio's refuses it or builds other joints; MuJoCo's URDF import drops what the file holds: the
reason says which and why), the other readings compared and agreeing (a URDF MuJoCo's import refuses
is said in its column: Pinocchio's parser is a URDF's reference); `refused`, the
harness's own reader refuses the file. `harness audit` exits 1 when one that was read disagrees, and 2
when a robot it was given by name or file is refused.
"""

from __future__ import annotations

import time
import xml.etree.ElementTree as ET
from dataclasses import asdict, dataclass, field
from importlib.metadata import PackageNotFoundError, distribution
from pathlib import Path

import numpy as np

from harness.base.numerics import largest_relative_difference as _largest  # each joint over its largest
from harness.base.tomlio import InputError, in_one_line
from harness.model.inertia import not_rigid
from harness.model.spec import RobotSpec
from harness.runner.audit_pinocchio import PinocchioParse, massive_ranks, rank

STATES = 100
RANK_STATES = 300
TOLERANCE = 1e-9  # engines that agree on a model agree to about 1e-13: beyond 1e-9 something reads it differently
# the identification column's bar on the held-out span: the log's accelerations are central differences
# of its velocities at BENCH_RATE, which alone leave the exact model (the model as given) 1e-7 to 1.3e-5 off
IDENTIFY_TOLERANCE = 1e-4
GRAVITY_W = np.array([0.0, 0.0, -9.80665])


@dataclass
class AuditRow:
    """One robot's audit; the figures are None where they could not be computed (`notes` says why)."""

    robot: str
    file: str
    verdict: str  # "agrees", "disagrees", "not compared" (a reference parser cannot represent the file) or "refused"
    reason: str = ""  # why refused, what disagrees, and which reference could not compare and why
    dof: int | None = None
    root: str | None = None  # "fixed" or "floating (fixed to the world)"
    torques_vs_pinocchio: float | None = None
    mass_matrix_vs_pinocchio: float | None = None
    torques_vs_mujoco: float | None = None
    torques_vs_mujoco_file: float | None = None  # an MJCF file: against MuJoCo's own model of it
    mjcf: str | None = None  # "read", or why MuJoCo's conversion or its reading failed
    torques_urdf_vs_mjcf: float | None = None
    drives_vs_pinocchio: float | None = None  # torques with the drives' law, MuJoCo's bench against Pinocchio
    floating: dict | None = None  # a floating base's figures, free (harness/runner/audit_floating.py)
    couplings: int = 0  # joint couplings (a URDF's <mimic>, an MJCF joint equality): followers, no dof of their own
    couplings_vs_pinocchio: float | None = None  # G^T tau and G^T M G against Pinocchio's mimic joints
    bodies: int | None = None
    invalid_bodies: list[str] = field(default_factory=list)
    base_parameters: int | None = None
    pinocchio_regressor_rank: int | None = None
    massive_ranks: tuple[int, int] | None = None  # with massless bodies: the harness's and Pinocchio's ranks of
    # their massive bodies' columns (audit_pinocchio.py), equal where the base's count and Pinocchio's rank differ
    # by the columns of bodies one reading has and the other has not (a ball's two carriages)
    notes: list[str] = field(default_factory=list)
    identified: dict | None = None  # `identify_from_bench`'s figures, where asked for (--identify)
    seconds: float = 0.0

    def as_dict(self) -> dict:
        return asdict(self)


def example_robot_data() -> dict[str, Path]:
    """Every URDF of the installed example-robot-data, by name: the file's stem, or folder/stem
    where two robots share a stem. Empty when the package is not installed."""
    try:
        dist = distribution("example-robot-data")
    except PackageNotFoundError:
        return {}
    root = Path(dist.locate_file("cmeel.prefix/share/example-robot-data/robots"))
    files = sorted(root.glob("*/*/*.urdf"))
    stems = [f.stem for f in files]
    return {(f.stem if stems.count(f.stem) == 1 else f"{f.parts[-3]}/{f.stem}"): f for f in files}


def resolve(arguments: list[str]) -> dict[str, Path]:
    """Robots by name: each argument a file (URDF, MJCF .xml) or a name of example-robot-data; none:
    the whole of example-robot-data."""
    known = example_robot_data()
    if not arguments:
        if not known:
            raise InputError("example-robot-data", "", "not installed: name files to audit, or pip install "
                                                       "example-robot-data")
        return known
    out = {}
    for a in arguments:
        path = Path(a)
        if path.is_file():
            if path.suffix.lower() not in (".urdf", ".xml", ".toml"):
                raise InputError(path, "", "neither a URDF (.urdf), an MJCF file (.xml) nor a model file (.toml)")
            out[path.stem] = path
        elif a in known:
            out[a] = known[a]
        else:
            raise InputError(a, "", "no such file, and no robot of that name in example-robot-data")
    return out


def _against_pinocchios_parser(row: AuditRow, spec: RobotSpec, described: Path | None, states, ours: np.ndarray,
                               M: np.ndarray, coupled: RobotSpec | None = None) -> str:
    """The harness's torques and mass matrix against Pinocchio's own parse of the file, and its
    regressor's rank, into `row`; why the parser could not be compared with ("" where it was): it
    refuses the file, or reads other joints (a file it cannot represent, not a disagreement: the
    harness's reading is still compared with MuJoCo's). `coupled`: the robot with its joint couplings."""
    if _not_the_files(spec, described):
        row.notes.append(f"not compared with Pinocchio's parser: {_not_the_files(spec, described)}")
        return ""
    try:
        with _CapturedStderr() as said:
            pin_model = PinocchioParse(described, spec, GRAVITY_W)
        row.notes += pin_model.notes + [f"Pinocchio's parser said: {line}" for line in said.lines]
    except Exception as exc:  # Pinocchio's parser refusing the file is a finding, not a crash
        return f"Pinocchio's {_format(described)} parser cannot read it: {in_one_line(str(exc)) or type(exc).__name__}"
    if pin_model.other_joints:
        return (f"Pinocchio's {_format(described)} parser builds other joints than the file's "
                f"({', '.join(pin_model.other_joints[:4])})")
    theirs, M_pin = pin_model.torques_and_mass(*states)
    row.torques_vs_pinocchio = _largest(ours, theirs)
    row.mass_matrix_vs_pinocchio = float(np.max(np.abs(M - M_pin)) / np.max(np.abs(M_pin)))
    states = _states(spec, RANK_STATES, seed=2)
    W_pin = pin_model.regressor(*states)
    row.pinocchio_regressor_rank = rank(W_pin)
    if any(b.massless for b in spec.bodies):
        from harness.engines.pinocchio import build_model

        row.massive_ranks = massive_ranks(build_model(spec.rigid(), GRAVITY_W), pin_model, W_pin, states)
    return "" if coupled is None else _couplings_against_pinocchio(row, coupled, pin_model)


def _couplings_against_pinocchio(row: AuditRow, spec: RobotSpec, pin_model: PinocchioParse) -> str:
    """A chain of joint couplings: the actuated torques G^T tau and mass matrix G^T M G of the harness's
    tree at STATES random consistent states against Pinocchio's own parse with each follower made its
    leader's mimic joint (transformJointIntoMimic: the reduction inside Pinocchio's RNEA and CRBA, no
    G), into `row`; why not compared ("" where it was)."""
    from harness.engines.pinocchio import build_model, crba, rnea
    from harness.model.closure import ClosedChain, ClosureError, actuated_torques, random_within_limits

    pin = pin_model.pin
    model = pin_model.model
    try:
        for loop in spec.loops:
            model = pin.transformJointIntoMimic(model, model.getJointId(loop.leader), model.getJointId(loop.follower),
                                                loop.ratio, loop.offset)
        chain = ClosedChain.of(spec)
        m = random_within_limits(chain, spec.limits, STATES, seed=3)
    except (ClosureError, RuntimeError, ValueError) as exc:
        return f"couplings not compared: Pinocchio's mimic joints cannot represent them ({in_one_line(str(exc))})"
    pm = build_model(spec.rigid(), GRAVITY_W)
    ours, M = actuated_torques(m.G, rnea(pm, m.q, m.qd, m.qdd).tau), np.swapaxes(m.G, 1, 2) @ crba(pm, m.q) @ m.G
    act = list(chain.actuated)
    reduced = PinocchioParse.reduced(pin_model, model, [spec.joint_names[k] for k in act])
    theirs, M_pin = reduced.torques_and_mass(m.q[:, act], m.qd[:, act], m.qdd[:, act])
    row.couplings = len(spec.loops)
    row.couplings_vs_pinocchio = max(_largest(ours, theirs), float(np.max(np.abs(M - M_pin)) / np.max(np.abs(M_pin))))
    return ""


def _format(path: Path) -> str:
    return "MJCF" if path.suffix.lower() == ".xml" else "URDF"


def _not_the_files(spec: RobotSpec, described: Path | None) -> str:
    """Why the robot is not the file that describes it (then neither Pinocchio's parse of the file nor
    MuJoCo's conversion of it is compared), or ""."""
    if described is None:
        return "the model file reads no URDF or MJCF"
    if spec.urdf_fixed:
        return f"the model file fixes joints its URDF moves ({', '.join(spec.urdf_fixed[:3])})"
    from harness.model.urdf import NO_RIGID_BODY

    unlike = [note.split(":", 1)[0] for note in spec.notes if NO_RIGID_BODY in note]
    if unlike:
        return f"the harness reads {', '.join(unlike[:3])} as the nearest rigid body, the file as no rigid body"
    return ""


def _read(path: Path) -> tuple[RobotSpec, Path | None, RobotSpec | None]:
    """The robot as the harness reads it, the URDF or MJCF file that describes it (a model file's,
    None for a model file of the harness's own tree). A closed chain's tree is what is audited (its
    loops are the closed-chain scenarios': docs/closed_chains.md); a chain of joint couplings alone is
    also judged through them (`_couplings_against_pinocchio`, from `coupled`, the spec with its loops)."""
    import dataclasses

    from harness.model.load import load_spec, spec_from_data

    if path.suffix.lower() == ".toml":
        spec = load_spec(path)
        source = spec.urdf or spec.mjcf
    else:
        kind = "mjcf" if path.suffix.lower() == ".xml" else "urdf"
        spec, source = spec_from_data({kind: {"file": str(path.resolve())}}, path), path
    coupled = spec if spec.loops and all(not lp.joins_points for lp in spec.loops) else None
    return dataclasses.replace(spec, loops=(), actuated=()), source, coupled


def _states(spec: RobotSpec, count: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    from harness.model.states import position_bounds, random_states

    n = len(spec.joints)
    lo, hi = position_bounds(spec.joint_names, [j.revolute for j in spec.joints], spec.limits)
    return random_states(lo, hi, np.full(n, 2.0), np.full(n, 5.0), count, seed)




class _CapturedStderr:
    """What C and C++ code writes to the process's standard error (a parser's warnings), captured
    as lines instead of crossing the progress line."""

    def __enter__(self):
        import os
        import sys
        import tempfile

        sys.stderr.flush()
        self._file = tempfile.TemporaryFile()
        self._saved = os.dup(2)
        os.dup2(self._file.fileno(), 2)
        self.lines: list[str] = []
        return self

    def __exit__(self, *exc) -> None:
        import os

        os.dup2(self._saved, 2)
        os.close(self._saved)
        self._file.seek(0)
        self.lines = [line.strip() for line in self._file.read().decode(errors="replace").splitlines() if line.strip()]
        self._file.close()


def _mujoco_conversion(path: Path, name: str) -> RobotSpec:
    """MuJoCo's compiler's model of the URDF, read back as an MJCF file is read."""
    import mujoco

    from harness.model.load import spec_from_mjmodel
    from harness.model.mjcf import compiler_message

    root = ET.fromstring(path.read_bytes())
    for link in root.findall("link"):
        for tag in ("visual", "collision"):
            for el in link.findall(tag):
                link.remove(el)
    for joint in root.findall("joint"):  # MuJoCo makes <mimic> an equality constraint; the harness ignores it
        for el in joint.findall("mimic"):
            joint.remove(el)
    try:
        model = mujoco.MjSpec.from_string(ET.tostring(root, encoding="unicode")).compile()
    except (ValueError, mujoco.FatalError) as exc:
        raise ValueError(f"MuJoCo's compiler refuses the URDF ({compiler_message(exc)})") from None
    return spec_from_mjmodel(model, path.with_suffix(".mjcf"), name)


def _massless_with_inertia(path: Path) -> list[str]:
    """The URDF's links of zero mass with a rotational inertia (which MuJoCo's URDF import drops)."""
    out = []
    for link in ET.fromstring(path.read_bytes()).findall("link"):
        el = link.find("inertial")
        mass = el.find("mass") if el is not None else None
        inertia = el.find("inertia") if el is not None else None
        if mass is not None and inertia is not None and float(mass.get("value", "0")) == 0.0 and any(
                float(inertia.get(k, "0")) != 0.0 for k in ("ixx", "iyy", "izz")):
            out.append(link.get("name"))
    return out


def _invalid_bodies(spec: RobotSpec) -> list[str]:
    return [f"{b.name}: {why}" for b in spec.bodies
            if not b.massless and (why := not_rigid(b.mass, b.principal_inertia))]


def audit(name: str, path: Path, identify_in: Path | None = None) -> AuditRow:
    """One robot's row (never raises for the robot's own faults: they are its verdict). With
    `identify_in`, a folder, the robot is also identified from its own bench log there."""
    import warnings

    from harness.engines.mujoco import inverse_dynamics
    from harness.engines.pinocchio import build_model, crba, rnea
    from harness.identify.torque_id import structural_base
    from harness.model.spec import FLOATING_BASE_FIXED

    t0 = time.perf_counter()
    row = AuditRow(name, str(path), "refused")
    try:
        spec, described, coupled = _read(path)
    except InputError as exc:
        row.reason = exc.message.removeprefix(f"{path.resolve()}: ")
        row.seconds = time.perf_counter() - t0
        return row
    row.notes = list(spec.notes)
    row.dof = len(spec.joints)
    floating = spec.floating is not None or any(note.endswith(FLOATING_BASE_FIXED) for note in spec.notes)
    row.root = "floating (judged free, and fixed at the file's pose)" if floating else "fixed"
    row.bodies = len(spec.massive_bodies)
    row.invalid_bodies = _invalid_bodies(spec)
    if not spec.joints:
        row.verdict, row.reason = "agrees", "no moving joint: nothing to compare"
        row.seconds = time.perf_counter() - t0
        return row
    rigid = spec.rigid()
    q, qd, qdd = _states(spec, STATES, seed=1)
    pm = build_model(rigid, GRAVITY_W)
    ours, M = rnea(pm, q, qd, qdd).tau, crba(pm, q)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        uncompared = [why for why in [_against_pinocchios_parser(row, spec, described, (q, qd, qdd), ours, M,
                                                                         coupled)] if why]
        row.torques_vs_mujoco = _largest(inverse_dynamics(rigid, GRAVITY_W, q, qd, qdd), ours)
        if spec.transmission is not None or any(not f.none for f in spec.frictions):
            with_drives = rnea(build_model(spec, GRAVITY_W), q, qd, qdd).tau
            row.drives_vs_pinocchio = _largest(inverse_dynamics(spec, GRAVITY_W, q, qd, qdd), with_drives)
        problems = _against_mujocos_reading(row, spec, described, name, (q, qd, qdd), ours, uncompared)
    if spec.floating is not None:
        from harness.runner.audit_floating import floating_figures

        row.floating = floating_figures(spec, None if _not_the_files(spec, described) else described, (q, qd, qdd),
                                        seed=3)
        problems += [f"floating base: {k.removeprefix('floating_').replace('_', ' ')} {v:.2g}"
                     for k, v in row.floating.items() if not v <= TOLERANCE]
    row.base_parameters = len(structural_base(pm, spec.limits).independent)
    for label, value in (("torques against Pinocchio", row.torques_vs_pinocchio),
                         ("mass matrix against Pinocchio", row.mass_matrix_vs_pinocchio),
                         ("torques against MuJoCo", row.torques_vs_mujoco),
                         ("torques against MuJoCo's own model of the file", row.torques_vs_mujoco_file),
                         ("torques with the drives, MuJoCo against Pinocchio", row.drives_vs_pinocchio),
                         ("actuated torques through the couplings against Pinocchio's mimic joints",
                          row.couplings_vs_pinocchio)):
        if value is not None and not value <= TOLERANCE:
            problems.append(f"{label} {value:.2g}")
    if row.pinocchio_regressor_rank not in (None, row.base_parameters):
        if row.massive_ranks is None:
            problems.append(f"{row.base_parameters} structural base parameters, Pinocchio's regressor has rank "
                            f"{row.pinocchio_regressor_rank}")
        elif row.massive_ranks[0] != row.massive_ranks[1]:  # a difference the massless bodies do not explain
            problems.append(f"{row.base_parameters} structural base parameters, Pinocchio's regressor has rank "
                            f"{row.pinocchio_regressor_rank}, and of the massive bodies' columns alone "
                            f"{row.massive_ranks[0]} and {row.massive_ranks[1]}")
    if identify_in is not None:
        try:
            row.identified = identify_from_bench(name, path, identify_in / name.replace("/", "_"))
            worst = max(row.identified["validation_rel_error"][m] for m in ("least squares", "consistent"))
            if not worst <= IDENTIFY_TOLERANCE:
                problems.append(f"identified from its bench log: {worst:.2g} on the held-out span")
        except InputError as exc:
            row.identified = {"failed": exc.one_line()}
            problems.append(f"identification from its bench log refused: {exc.message}")
    # a disagreement of the dynamics fails; a reference that cannot represent the file is said, and fails nothing
    row.verdict = "disagrees" if problems else "not compared" if uncompared else "agrees"
    row.reason = "; ".join(problems + [f"{'not compared: ' if problems else ''}{why}" for why in uncompared])
    row.seconds = time.perf_counter() - t0
    return row


def _against_mujocos_reading(row: AuditRow, spec: RobotSpec, described: Path | None, name: str, states,
                             ours: np.ndarray, uncompared: list[str]) -> list[str]:
    """The harness's torques against MuJoCo's reading of the file, into `row`: an MJCF file compiled by
    MuJoCo itself (`file_inverse_dynamics`: rigid bodies, loops off, a free joint held at the file's
    pose), a URDF through MuJoCo's URDF import read back as an MJCF file is (a URDF it refuses is said in
    `row.mjcf`: Pinocchio's parser is the URDF's reference). A difference its import makes by what it
    drops (links of zero mass with an inertia) is added to `uncompared`; what disagrees is returned."""
    from harness.engines.mujoco_file import file_inverse_dynamics
    from harness.engines.pinocchio import build_model, rnea

    q, qd, qdd = states
    if described is not None and described.suffix.lower() == ".xml":
        row.mjcf = "the file itself"
        if not _not_the_files(spec, described):
            try:
                row.torques_vs_mujoco_file = _largest(
                    file_inverse_dynamics(described, spec.joint_names, GRAVITY_W, q, qd, qdd), ours)
            except ValueError as exc:
                return [str(exc)]
        return []
    if _not_the_files(spec, described):
        row.mjcf = f"not converted: {_not_the_files(spec, described)}"
        return []
    try:
        with _CapturedStderr() as said:
            converted = _mujoco_conversion(described, name)
        row.notes += [f"MuJoCo's URDF import said: {line}" for line in said.lines]
        converted = converted.rigid()
        if sorted(converted.joint_names) != sorted(spec.joint_names):
            raise ValueError(f"MuJoCo's model has other joints ({', '.join(converted.joint_names[:4])}, ...)")
    except (ValueError, InputError) as exc:  # the column says why; Pinocchio's parser is the file's reference
        row.mjcf = exc.message if isinstance(exc, InputError) else str(exc)
        return []
    to_theirs = [spec.joint_names.index(j) for j in converted.joint_names]
    back = [converted.joint_names.index(j) for j in spec.joint_names]
    theirs = rnea(build_model(converted, GRAVITY_W), q[:, to_theirs], qd[:, to_theirs], qdd[:, to_theirs]).tau[:, back]
    row.torques_urdf_vs_mjcf = _largest(ours, theirs)
    row.mjcf = "read"
    if row.torques_urdf_vs_mjcf <= TOLERANCE:
        return []
    dropped = _massless_with_inertia(described)
    if dropped:  # a limit of MuJoCo's import, not of the harness's reading (Pinocchio's parser keeps them too)
        uncompared.append(f"torques URDF against MJCF {row.torques_urdf_vs_mjcf:.2g}: MuJoCo's URDF import drops the "
                          f"rotational inertia of {len(dropped)} link(s) of zero mass, {', '.join(dropped[:3])}, which "
                          "the harness and Pinocchio's parser keep")
        return []
    return [f"torques URDF against MJCF {row.torques_urdf_vs_mjcf:.2g}"]


def totals(rows: list[AuditRow]) -> dict:
    """How many robots were read, agree, disagree, were not compared and were refused, and how many MuJoCo
    converted."""
    return {"robots": len(rows), "read": sum(r.verdict != "refused" for r in rows),
            "agree": sum(r.verdict == "agrees" for r in rows), "disagree": sum(r.verdict == "disagrees" for r in rows),
            "not_compared": sum(r.verdict == "not compared" for r in rows),
            "refused": sum(r.verdict == "refused" for r in rows),
            "mjcf_read": sum(r.mjcf == "read" for r in rows),
            "with_invalid_bodies": sum(bool(r.invalid_bodies) for r in rows),
            "identified": sum(bool(r.identified) and "validation_rel_error" in r.identified and max(
                r.identified["validation_rel_error"][m] for m in ("least squares", "consistent")) <= IDENTIFY_TOLERANCE
                for r in rows)}


BENCH_SECONDS, BENCH_RATE = 4.0, 250.0  # the bench log of the identification column: 1000 rows


def identify_from_bench(name: str, path: Path, folder: Path) -> dict:
    """The robot identified from its own bench log, as a lab's log is: every joint (a closed chain's
    actuated ones: a coupling's leader, not its follower) on two incommensurate sinusoids about the
    middle of its range (a third of it, at most 1 rad or 0.1 m), simulated in MuJoCo for BENCH_SECONDS,
    written as a log of t, q, q', tau at BENCH_RATE (those joints' columns), and read
    back through `[data]` (harness/sources/log/) with its last 30 % held out, with the model's own
    friction law (what is audited is the reading; `[friction_law]` is not chosen). Returns the relative
    torque errors on that span and the seconds it took; the files stay in `folder`."""
    from harness.model.states import position_bounds
    from harness.runner.pipeline import run
    from harness.runner.scenario import load_scenario
    from harness.sources.bench import record, write_log

    t0 = time.perf_counter()
    folder.mkdir(parents=True, exist_ok=True)
    import tomli_w

    from harness.model.load import load_spec

    model_file = path.resolve()  # a model file as it is; a URDF or MJCF through one written here
    if path.suffix.lower() != ".toml":
        model_file = folder / "model.toml"
        model_file.write_text(tomli_w.dumps({"model": {"name": name.replace("/", "_")},
                                             "mjcf" if path.suffix.lower() == ".xml" else "urdf":
                                             {"file": str(path.resolve())}}))
    spec = load_spec(model_file)
    moved = [spec.joint(a) for a in spec.actuated] if spec.loops else list(spec.joints)  # a closed chain's actuated
    lo, hi = position_bounds([j.name for j in moved], [j.revolute for j in moved], spec.limits)
    rng = np.random.default_rng(0)
    motion = {}
    for k, j in enumerate(moved):
        amp = float(min((hi[k] - lo[k]) / 6, 1.0 if j.revolute else 0.1))
        motion[j.name] = {"type": "sinusoids", "offset": float((lo[k] + hi[k]) / 2),
                          "sin": [[0.7 * amp, float(rng.uniform(0.6, 1.4))]],
                          "cos": [[0.3 * amp, float(rng.uniform(1.6, 2.8))]]}

    def gate(metric: str) -> list[dict]:
        return [{"metric": metric, "limit": 1.0}]

    (folder / "bench.toml").write_text(tomli_w.dumps({
        "scenario": {"model": str(model_file), "duration": BENCH_SECONDS,
                     "output_steps": int(BENCH_SECONDS * BENCH_RATE)},
        "simulation": {"integrator": "RK4", "timestep": 0.0005}, "motion": motion,
        "gates": gate("torques.pinocchio_vs_mujoco.max_rel_error")}))
    write_log(record(load_scenario(folder / "bench.toml")), [j.name for j in moved], folder / "log.csv")
    (folder / "log.toml").write_text(tomli_w.dumps({
        "scenario": {"model": str(model_file)},
        "data": {"file": "log.csv", "columns": {"t": "t", "q": "q{j}", "qd": "qd{j}", "tau": "tau{j}"},
                 "validation": {"from": 0.7}},
        "friction_law": {"choose": False},
        "gates": gate("log_identification.validation_rel_error.consistent")}))
    out = run(load_scenario(folder / "log.toml"))
    done = out.stages["log_identification"]
    li = done.stage.serialise(done.result, out.context, done.config)
    return {"validation_rel_error": li["validation_rel_error"], "solver": li["consistent"]["solver"],
            "seconds": round(time.perf_counter() - t0, 3)}
