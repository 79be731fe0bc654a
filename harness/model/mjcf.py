"""Robots from MJCF files into a RobotSpec, through MuJoCo's own compiler (mujoco.MjSpec), so that
defaults, classes, includes, `inertiafromgeom` and every other MJCF rule mean what MuJoCo makes of
them.

Hinge (revolute) and slide (prismatic) joints; a body of several joints is the chain they are (MuJoCo
applies them in order), each joint after its first carried by a massless body `<body>[<joint before>]`,
where they share one point and those after the first are hinges (a universal joint, a gimbal; the
massless carriage the harness's models carry); a body without a joint is welded to its
parent and merged into it (masses add, centres of mass combine, inertias by the parallel-axis
theorem), as a URDF's fixed joint is. The geometry is taken at q = 0 (every hinge and slide
coordinate zero, which is MuJoCo's qpos, not `ref`), in the world frame. Per joint: its range as
the position limits, `armature` as the rotor inertia, `damping` as viscous friction and
`frictionloss` as Coulomb friction (MuJoCo's dry friction: a sharp sign, coulomb_velocity 0); an
actuator that drives one joint alone gives its force range, times its gear, as the joint's effort
limit. Gravity is the file's (`<option gravity>`, MuJoCo's default 0 0 -9.81 when it states none).

A free joint on a body of the world (a floating base) is fixed to the world at the file's pose, as
a URDF's root link is, and said so (RobotSpec.notes, printed as a warning and kept in results.json);
the base itself is kept (RobotSpec.floating: the body and those fixed to it, its frame, the joints on
it), which harness/engines/floating.py judges free.
Drives (harness/model/drives.py) are read where the file states them as MuJoCo writes a coupled
drive: one fixed tendon per motor over the joints it turns with, carrying the motor's `armature`,
`damping` and `frictionloss`, and at most one motor actuator on it with gear g. Motor k's row of N is
g times the tendon's coefficients (the motor turns g times the tendon's length), and its law in motor
units is the tendon's armature and damping over g^2 and its frictionloss over |g| (what reaches the
joints is the same). Every joint must then be on a drive tendon (N is square and invertible) and carry
no armature, damping or frictionloss of its own; MJCF has no motor offsets (they are read as zero).

Loops: `<equality>` `connect` and `weld` elements (of two bodies or two sites) close the tree into a
closed chain (harness/model/loops.py), its actuated joints those a joint actuator drives; a `joint`
equality of two joints whose polynomial is linear (polycoef a_0 a_1 0 0 0) couples them, joint1
following joint2 (q_1 = a_1 q_2 + a_0 + ref_1 - a_1 ref_2, in the harness's q, MuJoCo's qpos).

A ball joint is read as the three hinges about its body's axes at q = 0, `<ball>_x`, `<ball>_y`, `<ball>_z`,
applied in that order (harness/model/cardano.py: Cardano angles, singular where `<ball>_y` = +-pi/2), two
massless bodies carrying the second and third; its range, a cone, is RobotSpec.cones (judged by
the angle of its rotation) and each hinge's limits +-cone/3 (inside it).

Refused, with a line naming the element: a ball joint with a motor, armature, damping or friction loss or
beside other joints in its body, free joints below the root, a body whose joints
are apart or have a slide after the first, tendons that are not such drives, tendon and flex
equalities (a tendon loop), a joint equality of higher degree or of one joint, an equality that starts
inactive, loops beside drive tendons, a ball's stiffness, a tendon spring with a dead band, and gravity
compensation, which the harness's models do not carry. A hinge's or slide's `stiffness` k at `springref` q_ref
is the joint's spring: the law's k q with an offset -k q_ref (harness/model/friction.py); a drive tendon's,
its motor's (k/g^2 and -k L_s/g in motor units).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from harness.base.tomlio import MAX_XML_BYTES, Table, read_bounded
from harness.model.friction import JointFriction
from harness.model.inertia import union
from harness.model.spec import FLOATING_BASE_FIXED, Body, Joint, RobotSpec


def read_mjcf(path: Path, table: Table, key: str = "file") -> tuple:
    """Bodies and joints (world frame at q = 0) of an MJCF file, joint position limits by name,
    effort limits by name ({"effort": ..}), the file's gravity (3,), what was assumed (a floating base
    fixed), one line each, its drives (`drive_tendons`, None without) and its loops and actuated
    joints (`_closure`, None without equality constraints). Errors name the file and
    the element, under `key` of `table`."""
    import mujoco

    read_bounded(path, MAX_XML_BYTES)  # too large or unreadable: refused before MuJoCo parses it
    try:
        ms = mujoco.MjSpec.from_file(str(path))
        model = ms.compile()
    except (ValueError, mujoco.FatalError) as exc:
        raise table.error(key, f"{path}: MuJoCo cannot compile it ({compiler_message(exc)})") from None
    return read_model(model, path, table, key)


def compiler_message(exc: BaseException) -> str:
    """What MuJoCo's compiler said, on one line (its message and the element it names)."""
    return "; ".join(line.strip() for line in str(exc).strip().splitlines() if line.strip()) or type(exc).__name__


