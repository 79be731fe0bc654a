"""A model file's tables of drive laws (harness/model/load.py reads the rest): a joint's friction and
rotor inertia (`[joints.NAME]`, harness/model/friction.py) and the motors behind the joints (`[drives]`,
harness/model/drives.py), N stated in the table or read from a URDF's <transmission> elements
(harness/model/urdf_transmissions.py)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from harness.base.tomlio import InputError, Table
from harness.model.drives import Transmission
from harness.model.friction import FRICTION_KEYS, NO_FRICTION, JointFriction
from harness.model.spec import Joint


def read_friction(t: Table, base: JointFriction = NO_FRICTION) -> JointFriction:
    """The optional keys of a joint's table (harness/model/friction.py): armature, viscous, coulomb,
    coulomb_velocity, stribeck_velocity and stiffness non-negative; offset, viscous_asymmetry,
    coulomb_asymmetry and stribeck of any sign, load_coulomb too but under 1 in size. Keys not given keep
    `base` (a URDF's <dynamics>, an MJCF joint's own)."""
    values = {k: t.number(k, default=getattr(base, k), nonnegative=k in NONNEGATIVE) for k in FRICTION_KEYS
              if t.has(k) or getattr(base, k)}
    if values.get("stribeck") and not values.get("stribeck_velocity"):
        raise t.error("stribeck_velocity", "a Stribeck term needs its velocity (> 0)")
    if abs(values.get("load_coulomb", 0.0)) >= 1.0:  # friction.rigid_torque reads the load back only below 1
        raise t.error("load_coulomb", f"{values['load_coulomb']:g}: a load-dependent term is a fraction of the load "
                                      "(|f_l| < 1), or the friction would outgrow the torque it depends on")
    return JointFriction(**values)


NONNEGATIVE = ("armature", "viscous", "coulomb", "coulomb_velocity", "stribeck_velocity", "stiffness")


MAX_TRANSMISSION_CONDITION = 1e12  # a transmission whose N is worse conditioned than this is not invertible


def read_drives(t: Table, joints: list[Joint], urdf: Path | None = None) -> tuple[list[Joint], Transmission]:
    """`[drives]`: the motors behind the joints (harness/model/drives.py), in the spec's joint order
    (root outwards, as results.json lists them; a joint's index is its column of N):

        motors = ["m1", ...]              # optional: their names (default motor_1 .. motor_n)
        gear_ratio = [32, 32, 45, -48, 45, 32]      # N's diagonal: motor k turns gear_ratio[k] times joint k
        coupling = [{ motor = "motor_6", joint = "joint_5", ratio = 32 }]   # N's other entries
        # or: transmission = [[...], ...]   N whole, a row per motor
        offset = [0, 50.27, ...]          # optional: each motor's position at q = 0 (default 0)
        # or: joint_offset = [0, -1.5708, ...]   q = N^-1 q_m + joint_offset (offset = -N joint_offset)
        # or, for a URDF: urdf_transmissions = true   its <transmission> elements give the motors (their
        #   actuators' names), N and joint_offset (harness/model/urdf_transmissions.py)
        [drives.motor_6]                  # per motor, in motor units: the law of harness/model/friction.py
        armature = 0.00964                # rotor inertia, kg m^2
        viscous = 0.616
        coulomb = 1.95

    The joints' own friction (a URDF's <dynamics>, `[joints.NAME]`) cannot stand beside them: the
    drives carry it."""
    n, names = len(joints), [j.name for j in joints]
    with_friction = [j.name for j in joints if not j.friction.none]
    if with_friction:
        raise t.error("", f"joint {with_friction[0]!r} has friction of its own (a URDF's <dynamics> or "
                          "[joints.NAME]): with [drives] the motors carry it ([drives.MOTOR]; [urdf] dynamics = "
                          "false leaves a URDF's <dynamics> out)")
    if t.has("urdf_transmissions"):
        return _urdf_drives(t, joints, urdf)
    motors = tuple(t.strings("motors", choices=None)) if t.has("motors") else tuple(f"motor_{k + 1}" for k in range(n))
    if len(motors) != n or len(set(motors)) != n:
        raise t.error("motors", f"{len(motors)} names for {n} joints: one distinct name per joint's motor")
    if t.either("gear_ratio", "transmission", "gear_ratio (N's diagonal, with coupling) or transmission "
                                              "(N whole)") == "gear_ratio":
        N = np.diag(t.vector("gear_ratio", length=n))
        for c in (t.tables("coupling") if t.has("coupling") else ()):
            k = motors.index(c.string("motor", choices=motors))
            j = names.index(c.string("joint", choices=tuple(names)))
            if k == j:
                raise c.error("joint", f"{names[j]!r} is {motors[k]!r}'s own joint: its ratio is in gear_ratio")
            N[k, j] = c.number("ratio")
            c.finish()
    else:
        if t.has("coupling"):
            raise t.error("coupling", "with transmission (N whole), every coupling is in it")
        N = t.rows("transmission", n)
        if len(N) != n:
            raise t.error("transmission", f"{len(N)} rows for {n} motors: N is {n} x {n}")
    if not invertible(N):
        raise _singular(t, N, motors, names)
    offset = np.zeros(n)
    if t.has("offset") and t.has("joint_offset"):
        raise t.error("joint_offset", "give offset (the motors') or joint_offset, not both")
    if t.has("offset"):
        offset = t.vector("offset", length=n)
    elif t.has("joint_offset"):
        offset = -N @ t.vector("joint_offset", length=n)
    return _with_laws(t, joints, Transmission(N, offset, motors))


def _with_laws(t: Table, joints: list[Joint], transmission: Transmission) -> tuple[list[Joint], Transmission]:
    """Each motor's law (`[drives.MOTOR]`, else none), on its row's joint; the table finished."""
    laws = []
    for m in transmission.motors:
        if t.has(m):
            mt = t.table(m)
            laws.append(read_friction(mt))
            mt.finish()
        else:
            laws.append(NO_FRICTION)
    t.finish()
    return [dataclasses.replace(j, friction=f) for j, f in zip(joints, laws, strict=True)], transmission


def _urdf_drives(t: Table, joints: list[Joint], urdf: Path | None) -> tuple[list[Joint], Transmission]:
    """`urdf_transmissions = true`: the URDF's <transmission> elements as the drives, nothing of N beside."""
    from harness.model import urdf_transmissions

    if not t.boolean("urdf_transmissions"):
        raise t.error("urdf_transmissions", "false: leave the key out, or give gear_ratio or transmission")
    if urdf is None:
        raise t.error("urdf_transmissions", "reads a URDF's <transmission> elements, and the model is not a URDF")
    given = [k for k in ("motors", "gear_ratio", "coupling", "transmission", "offset", "joint_offset") if t.has(k)]
    if given:
        raise t.error(given[0], "with urdf_transmissions = true the URDF's <transmission> elements state it")
    try:
        read = urdf_transmissions.read(urdf, [j.name for j in joints])
    except ValueError as exc:
        raise t.error("urdf_transmissions", f"{urdf.name}: {exc}") from None
    if not invertible(read.N):
        raise t.error("urdf_transmissions", f"{urdf.name}: the transmissions' N is not invertible")
    return _with_laws(t, joints, Transmission(read.N, -read.N @ read.joint_offset, read.motors))


