"""A model file read into a RobotSpec (harness/model/spec.py): models/*.toml, or a URDF it names.

Geometry is given in the world frame at the initial pose (all joint coordinates zero), the way
the paper describes its layout (section 2.1, Figure 2): each body's centre of mass O_ci, its
principal axes e1(i), e2(i) (e3(i) = e1(i) x e2(i)), and each joint's point O_j and axis.
Inertias of homogeneous cylinders follow from geometry (paper section 2.2, Eq. 24):

    m = rho pi R^2 l,   J11 = m R^2 / 2,   J22 = J33 = m (3 R^2 + l^2) / 12,

with the cylinder's axis along e1(i). A body may also be a thin rod along e1(i)
(J11 = 0, J22 = J33 = m l^2 / 12), a point mass (all moments zero), state its mass and principal
moments, or be massless (a carriage that only carries a joint).

A model may instead be given by Denavit-Hartenberg parameters (`[dh]`, standard convention
T = Rz(theta) Tz(d) Tx(a) Rx(alpha)): link i turns about z(i-1) at the origin of frame i-1, a rod
link spans a_i along x(i) and ends at the origin of frame i, with its centre of mass at its
middle; a point link sits at the origin of frame i.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from harness.base.tomlio import InputError, Table, read_toml
from harness.model.drive_tables import invertible, read_drives, read_friction
from harness.model.drives import Transmission
from harness.model.friction import NO_FRICTION
from harness.model.inertia import MOMENT_FLOOR, not_rigid, union
from harness.model.spec import BODY_SHAPES, JOINT_TYPES, WORLD, Body, Cylinder, Joint, RobotSpec
from harness.model.urdf import example_robot_data_path, read_urdf

_ORTHO_TOL = 1e-9


def load_spec(path: Path | str) -> RobotSpec:
    """Load and validate models/*.toml; raises `InputError` naming the file and key."""
    path = Path(path)
    return spec_from_data(read_toml(path), path)


def spec_from_data(data: dict, path: Path) -> RobotSpec:
    """A model file's content, validated as `load_spec` does; files it names are relative to
    `path`, and errors name `path` (which need not exist: `{"urdf": {"file": ...}}` reads a URDF)."""
    root = Table(data, path)
    # [model] may be left out of a URDF or MJCF model file: the robot's name, or the file's, names it
    default_name = ((root.data.get("urdf") or {}).get("robot", path.stem) if root.has("urdf")
                    else path.stem if root.has("mjcf") else None)
    model = root.table("model", default={}) if default_name else root.table("model")
    name = model.string("name", default=default_name) if default_name else model.string("name")
    description = model.string("description", default="")
    stated = model.vector("gravity") if model.has("gravity") else None  # m/s^2, world: over an MJCF's <option>
    model.finish()
    dh = limits = urdf_path = drive_limits = gravity = mjcf_path = tendons = closure = floating = cones = None
    fixed: tuple[str, ...] = ()
    notes: tuple[str, ...] = ()
    if root.has("dh"):
        bodies, joints, body_tables, joint_tables, dh = _read_dh(root.table("dh"))
    elif root.has("urdf"):
        ut = root.table("urdf")
        if ut.either("robot", "file", "robot (from example-robot-data) or file") == "robot":
            name_ = ut.string("robot")
            urdf_path = example_robot_data_path(name_)
            if urdf_path is None:
                from importlib.metadata import PackageNotFoundError, distribution

                try:
                    distribution("example-robot-data")
                except PackageNotFoundError:
                    raise ut.error("robot", f"no robot {name_!r}: the example-robot-data package is not installed "
                                            "(pip install -e '.[robots]')") from None
                raise ut.error("robot", f"no robot {name_!r} in example-robot-data (looked for {name_}.urdf in "
                                        "every */urdf/ and */robots/ folder of its robots)")
        else:
            urdf_path = path.parent / ut.string("file")
            if not urdf_path.is_file():
                raise ut.error("file", f"URDF file {urdf_path} not found")
        fixed = ut.strings("fixed", choices=None) if ut.has("fixed") else ()
        dynamics = ut.boolean("dynamics", default=True)  # false: the joints' <dynamics> left out
        mimic = ut.string("mimic", default="coupled", choices=MIMIC_READINGS)
        floating_root = ut.boolean("floating", default=False)  # the root link floats (a legged robot's base)
        ut.finish()
        bodies, joints, limits, drive_limits, urdf_notes, couplings, floating = read_urdf(urdf_path, ut, fixed,
                                                                                          floating_root)
        if couplings and mimic == "independent":
            urdf_notes += [f"joint {c.follower!r} mimics {c.leader!r} in the URDF: read as a joint of its own, moved "
                           "and identified as the others ([urdf] mimic = \"independent\")" for c in couplings]
            couplings = ()
        if couplings:  # <mimic>: the followers are the passive joints
            followers = {c.follower for c in couplings}
            closure = (couplings, tuple(j.name for j in joints if j.name not in followers))
        if not dynamics:
            joints = [dataclasses.replace(j, friction=NO_FRICTION) for j in joints]
        notes = tuple(urdf_notes)
        joints = _joint_friction(root, joints, "the URDF")
        body_tables = [Table({"name": b.name}, path, f"urdf.{b.name}") for b in bodies]
        joint_tables = [Table({"name": j.name}, path, f"urdf.{j.name}") for j in joints]
    elif root.has("mjcf"):
        from harness.model.mjcf import read_mjcf  # loads MuJoCo: only for an MJCF model

        mt = root.table("mjcf")
        mjcf_path = path.parent / mt.string("file")
        if not mjcf_path.is_file():
            raise mt.error("file", f"MJCF file {mjcf_path} not found")
        mt.finish()
        bodies, joints, limits, drive_limits, gravity, notes, tendons, closure, floating, cones = read_mjcf(mjcf_path,
                                                                                                              mt)
        joints = _joint_friction(root, joints, "the MJCF file")
        body_tables = [Table({"name": b.name}, path, f"mjcf.{b.name}") for b in bodies]
        joint_tables = [Table({"name": j.name}, path, f"mjcf.{j.name}") for j in joints]
    else:
        body_tables, joint_tables = root.tables("bodies"), root.tables("joints")
        bodies = [_read_body(t) for t in body_tables]
        joints = [_read_joint(t) for t in joint_tables]
    payload = root.table("payload") if root.has("payload") else None
    if payload is not None:
        bodies = _with_payload(bodies, payload)
    drives = root.table("drives") if root.has("drives") else None
    chain_table = root.table("closed_chain") if root.has("closed_chain") else None
    root.finish()
    if urdf_path or mjcf_path:
        notes = notes + _degenerate(bodies, "the URDF" if urdf_path else "the MJCF file")
    spec = _assemble(RobotSpec(name, description, path, tuple(bodies), tuple(joints), dh, limits, urdf_path, fixed,
                               drive_limits, gravity if stated is None else stated, mjcf_path, notes, floating=floating,
                               cones=cones), body_tables, joint_tables)
    if root.has("mjcf") and tendons is not None:
        if drives is not None:
            raise drives.error("", f"{mjcf_path} states its drives (tendons): give them there or here, not both")
        spec = with_tendon_drives(spec, tendons, Table({}, path, "mjcf"))
    if drives is not None:  # in the spec's joint order, root outwards
        joints, transmission = read_drives(drives, list(spec.joints), urdf_path)
        spec = dataclasses.replace(spec, joints=tuple(joints), transmission=transmission)
    elif urdf_path is not None:  # transmissions a URDF states and the model does not read: said
        from harness.model import urdf_transmissions

        unread = urdf_transmissions.unread_note(urdf_path, spec.joint_names)
        spec = spec if unread is None else dataclasses.replace(spec, notes=(*spec.notes, unread))
    if closure is not None or chain_table is not None:
        spec = _closed_chain(spec, closure, chain_table, Table({}, path, "mjcf" if mjcf_path else "urdf")
                             if closure is not None else root)
    return spec