def read_model(model, path: Path, table: Table, key: str = "file") -> tuple:
    """`read_mjcf`'s reading of a compiled MuJoCo model (mujoco.MjModel) that came from `path`."""
    import mujoco

    try:
        return _read(model, mujoco, path)
    except _Refused as exc:
        raise table.error(key, f"{path}: {exc}") from None


class _Refused(ValueError):
    pass


def _name(model, kind, i: int) -> str:
    import mujoco

    return mujoco.mj_id2name(model, kind, i) or f"#{i}"


def _read(model, mujoco, path: Path) -> tuple:
    obj, jt = mujoco.mjtObj, mujoco.mjtJoint
    _check_equalities(model, mujoco)
    drives = drive_tendons(model, mujoco) if model.ntendon else None
    if model.neq and drives is not None:
        raise _Refused(f"equality constraint {_name(model, obj.mjOBJ_EQUALITY, 0)!r}: a closed chain with drive "
                       "tendons is not supported")
    if np.any(model.body_gravcomp):
        b = int(np.flatnonzero(model.body_gravcomp)[0])
        raise _Refused(f"body {_name(model, obj.mjOBJ_BODY, b)!r}: gravcomp is not supported")
    free_root = None
    for j in range(model.njnt):
        name, body = _name(model, obj.mjOBJ_JOINT, j), int(model.jnt_bodyid[j])
        kind = model.jnt_type[j]
        if kind == jt.mjJNT_BALL:
            _check_ball(model, mujoco, j)
        if kind == jt.mjJNT_FREE:
            if model.body_parentid[body] != 0:
                raise _Refused(f"joint {name!r}: a free joint below the root is not supported")
            if free_root is not None:
                raise _Refused(f"joint {name!r}: a second floating body (one robot per file)")
            free_root = j
            continue
    data = mujoco.MjData(model)
    data.qpos[:] = 0.0
    balls = [j for j in range(model.njnt) if model.jnt_type[j] == jt.mjJNT_BALL]
    data.qpos[model.jnt_qposadr[balls]] = 1.0  # a ball at q = 0: its identity quaternion (not left to MuJoCo's
    # normalising of a zero one)
    notes: tuple[str, ...] = tuple(_ball_note(model, mujoco, path, j) for j in balls)
    if free_root is not None:  # fixed at the file's pose
        adr = model.jnt_qposadr[free_root]
        data.qpos[adr:adr + 7] = model.qpos0[adr:adr + 7]
        notes += (f"{path.name}: free joint {_name(model, obj.mjOBJ_JOINT, free_root)!r} of body "
                 f"{_name(model, obj.mjOBJ_BODY, int(model.jnt_bodyid[free_root]))!r}: {FLOATING_BASE_FIXED}",)
    mujoco.mj_kinematics(model, data)
    _check_joint_chains(model, data, mujoco)

    # every body belongs to the nearest body at or above it with a hinge or slide joint, or to the world
    moving = {int(model.jnt_bodyid[j]) for j in range(model.njnt) if j != free_root}
    owner = {0: 0}
    for b in range(1, model.nbody):  # MuJoCo numbers bodies from the root outwards
        owner[b] = b if b in moving else owner[int(model.body_parentid[b])]
    groups: dict[int, list[int]] = {}
    for b in range(1, model.nbody):
        if owner[b]:
            groups.setdefault(owner[b], []).append(b)
    bodies = []
    for b, members in groups.items():
        parts = _parts(model, data, members)
        mass = sum(p[0] for p in parts)
        name = _name(model, obj.mjOBJ_BODY, b)
        if mass <= 0:
            raise _Refused(f"body {name!r} moves without mass")
        _, com, moments, axes = union(parts)
        bodies.append(Body(name, mass, np.diag(moments), axes, com))

    joints, limits, efforts, cones = [], {}, {}, {}
    for j in range(model.njnt):
        if j == free_root:
            continue
        name, b = _name(model, obj.mjOBJ_JOINT, j), int(model.jnt_bodyid[j])
        dof = model.jnt_dofadr[j]
        friction = _joint_law(model, j, dof, name)
        parent = owner[int(model.body_parentid[b])]
        inner, outer = (_name(model, obj.mjOBJ_BODY, parent) if parent else "world"), _name(model, obj.mjOBJ_BODY, b)
        if j in balls:  # three hinges about the body's axes, two massless carriages between them
            hinges, carriages = _ball_hinges(model, data, obj, j, inner, outer, friction)
            joints += hinges
            bodies += carriages
            if model.jnt_limited[j]:  # its cone; each hinge within a third of it keeps the ball inside it
                cone = float(model.jnt_range[j, 1])
                cones[name] = (tuple(h.name for h in hinges), cone)
                limits |= {h.name: (-cone / 3, cone / 3) for h in hinges}
            continue
        first, count = int(model.body_jntadr[b]), int(model.body_jntnum[b])
        if count > 1:  # joints of one body: a chain, each after the first carried by a massless body at their point
            if j > first:
                inner = _carriage(model, obj, b, j - 1)
            if j < first + count - 1:
                outer = _carriage(model, obj, b, j)
                bodies.append(Body(outer, 0.0, np.zeros((3, 3)), np.eye(3), data.xanchor[j].copy()))
        joints.append(Joint(name, "revolute" if model.jnt_type[j] == jt.mjJNT_HINGE else "prismatic",
                            inner, outer, data.xanchor[j].copy(), data.xaxis[j].copy(), friction))
        if model.jnt_limited[j]:
            limits[name] = (float(model.jnt_range[j, 0]), float(model.jnt_range[j, 1]))
    for a in range(model.nu):
        if model.actuator_trntype[a] != mujoco.mjtTrn.mjTRN_JOINT or not model.actuator_forcelimited[a]:
            continue
        j = int(model.actuator_trnid[a, 0])
        if j == free_root or j < 0:
            continue
        effort = float(np.max(np.abs(model.actuator_forcerange[a])) * abs(model.actuator_gear[a, 0]))
        name = _name(model, obj.mjOBJ_JOINT, j)
        efforts[name] = {"effort": effort + efforts.get(name, {}).get("effort", 0.0)}  # actuators on one joint add
    closure = _closure(model, data, mujoco, owner) if model.neq else None
    floating = None if free_root is None else _floating_base(model, data, mujoco, free_root, owner)
    return bodies, joints, limits, efforts, model.opt.gravity.copy(), notes, drives, closure, floating, cones