def invertible(N: np.ndarray) -> bool:
    with np.errstate(divide="ignore"):
        return bool(np.linalg.cond(N) < MAX_TRANSMISSION_CONDITION)


def _singular(t: Table, N: np.ndarray, motors: tuple[str, ...], joints: list[str]) -> InputError:
    """Why `[drives]`'s N is not invertible, naming the entry that makes it so: a gear ratio of 0, a
    coupling without which N would be invertible, a row of zeros (a motor that turns with no joint) or a
    column (a joint no motor turns), else the motors whose rows are linearly dependent."""
    by_ratio = t.has("gear_ratio")
    why = f"N is not invertible (condition number {np.linalg.cond(N):.3g}): "
    if by_ratio and not np.all(np.diag(N)):
        k = int(np.flatnonzero(np.diag(N) == 0)[0])
        return t.error("gear_ratio", why + f"entry {k + 1} (motor {motors[k]!r}, joint {joints[k]!r}) is 0: a motor "
                                           "that turns with its joint has a ratio other than 0")
    couplings = t.data.get("coupling", []) if by_ratio else []
    for i, c in enumerate(couplings):
        k, j = motors.index(c["motor"]), joints.index(c["joint"])
        if invertible(np.where((np.arange(len(N))[:, None] == k) & (np.arange(len(N)) == j), 0.0, N)):
            return t.error(f"coupling[{i}]", why + f"ratio {c['ratio']:g} of motor {c['motor']!r} on joint "
                                                  f"{c['joint']!r} makes it so (without it N is invertible)")
    key = "gear_ratio" if by_ratio else "transmission"
    zero_row = np.flatnonzero(~N.any(axis=1))
    if len(zero_row):
        return t.error(key if by_ratio else f"transmission.{zero_row[0]}",
                       why + f"motor {motors[zero_row[0]]!r} turns with no joint (its row of N is 0)")
    zero_column = np.flatnonzero(~N.any(axis=0))
    if len(zero_column):
        return t.error(key, why + f"no motor turns joint {joints[zero_column[0]]!r} (its column of N is 0)")
    u = np.linalg.svd(N)[0][:, -1]  # N^T u = 0: the motors' rows u combines to nothing
    dependent = [motors[k] for k in np.flatnonzero(np.abs(u) > 1e-6 * np.max(np.abs(u)))]
    return t.error(key, why + f"the rows of motors {', '.join(map(repr, dependent))} are linearly dependent: these "
                              "motors turn with the joints in a way the joints cannot be told from")