MIMIC_READINGS = ("coupled", "independent")  # a URDF's <mimic>: a coupling (the follower no degree of freedom),
# or each mimic joint a joint of its own (the tree every joint of which a scenario moves)


def _closed_chain(spec: RobotSpec, from_file: tuple | None, t: Table | None, file_table: Table) -> RobotSpec:
    """The spec with its loops (an MJCF file's, or `[[closed_chain.loops]]`'s for a TOML or URDF tree:
    `name`, `type` connect or weld, `body1`, `body2` (a body or "world") and `point`, the world point at
    q = 0 where they are joined, a weld keeping their relative orientation at q = 0; or `type` joint,
    `follower`, `leader`, `ratio` (default 1) and `offset` (default 0): a coupling q_follower = ratio
    q_leader + offset, as a URDF's <mimic> states one and the model reads there) and its actuated
    joints (`closed_chain.actuated`, else the MJCF file's actuated joints), checked: the loops close
    near q = 0 and the actuated joints determine the passive ones there (harness/model/closure.py)."""
    from harness.model.closure import ClosedChain, ClosureError, close, projection
    from harness.model.spec import LOOP_KINDS, Loop

    loops, actuated = from_file if from_file is not None else ((), ())
    key, where = ("file", file_table) if from_file is not None else ("closed_chain", t)
    origin = f"{spec.mjcf or spec.urdf}: " if from_file is not None else ""
    if t is not None:
        if t.has("actuated"):
            actuated = t.strings("actuated", choices=spec.joint_names)
            key, where, origin = "actuated", t, ""
        if t.has("loops"):
            if from_file is not None and spec.mjcf is not None:
                raise t.error("loops", f"{spec.mjcf} states its loops (<equality>): give them there or here, not both")
            bodies = [b.name for b in spec.bodies] + [WORLD]
            read = []
            for lt in t.tables("loops"):
                kind = lt.string("type", choices=LOOP_KINDS)
                if kind == "joint":
                    read.append(_coupling(lt, spec, f"loop{len(read) + 1}"))
                    continue
                a, b = lt.string("body1", choices=bodies), lt.string("body2", choices=bodies)
                if a == b:
                    raise lt.error("body2", f"joins body {a!r} to itself")
                point = lt.vector("point")
                frame = np.eye(3) if kind == "weld" else None
                read.append(Loop(lt.string("name", default=f"loop{len(read) + 1}"), kind, a, b, point, point,
                                 frame, frame))
                lt.finish()
            loops = (*loops, *read)  # a URDF's couplings (<mimic>) and the loops stated here
        t.finish()
    if not loops:
        raise where.error(key, "a closed chain needs loops: none is stated")
    if spec.transmission is not None:
        raise where.error(key, f"{origin}loop {loops[0].name!r}: a closed chain with drives ([drives]) is not "
                               "supported")
    loaded = [j.name for j, f in zip(spec.joints, spec.frictions, strict=True) if f.load_coulomb]
    if loaded:  # tests/test_closed_chains.py: MuJoCo's drive reads it at the commanded accelerations, 3.6e-6 apart
        raise InputError(file_table.file, f"joints.{loaded[0]}.load_coulomb",
                         "a closed chain's friction cannot depend on the load: which load a joint in a loop "
                         "carries (the tree's rigid-body torque, or with the loops' forces) the law does not say")
    for loop in loops:
        for body in (loop.body_a, loop.body_b) if loop.joins_points else ():
            if body != WORLD and spec.body(body).massless:
                raise where.error(key, f"{origin}loop {loop.name!r} joins body {body!r}, which has no mass (a carriage "
                                       "merged into its child): join the body that moves")
    if not actuated:
        raise where.error(key, f"{origin}loop {loops[0].name!r} closes a chain whose actuated joints are not named "
                               "(an MJCF file's joint actuators, or closed_chain.actuated)")
    spec = dataclasses.replace(spec, loops=tuple(loops), actuated=tuple(actuated))
    try:
        chain = ClosedChain.of(spec)
        projection(chain, close(chain, np.zeros(len(spec.joints)), "the initial configuration (all q = 0), row"))
    except ClosureError as exc:
        raise where.error(key, f"{origin}{exc}") from None
    return spec