def _joint_law(model, j: int, dof: int, name: str) -> JointFriction:
    """Joint j's drive as the file gives it: armature, damping, frictionloss (a sharp sign) and its spring,
    MuJoCo's -k (q - q_ref), the law's k q with an offset f_o = -k q_ref (a polynomial spring refused)."""
    if np.any(model.jnt_stiffnesspoly[j]):
        raise _Refused(f"joint {name!r}: a spring's polynomial terms (stiffness beyond its first value) are not "
                       "supported: a spring is linear, k (q - springref)")
    k, q_ref = float(model.jnt_stiffness[j]), float(model.qpos_spring[model.jnt_qposadr[j]])
    return JointFriction(armature=float(model.dof_armature[dof]), viscous=float(model.dof_damping[dof]),
                         coulomb=float(model.dof_frictionloss[dof]), offset=-k * q_ref if k else 0.0, stiffness=k)


def _floating_base(model, data, mujoco, free_root: int, owner: dict):
    """The free joint's body and every body without a joint below it, at the file's pose, as one
    rigid body (harness/model/spec.py, FloatingBase)."""
    from harness.model.spec import FloatingBase

    obj = mujoco.mjtObj
    base = int(model.jnt_bodyid[free_root])

    def on_base(b: int) -> bool:
        while b and owner[b] == 0:
            if b == base:
                return True
            b = int(model.body_parentid[b])
        return False

    mass, com, moments, axes = union(_parts(model, data, [b for b in range(1, model.nbody) if on_base(b)]))
    ball = int(mujoco.mjtJoint.mjJNT_BALL)  # a ball's three hinges (`_ball_hinges`), as a body's several joints
    on_it = tuple(name for j in range(model.njnt)
                  if j != free_root and on_base(int(model.body_parentid[model.jnt_bodyid[j]]))
                  for name in ([f"{_name(model, obj.mjOBJ_JOINT, j)}_{s}" for s in BALL_AXES]
                               if int(model.jnt_type[j]) == ball else [_name(model, obj.mjOBJ_JOINT, j)]))
    return FloatingBase(_name(model, obj.mjOBJ_JOINT, free_root),
                        Body(_name(model, obj.mjOBJ_BODY, base), mass, np.diag(moments), axes, com),
                        data.xmat[base].reshape(3, 3).copy(), data.xpos[base].copy(), on_it)