def _coupling(lt: Table, spec: RobotSpec, default_name: str):
    """A `type = "joint"` loop of `[[closed_chain.loops]]`: a coupling of two of the spec's joints."""
    from harness.model.spec import Loop

    follower = lt.string("follower", choices=spec.joint_names)
    leader = lt.string("leader", choices=spec.joint_names)
    if leader == follower:
        raise lt.error("leader", f"couples joint {follower!r} to itself")
    ratio, offset = lt.number("ratio", default=1.0), lt.number("offset", default=0.0)
    if ratio == 0.0:
        raise lt.error("ratio", "is 0: the follower would be held, not coupled (fix the joint instead)")
    loop = Loop.coupling(lt.string("name", default=default_name), follower, leader, ratio, offset)
    lt.finish()
    return loop


def _degenerate(bodies: list[Body], source: str) -> tuple[str, ...]:
    """A note per moving body that a file gives no rotational inertia about some axis (a point or a thin
    rod, where a real link has size): what the engines and a fit make of it."""
    return tuple(f"{b.name!r} has a principal moment of inertia of zero in {source}: MuJoCo is given "
                 f"{MOMENT_FLOOR:g} of the model's largest moment there, and an identified inertia of it is judged "
                 "against nothing (no size of its own in the model)" for b in bodies
                 if not b.massless and not_rigid(b.mass, b.principal_inertia) == "a principal moment not positive")


def with_tendon_drives(spec: RobotSpec, tendons: dict, table: Table) -> RobotSpec:
    """The spec with the drives an MJCF file states as tendons (harness/model/mjcf.py, drive_tendons):
    N in the spec's joint order, the motors' laws, no offsets."""
    names = spec.joint_names
    own = [j.name for j in spec.joints if not j.friction.none]
    if own:
        raise table.error("file", f"{spec.mjcf} states its drives (tendons): joint {own[0]!r} cannot have friction of "
                                  "its own ([joints.NAME]); the drives carry it")
    if len(tendons["motors"]) != len(names):
        raise table.error("file", f"{spec.mjcf}: tendon {tendons['motors'][0]!r} is read as a motor's drive (a fixed "
                                  f"tendon): {len(tendons['motors'])} drive tendons for {len(names)} joints, where "
                                  "each joint's motion must be some motor's (N square and invertible)")
    N = np.array([[row.get(j, 0.0) for j in names] for row in tendons["rows"]])
    if not invertible(N):
        raise table.error("file", f"{spec.mjcf}: the drive tendons' transmission is not invertible")
    return dataclasses.replace(spec, joints=tuple(dataclasses.replace(j, friction=f) for j, f in
                                                  zip(spec.joints, tendons["laws"], strict=True)),
                               transmission=Transmission(N, np.zeros(len(names)), tuple(tendons["motors"])))


def _assemble(spec: RobotSpec, body_tables: list[Table], joint_tables: list[Table]) -> RobotSpec:
    """The spec checked (unique names, a tree, massless bodies that only carry a joint) and ordered
    from the root outwards; errors name the tables the bodies and joints came from."""
    bodies, joints = list(spec.bodies), list(spec.joints)
    _check_unique([b.name for b in bodies], body_tables, "body")
    _check_unique([j.name for j in joints], joint_tables, "joint")
    order = _check_tree(bodies, joints, body_tables, joint_tables)
    bodies_by_name = {b.name: b for b in bodies}
    spec = dataclasses.replace(spec, bodies=tuple(bodies_by_name[n] for n in order),
                               joints=tuple(sorted(joints, key=lambda j: order.index(j.child))))
    _check_massless(spec, {t.data.get("name"): t for t in body_tables})
    return spec