def _parts(model, data, bodies: list[int]) -> list[tuple[float, np.ndarray, np.ndarray]]:
    """Each MuJoCo body's (mass, centre of mass, inertia about it), world frame, for `union`."""
    out = []
    for k in bodies:
        R = data.ximat[k].reshape(3, 3)
        out.append((float(model.body_mass[k]), data.xipos[k].copy(), R @ np.diag(model.body_inertia[k]) @ R.T))
    return out


BALL_AXES = ("x", "y", "z")  # a ball joint's hinges, `<ball>_x` .. `<ball>_z`, about its body's axes in this order


def _check_ball(model, mujoco, j: int) -> None:
    """A ball joint read as its three hinges (`_ball_hinges`), else refused in one line: one with a motor, or
    armature, damping, friction loss or stiffness (MuJoCo's act on the ball's angular velocity or rotation,
    which are not its hinges' rates and angles: harness/model/cardano.py), one beside other joints in its
    body, one whose hinges' names the file gives other joints."""
    obj = mujoco.mjtObj
    name, body = _name(model, obj.mjOBJ_JOINT, j), int(model.jnt_bodyid[j])
    dofs = slice(int(model.jnt_dofadr[j]), int(model.jnt_dofadr[j]) + 3)
    for term, values in (("armature", model.dof_armature), ("damping", model.dof_damping),
                         ("frictionloss", model.dof_frictionloss), ("stiffness", model.jnt_stiffness[j: j + 1])):
        if np.any(values[dofs if term != "stiffness" else slice(None)] != 0.0):
            raise _Refused(f"ball joint {name!r} has {term} (a ball is read as three hinges about its body's axes, "
                           "on whose rates MuJoCo's ball terms do not act alike): only a ball without them is read")
    driven = [a for a in range(model.nu) if model.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT
              and int(model.actuator_trnid[a, 0]) == j]
    if driven:
        raise _Refused(f"actuator {_name(model, obj.mjOBJ_ACTUATOR, driven[0])!r} drives ball joint {name!r}: a motor "
                       "on a ball joint is not supported")
    if int(model.body_jntnum[body]) > 1:
        raise _Refused(f"body {_name(model, obj.mjOBJ_BODY, body)!r} has ball joint {name!r} and other joints (a ball "
                       "joint is read alone in its body)")
    taken = {_name(model, obj.mjOBJ_JOINT, k) for k in range(model.njnt)} & {f"{name}_{s}" for s in BALL_AXES}
    if taken:
        raise _Refused(f"ball joint {name!r} is read as hinges {name}_x, {name}_y, {name}_z, and the file names "
                       f"another joint {sorted(taken)[0]!r}")


def _ball_hinges(model, data, obj, j: int, inner: str, outer: str, friction: JointFriction) -> tuple[list, list]:
    """Ball joint j as the three hinges about its body's x, y and z axes at q = 0, in that order, at its
    anchor (harness/model/cardano.py: the body then turns by R(theta) = Rx Ry Rz in its own axes, as the
    ball's quaternion turns it), and the two massless bodies that carry the second and third hinge."""
    name, body = _name(model, obj.mjOBJ_JOINT, j), int(model.jnt_bodyid[j])
    axes_W = data.xmat[body].reshape(3, 3)  # its columns: the body's axes in world
    point = data.xanchor[j].copy()
    names = [f"{name}_{s}" for s in BALL_AXES]
    carriages = [f"{_name(model, obj.mjOBJ_BODY, body)}[{n}]" for n in names[:2]]
    ends = [inner, *carriages, outer]
    hinges = [Joint(n, "revolute", ends[k], ends[k + 1], point.copy(), axes_W[:, k].copy(), friction)
              for k, n in enumerate(names)]
    return hinges, [Body(c, 0.0, np.zeros((3, 3)), np.eye(3), point.copy()) for c in carriages]


def _ball_note(model, mujoco, path: Path, j: int) -> str:
    """What the reading of ball joint j assumed, one line."""
    obj = mujoco.mjtObj
    name = _name(model, obj.mjOBJ_JOINT, j)
    r = model.jnt_range[j, 1]
    cone = (f"; its range, a cone of {r:g} rad, judges the motion (results.json: motion.limits), and the motions "
            f"the harness makes keep each hinge within +-{r / 3:g} rad, inside it") if model.jnt_limited[j] else ""
    return (f"{path.name}: ball joint {name!r} of body {_name(model, obj.mjOBJ_BODY, int(model.jnt_bodyid[j]))!r} "
            f"read as the hinges {name}_x, {name}_y, {name}_z about the body's axes, in that order (Cardano angles: "
            f"singular where {name}_y = +-pi/2){cone}")


def _carriage(model, obj, body: int, joint: int) -> str:
    """The massless body between `joint` and the next joint of the same MuJoCo body."""
    return f"{_name(model, obj.mjOBJ_BODY, body)}[{_name(model, obj.mjOBJ_JOINT, joint)}]"


def _check_joint_chains(model, data, mujoco) -> None:
    """A body with several joints (MuJoCo applies them in order, each about its axis as the ones before
    it have turned it) is the chain of joints it is, each after the first carried by a massless body:
    read where its joints share one point and every joint after the first is a hinge (what a carriage
    of the harness carries); refused in one line otherwise."""
    obj = mujoco.mjtObj
    for b in range(1, model.nbody):
        first, count = int(model.body_jntadr[b]), int(model.body_jntnum[b])
        if count < 2:
            continue
        name = _name(model, obj.mjOBJ_BODY, b)
        later = range(first + 1, first + count)
        if any(model.jnt_type[j] != mujoco.mjtJoint.mjJNT_HINGE for j in later):
            slide = next(j for j in later if model.jnt_type[j] != mujoco.mjtJoint.mjJNT_HINGE)
            raise _Refused(f"body {name!r} has {count} joints and joint {_name(model, obj.mjOBJ_JOINT, slide)!r}, "
                           "not its first, is not a hinge (a chain of joints in one body is read with hinges after "
                           "its first joint)")
        apart = float(np.max(np.linalg.norm(data.xanchor[list(later)] - data.xanchor[first], axis=1)))
        if apart > 1e-12 * max(1.0, float(np.linalg.norm(data.xanchor[first]))):
            raise _Refused(f"body {name!r} has {count} joints {apart:.3g} m apart (a chain of joints in one body is "
                           "read where they share one point)")


def _check_equalities(model, mujoco) -> None:
    """Every equality constraint a loop (`_closure`): joint, tendon and flex equalities and one that
    starts inactive refused in one line."""
    obj, eq = mujoco.mjtObj, mujoco.mjtEq
    for i in range(model.neq):
        name, kind = _name(model, obj.mjOBJ_EQUALITY, i), mujoco.mjtEq(int(model.eq_type[i]))
        if kind not in (eq.mjEQ_CONNECT, eq.mjEQ_WELD, eq.mjEQ_JOINT):
            what = "a tendon coupling or tendon loop" if kind == eq.mjEQ_TENDON else "a flex constraint"
            raise _Refused(f"equality constraint {name!r} is {what}: only connect, weld and linear joint equalities "
                           "are supported")
        if kind == eq.mjEQ_JOINT and int(model.eq_obj2id[i]) < 0:
            held = _name(model, obj.mjOBJ_JOINT, int(model.eq_obj1id[i]))
            raise _Refused(f"equality constraint {name!r} holds joint {held!r} at a constant (no joint2): fix the "
                           "joint in the file instead")
        if kind == eq.mjEQ_JOINT and np.any(model.eq_data[i, 2:5] != 0.0):
            raise _Refused(f"equality constraint {name!r} couples its joints by a polynomial of degree above 1 "
                           f"(polycoef {' '.join(f'{c:g}' for c in model.eq_data[i, :5])}): only a linear coupling "
                           "is supported")
        if not model.eq_active0[i]:
            raise _Refused(f"equality constraint {name!r} starts inactive: a loop switched on and off is not "
                           "supported")