def spec_from_mjmodel(model, path: Path, name: str) -> RobotSpec:
    """A compiled MuJoCo model (MuJoCo's own conversion of a URDF, say) as a RobotSpec, read as an
    `[mjcf]` file is (harness/model/mjcf.py); errors name `path`."""
    from harness.model.mjcf import read_model

    table = Table({}, path)
    bodies, joints, limits, drive_limits, gravity, notes, tendons, closure, floating, cones = read_model(model, path,
                                                                                                          table)
    spec = _assemble(RobotSpec(name, "", path, tuple(bodies), tuple(joints), None, limits, None, (), drive_limits,
                               gravity, path, notes, floating=floating, cones=cones),
                     [Table({"name": b.name}, path, f"mjcf.{b.name}") for b in bodies],
                     [Table({"name": j.name}, path, f"mjcf.{j.name}") for j in joints])
    spec = spec if tendons is None else with_tendon_drives(spec, tendons, table)
    return spec if closure is None else _closed_chain(spec, closure, None, table)


def _joint_friction(root: Table, joints: list[Joint], source: str) -> list[Joint]:
    """`[joints.<name>]`: friction and rotor inertia beyond what the description file states."""
    if not root.has("joints"):
        return joints
    jt = root.table("joints")
    by_name = {j.name: j for j in joints}
    for jname in list(jt.data):
        if jname not in by_name:
            raise jt.error(jname, f"no joint {jname!r} in {source} (joints: {', '.join(by_name)})")
        t = jt.table(jname)
        by_name[jname] = dataclasses.replace(by_name[jname], friction=read_friction(t, by_name[jname].friction))
        t.finish()
    jt.finish()
    return [by_name[j.name] for j in joints]


def _with_payload(bodies: list[Body], t: Table) -> list[Body]:
    """`[payload]`: a rigid load on a body (`body`): `mass`, its centre of mass `com` and its
    inertia about that centre `inertia` = [Ixx, Iyy, Izz, Ixy, Ixz, Iyz], both in the world frame at
    the initial pose. The body becomes the union of both (parallel axes), in its new principal axes."""
    name = t.string("body")
    if name not in {b.name for b in bodies} or next(b for b in bodies if b.name == name).massless:
        raise t.error("body", f"no body {name!r} with mass to carry the payload")
    m = t.number("mass", positive=True)
    c = t.vector("com")
    xx, yy, zz, xy, xz, yz = t.vector("inertia", length=6)
    I_c = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
    moments = np.linalg.eigvalsh(I_c)
    if moments[0] < 0 or moments[0] + moments[1] < moments[2] * (1 - 1e-9):
        raise t.error("inertia", "is not the inertia of a rigid body (negative, or breaks the triangle inequality)")
    t.finish()
    out = []
    for b in bodies:
        if b.name != name:
            out.append(b)
            continue
        M, com, principal, axes = union([(b.mass, b.p_W_com0, b.R_WB0 @ b.I_B @ b.R_WB0.T), (m, c, I_c)])
        out.append(dataclasses.replace(b, mass=M, I_B=np.diag(principal), R_WB0=axes, p_W_com0=com, cylinder=None))
    return out


def _named(table: Table, kind: str) -> str:
    name = table.string("name")
    if not name or name == WORLD:
        raise table.error("name", f"{name!r} cannot name a {kind}")
    table.path = f"{table.path.split('[')[0]}.{name}"
    return name