def _closure(model, data, mujoco, owner: dict) -> tuple[tuple, tuple[str, ...]]:
    """The file's loops (harness/model/loops.py: each `connect` or `weld` of two bodies or two sites,
    its points and frames where they are at q = 0, `data` holding the kinematics there) and its actuated
    joints (those a joint actuator drives; with couplings alone and no actuator, every joint that follows
    none). A body without a joint belongs to the body it is merged into
    (`owner`); a linear joint equality as a coupling. Refused: tendon and flex equalities (a tendon loop),
    an equality that starts inactive, a loop whose two sides are one body."""
    from harness.model.spec import Loop

    obj, eq = mujoco.mjtObj, mujoco.mjtEq
    loops = []
    for i in range(model.neq):
        name, kind = _name(model, obj.mjOBJ_EQUALITY, i), mujoco.mjtEq(int(model.eq_type[i]))
        d = model.eq_data[i]
        if kind == eq.mjEQ_JOINT:  # q_1 - ref_1 = a_0 + a_1 (q_2 - ref_2), q here MuJoCo's qpos
            j1, j2 = int(model.eq_obj1id[i]), int(model.eq_obj2id[i])
            ref1, ref2 = (float(model.qpos0[model.jnt_qposadr[j]]) for j in (j1, j2))
            loops.append(Loop.coupling(name, _name(model, obj.mjOBJ_JOINT, j1), _name(model, obj.mjOBJ_JOINT, j2),
                                       d[1], ref1 + d[0] - d[1] * ref2))
            continue
        ends = []
        for side, obj_id in ((0, int(model.eq_obj1id[i])), (1, int(model.eq_obj2id[i]))):
            if int(model.eq_objtype[i]) == int(obj.mjOBJ_SITE):
                body = int(model.site_bodyid[obj_id])
                point, R = data.site_xpos[obj_id].copy(), data.site_xmat[obj_id].reshape(3, 3).copy()
            else:
                body = obj_id
                R_body, p_body = data.xmat[body].reshape(3, 3), data.xpos[body]
                if kind == eq.mjEQ_CONNECT:  # data: the anchor in body 1's frame, then in body 2's
                    point, R = p_body + R_body @ d[3 * side:3 * side + 3], R_body.copy()
                else:  # data: the anchor in body 2's frame, then where it and body 2's axes are in body 1's
                    rel = np.zeros(9)
                    mujoco.mju_quat2Mat(rel, d[6:10])
                    if side == 0:
                        point, R = p_body + R_body @ d[3:6], R_body @ rel.reshape(3, 3)
                    else:
                        point, R = p_body + R_body @ d[0:3], R_body.copy()
            ends.append((_name(model, obj.mjOBJ_BODY, owner[body]) if owner[body] else "world", point, R))
        if ends[0][0] == ends[1][0]:
            raise _Refused(f"equality constraint {name!r} joins body {ends[0][0]!r} to itself")
        weld = kind == eq.mjEQ_WELD
        loops.append(Loop(name, "weld" if weld else "connect", ends[0][0], ends[1][0], ends[0][1], ends[1][1],
                          ends[0][2] if weld else None, ends[1][2] if weld else None))
    actuated = tuple(dict.fromkeys(_name(model, obj.mjOBJ_JOINT, int(model.actuator_trnid[a, 0]))
                                   for a in range(model.nu) if model.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT))
    if not actuated and all(not lp.joins_points for lp in loops):  # couplings alone: every joint not a follower
        followers = {lp.follower for lp in loops}
        one_dof = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
        actuated = tuple(n for j in range(model.njnt) if (n := _name(model, obj.mjOBJ_JOINT, j)) not in followers
                         and int(model.jnt_type[j]) in one_dof)
    return tuple(loops), actuated