def _read_body(t: Table) -> Body:
    name = _named(t, "body")
    shape = t.string("shape", choices=BODY_SHAPES)
    cylinder = None
    if shape == "massless":
        mass, inertia = 0.0, np.zeros(3)
        p_W_com = t.vector("com", default=[0.0, 0.0, 0.0])
        R_WB = np.eye(3)
    else:
        if shape == "cylinder":
            cylinder = Cylinder(t.number("length", positive=True), t.number("radius", positive=True),
                                t.number("density", positive=True))
            mass, inertia = cylinder.mass, cylinder.principal_inertia
        elif shape in ("rod", "point"):
            mass = t.number("mass", positive=True)
            length = t.number("length", positive=True) if shape == "rod" else 0.0
            inertia = np.array([0.0, 1.0, 1.0]) * mass * length**2 / 12.0
        else:
            mass = t.number("mass", positive=True)
            inertia = t.vector("inertia")
            if np.any(inertia <= 0.0):
                raise t.error("inertia", f"principal moments must be positive, got {inertia.tolist()}")
            if np.any(2.0 * inertia > inertia.sum() * (1.0 + 1e-12)):
                raise t.error("inertia", "principal moments violate the triangle inequality "
                                         f"(J11 <= J22 + J33 and cyclic), got {inertia.tolist()}")
        p_W_com = t.vector("com")
        R_WB = _frame(t) if shape != "point" or t.has("e1") else np.eye(3)
    t.finish()
    return Body(name, mass, np.diag(inertia), R_WB, p_W_com, cylinder)


def dh_transform(alpha: float, a: float, d: float, theta: float) -> np.ndarray:
    """Standard Denavit-Hartenberg: T = Rz(theta) Tz(d) Tx(a) Rx(alpha), 4 x 4."""
    ct, st, ca, sa = np.cos(theta), np.sin(theta), np.cos(alpha), np.sin(alpha)
    return np.array([[ct, -st * ca, st * sa, a * ct], [st, ct * ca, -ct * sa, a * st],
                     [0.0, sa, ca, d], [0.0, 0.0, 0.0, 1.0]])


def _read_dh(t: Table) -> tuple[list[Body], list[Joint], list[Table], list[Table], tuple]:
    """A serial chain from DH rows; every joint revolute about z(i-1), zero at theta = 0."""
    unit = {"degrees": np.pi / 180.0, "radians": 1.0}[t.string("angles", default="radians",
                                                               choices=("degrees", "radians"))]
    t.string("convention", default="standard", choices=("standard",))
    rows = t.tables("links")
    t.finish()
    T = np.eye(4)
    bodies, joints, dh = [], [], []
    parent = WORLD
    for row in rows:
        name = _named(row, "body")
        joint_name = row.string("joint")
        alpha, a = row.number("alpha") * unit, row.number("a", nonnegative=True)
        d, theta = row.number("d"), row.number("theta", default=0.0) * unit
        shape = row.string("shape", choices=("rod", "point"))
        mass = row.number("mass", positive=True)
        row.finish()
        dh.append((alpha, a, d, theta))
        axis, origin = T[:3, 2].copy(), T[:3, 3].copy()
        T = T @ dh_transform(alpha, a, d, theta)
        if shape == "rod":
            if a <= 0.0:
                raise row.error("a", "a rod link needs a > 0 (its length)")
            com = T[:3, 3] - a / 2 * T[:3, 0]
            inertia = np.array([0.0, 1.0, 1.0]) * mass * a**2 / 12.0
        else:
            com, inertia = T[:3, 3].copy(), np.zeros(3)
        bodies.append(Body(name, mass, np.diag(inertia), T[:3, :3].copy(), com))
        joints.append(Joint(joint_name, "revolute", parent, name, origin, axis))
        parent = name
    names = [j.name for j in joints]
    if len(set(names)) != len(names):
        dup = next(n for n in names if names.count(n) > 1)
        raise rows[names.index(dup, names.index(dup) + 1)].error("joint", f"duplicate joint name {dup!r}")
    joint_tables = [Table({"name": j.name}, t.file, f"{r.path}.joint") for j, r in zip(joints, rows, strict=True)]
    return bodies, joints, rows, joint_tables, tuple(dh)


def _frame(t: Table) -> np.ndarray:
    e1 = t.vector("e1", nonzero=True)
    e2 = t.vector("e2", nonzero=True)
    e1, e2 = e1 / np.linalg.norm(e1), e2 / np.linalg.norm(e2)
    if abs(e1 @ e2) > _ORTHO_TOL:
        raise t.error("e2", f"must be perpendicular to e1 (e1 . e2 = {e1 @ e2:.3g})")
    return np.column_stack([e1, e2, np.cross(e1, e2)])