def drive_tendons(model, mujoco) -> dict:
    """The file's drives (the module's docstring): {"motors": names, "rows": per motor {joint: N[k, j]},
    "laws": per motor its JointFriction in motor units}, refused in one line where a tendon is not a
    drive (a spatial tendon, one that no joint moves, two motors on it, a joint of its own friction)."""
    obj = mujoco.mjtObj
    motors, rows, laws = [], [], []
    gear = {}
    for a in range(model.nu):
        if model.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_TENDON:
            k = int(model.actuator_trnid[a, 0])
            if k in gear:
                raise _Refused(f"tendon {_name(model, obj.mjOBJ_TENDON, k)!r}: two actuators drive it (a drive is "
                               "one motor)")
            gear[k] = float(model.actuator_gear[a, 0])
    for k in range(model.ntendon):
        name = _name(model, obj.mjOBJ_TENDON, k)
        adr, num = int(model.tendon_adr[k]), int(model.tendon_num[k])
        if any(model.wrap_type[adr + i] != mujoco.mjtWrap.mjWRAP_JOINT for i in range(num)):
            raise _Refused(f"tendon {name!r}: a spatial tendon is not supported (a drive is a fixed tendon over "
                           "joints)")
        g = gear.get(k, 1.0)
        if g == 0:
            raise _Refused(f"tendon {name!r}: its motor's gear is 0")
        rows.append({_name(model, obj.mjOBJ_JOINT, int(model.wrap_objid[adr + i])): g * float(model.wrap_prm[adr + i])
                     for i in range(num)})
        motors.append(name)
        # the tendon's spring, -k (L - L_s) along it, is the motor's k/g^2 q_m - k L_s/g (q_m = g L)
        stiffness, (low, high) = float(model.tendon_stiffness[k]), model.tendon_lengthspring[k]
        if np.any(model.tendon_stiffnesspoly[k]):
            raise _Refused(f"tendon {name!r}: a spring's polynomial terms are not supported (a spring is linear)")
        if stiffness and low != high:
            raise _Refused(f"tendon {name!r}: a spring with a dead band (springlength {low:g} to {high:g}) is not "
                           "supported")
        laws.append(JointFriction(armature=float(model.tendon_armature[k]) / g**2,
                                  viscous=float(model.tendon_damping[k]) / g**2,
                                  coulomb=float(model.tendon_frictionloss[k]) / abs(g),
                                  offset=-stiffness * float(low) / g if stiffness else 0.0, stiffness=stiffness / g**2))
    for j in range(model.njnt):
        dof = model.jnt_dofadr[j]
        if model.dof_armature[dof] or model.dof_damping[dof] or model.dof_frictionloss[dof] or model.jnt_stiffness[j]:
            raise _Refused(f"tendon {motors[0]!r} is read as a motor's drive (a fixed tendon: "
                           f"harness/model/drives.py), and joint {_name(model, obj.mjOBJ_JOINT, j)!r} has armature, "
                           "damping, frictionloss or stiffness of its own beside it: the drives carry them")
    return {"motors": motors, "rows": rows, "laws": laws}


# --- the robot as an MJCF file for others to simulate: the reader's counterpart ---------------------