def _read_joint(t: Table) -> Joint:
    name = _named(t, "joint")
    jtype = t.string("type", choices=JOINT_TYPES)
    parent = t.string("parent")
    child = t.string("child")
    point = t.vector("point")
    axis = t.vector("axis", nonzero=True)
    friction = read_friction(t)
    t.finish()
    return Joint(name, jtype, parent, child, point, axis / np.linalg.norm(axis), friction)




def _check_unique(names: list[str], tables: list[Table], kind: str) -> None:
    seen: set[str] = set()
    for name, t in zip(names, tables, strict=True):
        if name in seen:
            raise t.error("name", f"duplicate {kind} name {name!r}")
        seen.add(name)


def _check_tree(bodies: list[Body], joints: list[Joint], body_tables: list[Table],
                joint_tables: list[Table]) -> list[str]:
    """Every body has exactly one inner joint and is reached from the world: a tree."""
    names = {b.name for b in bodies}
    inner: dict[str, Joint] = {}
    for j, t in zip(joints, joint_tables, strict=True):
        if j.parent != WORLD and j.parent not in names:
            raise t.error("parent", f"body {j.parent!r} does not exist")
        if j.child not in names:
            raise t.error("child", f"body {j.child!r} does not exist")
        if j.child == j.parent:
            raise t.error("child", f"joint {j.name!r} connects body {j.child!r} to itself")
        if j.child in inner:
            raise t.error("child", f"body {j.child!r} is already the child of joint "
                                   f"{inner[j.child].name!r}: each body has one inner joint")
        inner[j.child] = j
    for b, t in zip(bodies, body_tables, strict=True):
        if b.name not in inner:
            raise t.error("name", f"body {b.name!r} is not the child of any joint")
    order: list[str] = []
    frontier = [WORLD]
    while frontier:
        parent = frontier.pop(0)
        children = [b.name for b in bodies if inner[b.name].parent == parent]
        order += children
        frontier += children
    if len(order) < len(bodies):
        stray = next(b.name for b in bodies if b.name not in order)
        loop, cur = [stray], inner[stray].parent
        while cur not in loop:
            loop.append(cur)
            cur = inner[cur].parent
        t = joint_tables[joints.index(inner[stray])]
        raise t.error("parent", "loop in the tree: " + " <- ".join(loop + [cur]))
    return order


def _check_massless(spec: RobotSpec, tables: dict[str, Table]) -> None:
    """A massless body is a carriage: it carries exactly one revolute joint through its own point.

    The engines merge it into its child (a body of zero mass cannot move on its own), and the
    wrench across its inner joint is then measured about the shared point.
    """
    for b in spec.bodies:
        if not b.massless:
            continue
        t = tables[b.name]
        outer = spec.outer_joints(b.name)
        if not outer:  # nothing to merge it into: it would move alone
            where = f"{spec.urdf}: link" if spec.urdf else f"{spec.mjcf}: body" if spec.mjcf else "body"
            raise t.error("mass", f"{where} {b.name!r} moves (joint {spec.inner_joint(b.name).name!r}) and has no "
                                  "mass: no engine moves a body without mass; give it mass (in a URDF, an "
                                  "<inertial>) or fix its joint")
        if len(outer) != 1 or not outer[0].revolute:
            raise t.error("shape", f"massless body {b.name!r} must carry exactly one revolute joint")
        inner = spec.inner_joint(b.name)
        if not np.allclose(inner.p_W0, outer[0].p_W0, rtol=0.0, atol=1e-12):
            raise t.error("shape", f"massless body {b.name!r}: its inner joint {inner.name!r} and "
                                   f"outer joint {outer[0].name!r} must share one point")


__all__ = ["WORLD", "Body", "Cylinder", "InputError", "Joint", "RobotSpec", "load_spec"]