def write_mjcf(spec: RobotSpec, gravity_W: np.ndarray, comment: str = "", floating: bool = False) -> str:
    """The robot as an MJCF file: its bodies with their inertials, hinge and slide joints with their
    ranges, `armature` (rotor inertia), `damping` (viscous friction) and `frictionloss` (Coulomb
    friction, which MuJoCo applies as dry friction: the mapping of the smooth law is the caller's to
    state), a motor per joint (gear 1; a closed chain's actuated joints only) with the joint's effort
    limit as its force range, and a closed chain's loops as site-based equalities. Built
    with MjSpec and written by MuJoCo's own writer, then every number it wrote rewritten from the
    MjSpec's doubles at full precision (the writer keeps six digits), so the file reloads to the bit.
    `comment` (plain text) heads the file. With `floating`, the floating base on a free joint (as the
    file's own, or a URDF's floating joint, named), the joints on it."""
    import xml.etree.ElementTree as ET

    import mujoco

    from harness.model.mjspec import add_robot, new_spec

    ms = new_spec(spec.name, gravity_W)
    add_robot(ms, spec, frictionloss=True, floating=floating)
    for joint in spec.joints:
        j = ms.joint(joint.name)
        if spec.transmission is None:
            j.frictionloss = joint.friction.coulomb
            j.stiffness = [joint.friction.stiffness, 0.0, 0.0]  # linear, at springref 0: the law's k q (its
            # offset has no place)
        lo, hi = (spec.limits or {}).get(joint.name, (-np.inf, np.inf))
        if np.isfinite(lo) and np.isfinite(hi):
            j.range = [lo, hi]
        if spec.transmission is None and (not spec.loops or joint.name in spec.actuated):  # a closed chain's
            effort = (spec.drive_limits or {}).get(joint.name, {}).get("effort")  # passive joints: no motor
            motor = ms.add_actuator(name=joint.name, target=joint.name, trntype=mujoco.mjtTrn.mjTRN_JOINT,
                                    gear=[1.0, 0, 0, 0, 0, 0])
            if effort is not None:
                motor.forcerange = [-effort, effort]
    for motor in (spec.transmission.motors if spec.transmission is not None else ()):  # on its drive tendon
        ms.add_actuator(name=motor, target=motor, trntype=mujoco.mjtTrn.mjTRN_TENDON, gear=[1.0, 0, 0, 0, 0, 0])
    ms.compile()  # what MuJoCo refuses is refused here, not by the reader of the file
    root = ET.fromstring(ms.to_xml())
    for el in root.iter():
        _exact_numbers(el, ms, root)
    for tendon in root.iter("fixed"):  # a drive tendon's coefficients: its motor's row of N
        k = spec.transmission.motors.index(tendon.get("name"))
        for wrap in tendon.iter("joint"):
            wrap.set("coef", repr(float(spec.transmission.N[k, spec.joint_names.index(wrap.get("joint"))])))
    ET.indent(root)
    head = "".join(f"<!-- {line} -->\n" for line in comment.replace("--", "- -").splitlines())
    return head + ET.tostring(root, encoding="unicode") + "\n"


# what each MJCF attribute holds in the MjSpec element it belongs to
_ATTRIBUTES = {"body": {"pos": "pos", "quat": "quat"},
               "inertial": {"pos": "ipos", "quat": "iquat", "mass": "mass", "diaginertia": "inertia"},
               "joint": {"pos": "pos", "axis": "axis", "range": "range", "armature": "armature",
                         "damping": "damping", "frictionloss": "frictionloss", "stiffness": "stiffness"},
               "general": {"gear": "gear", "forcerange": "forcerange"},
               "fixed": {"armature": "armature", "damping": "damping", "frictionloss": "frictionloss",
                         "stiffness": "stiffness"},
               "option": {"gravity": "gravity"},
               "site": {"pos": "pos", "quat": "quat"}}


def _exact_numbers(el, ms, root) -> None:
    """Every number MuJoCo's writer put in `el` replaced by the double the MjSpec holds."""
    names = _ATTRIBUTES.get(el.tag)
    if names is None:
        return
    if el.tag == "inertial":
        owner = next(b for b in root.iter("body") if el in list(b))
        source = ms.body(owner.get("name"))
    elif el.tag == "option":
        source = ms.option
    elif el.tag == "fixed":
        source = ms.tendon(el.get("name"))
    elif el.tag == "joint" and el.get("name") is None:  # a tendon's wrap: its coefficient is set by the caller
        return
    elif el.tag == "joint" and el.get("joint1") is not None:  # an equality's: a coupling's polynomial
        if el.get("polycoef") is not None:
            eq = next(e for e in ms.equalities if e.name == el.get("name"))
            el.set("polycoef", " ".join(repr(float(v)) for v in eq.data[:5]))
        return
    else:
        source = {"body": ms.body, "joint": ms.joint, "general": ms.actuator, "site": ms.site}[el.tag](el.get("name"))
    for attribute, field in names.items():
        if el.get(attribute) is None:
            continue
        values = np.atleast_1d(np.asarray(getattr(source, field), dtype=float))
        written = len(el.get(attribute).split())
        el.set(attribute, " ".join(repr(float(v)) for v in values[:written]))
