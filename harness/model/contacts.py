"""A floating-base robot standing on its feet: a scenario's `[[contacts]]`, the bench's ground.

Each contact is a point of a body (`body`; `point`, where it is at q = 0, the file's pose, in world
components, as a model file's loops give theirs) that stays where it is at t = 0 while the base moves
along `[base_motion]`: the bench holds it there by a stiff connect constraint to the ground
(harness/engines/free_base.py), a planted foot that cannot slip or lift (bilateral: no friction cone,
no unilateral limit; the honest model of a foot that stays planted, as a closed chain's loop is). Within
a contact's `lift` (`from`, `to`, s, on the recording's grid) the constraint is released and the foot
swings: its joints move by `swing` (joint = displacement at the lift's middle) weighted by
w(s) = sin^4(pi s), s = (t - from) / (to - from), which starts and ends with w, w' and w'' zero, so the
foot leaves and lands on its point with no velocity or acceleration: the contacts change, no impact.

A contact is a point (`kind = "point"`, the default: a foot of a legged robot, its force alone) or a sole
(`kind = "sole"`: the body's whole frame held, as a flat foot standing on its sole; MuJoCo's weld, its force and
its moment about the point), the frame held the body's own as it stands at t = 0.

The joints from the base to a contact's body (its chain, at least three for a point, six for a sole) follow
from the contact: their [motion] gives the stance at t = 0 (a constant: a chain joint that moves is refused), and
the bench moves them so that the point stays put. With (R(t), p(t)) the base frame's pose, c_W the
ground point and (R_WF0, p_WF0) the base frame where the file draws it, the point must be, on the robot
read with its base fixed there (harness/model/loops.py's kinematics),

    x(q) = p_WF0 + R_WF0 y,    y = R^T r,  r = c_W - p,
    y'  = R^T (r' - omega x r),    y'' = R^T (r'' - alpha x r - 2 omega x r' + omega x (omega x r))

(omega, alpha the base's angular velocity and acceleration, world axes): Newton's method on x(q) = target
for the chain's joints at every time at once, then J q'_chain = x' and J q''_chain = x'' - b(q, q') (the
point's Jacobian and acceleration bias, loops.jacobian and loops.bias). A sole's frame, R_W its orientation
on the ground, must have on that robot the orientation, angular velocity and angular acceleration

    R_F = R_WF0 R^T R_W,    w_F = -R_WF0 R^T omega,    w'_F = -R_WF0 R^T alpha

(the ground's frame seen from the moving base): its three rows more, phi(R_now R_F^T) = 0 (the weld's
rotation vector, loops.py) and the angular rows of J and b.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from harness.base.tomlio import InputError, Table
from harness.model import loops as loop_eqs
from harness.model.kinematics import cross
from harness.model.spec import WORLD, Loop, RobotSpec

NEWTON_ITERATIONS = 30
NEWTON_TOLERANCE = 1e-13  # of the robot's size: the point's distance from its target after Newton's method
CONTACT_KINDS = ("point", "sole")
CHAIN_NEEDS = {"point": (3, "three"), "sole": (6, "six")}  # the joints a contact's chain needs: its constraint's rows


@dataclass(frozen=True)
class Lift:
    """A contact released from `start` to `end` (s), its chain's joints swung by `swing` at the middle."""

    start: float
    end: float
    swing: tuple[tuple[str, float], ...]  # (joint, displacement at the middle: rad or m)

    def weight(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """w(t), w'(t), w''(t): sin^4(pi s) within the lift, 0 outside (module docstring)."""
        T = self.end - self.start
        s = np.clip((t - self.start) / T, 0.0, 1.0)
        a = np.pi * s
        sn, cs = np.sin(a), np.cos(a)
        inside = (t > self.start) & (t < self.end)
        w = np.where(inside, sn**4, 0.0)
        wd = np.where(inside, 4.0 * np.pi * sn**3 * cs / T, 0.0)
        wdd = np.where(inside, 4.0 * np.pi**2 * (3.0 * sn**2 * cs**2 - sn**4) / T**2, 0.0)
        return w, wd, wdd


@dataclass(frozen=True, eq=False)
class Contact:
    """A point of `body` held on the ground (module docstring); `chain` the joints from the base to it."""

    name: str
    body: str
    point_W0: np.ndarray  # (3,) where the point is at q = 0, world components
    chain: tuple[str, ...]
    lift: Lift | None = None
    kind: str = "point"  # "point" (its force) or "sole" (the body's frame held: its force and moment)

    @property
    def sole(self) -> bool:
        return self.kind == "sole"

    def planted(self, t: np.ndarray) -> np.ndarray:
        """(N,) whether the contact holds at times t: outside its lift, and at the lift's two ends."""
        t = np.asarray(t, dtype=float)
        return np.ones(t.shape, dtype=bool) if self.lift is None else ~((t > self.lift.start) & (t < self.lift.end))

    def loop(self) -> Loop:
        """The point as a loop to the world's origin: its residual is where the point is (loops.py)."""
        return _to_origin(self)

    def held(self, x: np.ndarray, R: np.ndarray | None) -> Loop:
        """The contact as a loop to where it must be at each of N times, seen from the base (`_targets`): its
        point at x (N, 3), a sole's frame (the body's axes, the world's at q = 0) at R (N, 3, 3); loops.py's
        residual is then the distance (and rotation) still to go, its Jacobian and bias those of the contact."""
        if not self.sole:
            return Loop(self.name, "connect", self.body, WORLD, self.point_W0, x)
        return Loop(self.name, "weld", self.body, WORLD, self.point_W0, x, np.eye(3), R)


def _to_origin(c) -> Loop:
    """The point of `c` (a `body`, its `point_W0`) as a loop to the world's origin (loops.py's residual: the point)."""
    return Loop(c.name, "connect", c.body, WORLD, c.point_W0, np.zeros(3))


def read_contacts(root: Table, robot: RobotSpec, motions: dict, t_out: np.ndarray) -> tuple[Contact, ...]:
    """`[[contacts]]` (`name`, `body`, `point`, optional `kind = "point" | "sole"` and `lift = { from, to, swing =
    { joint = value } }`), validated: beside `[base_motion]` only, on a body of the robot that is not its base,
    chains of at least three joints (six for a sole) that share none, a chain's joints held by their [motion] (the
    stance), a lift on the recording's grid `t_out`. () without the table."""
    if not root.has("contacts"):
        if "contact_wrenches" in root.data.get("measurement", {}).get("noise", {}):
            raise root.error("measurement.noise.contact_wrenches", "contact wrenches are recorded only where the "
                                                                   "robot stands on [[contacts]]")
        return ()
    if not root.has("base_motion"):
        raise root.error("contacts", "contacts hold a floating base the bench moves: the scenario needs "
                                     "[base_motion]")
    out, owner = [], {}
    bodies = {b.name for b in robot.massive_bodies}
    for t in root.tables("contacts"):
        name = t.string("name")
        body = t.string("body")
        if name in {c.name for c in out}:
            raise t.error("name", f"contact {name!r} is named twice")
        if body not in bodies:
            why = " (the base: a contact on it holds no joint)" if body == robot.floating.body.name else ""
            raise t.error("body", f"no moving body {body!r} in model {robot.name!r}{why}")
        kind = t.string("kind", "point", choices=CONTACT_KINDS)
        chain = tuple(j for j, c in zip(robot.joint_names, loop_eqs.carried(robot, body), strict=True) if c)
        needs, in_words = CHAIN_NEEDS[kind]
        if len(chain) < needs:
            raise t.error("body", f"{len(chain)} joint(s) between the base and {body!r}: a {kind} held on the ground "
                                  f"needs {in_words}")
        for j in chain:
            if j in owner:
                raise t.error("body", f"joint {j!r} carries contact {owner[j]!r} too: each contact needs joints of "
                                      "its own")
            owner[j] = name
            if np.any(motions[j].evaluate(t_out)[1] != 0.0):
                raise root.error(f"motion.{j}", f"moves a joint that holds contact {name!r}: its motion gives "
                                                "the stance (a constant), the bench moves it to keep the point put")
        lift = _read_lift(t.table("lift"), chain, t_out) if t.has("lift") else None
        point = t.vector("point")
        t.finish()
        out.append(Contact(name, body, point, chain, lift, kind))
    return tuple(out)


def _read_lift(t: Table, chain: tuple[str, ...], t_out: np.ndarray) -> Lift:
    start, end = t.number("from", nonnegative=True), t.number("to", positive=True)
    if not start < end <= t_out[-1]:
        raise t.error("to", f"a lift from {start:g} s to {end:g} s: it must end after it starts and by the "
                            f"recording's end, {t_out[-1]:g} s")
    step = t_out[1] - t_out[0]
    for key, value in (("from", start), ("to", end)):
        if abs(value / step - round(value / step)) > 1e-9:
            raise t.error(key, f"{value:g} s is not on the recording's grid (every {step:g} s): the bench "
                               "releases and holds a contact between rows")
    swing = t.table("swing")
    values = tuple((j, swing.number(j)) for j in list(swing.data))
    for j, _ in values:
        if j not in chain:
            raise swing.error(j, f"not a joint of the contact's chain ({', '.join(chain)})")
    swing.finish()
    t.finish()
    return Lift(start, end, values)


def contact_points(spec: RobotSpec, contacts: tuple, base, q: np.ndarray) -> np.ndarray:
    """(N, k, 3) each contact's point (anything with a `body` and its `point_W0`: a Contact, a log's contact) in
    the world at the states (base, q) (N states, a harness.model.floating.BaseMotion and (N, n)): where the robot
    read with its base where the file draws it has it, moved with the base, p + R R_WF0^T (x - p_WF0) (as rows:
    p + (x - p_WF0) R_WF0 R^T)."""
    fb = spec.floating
    x = np.stack([loop_eqs.joined_points(spec, (_to_origin(c),), q)[0][0] for c in contacts], axis=1)  # fixed robot
    return base.p_W[:, None] + (x - fb.p_WF0) @ fb.R_WF0 @ np.swapaxes(base.R_WB, 1, 2)


def contact_axes(spec: RobotSpec, contacts: tuple, base_R_WB: np.ndarray, q: np.ndarray) -> np.ndarray:
    """(N, k, 3, 3) the axes of each contact's frame in the world (anything with a `body` and its frame's
    orientation at q = 0 in world, `R_W0`: a sensor on the body), at the base's orientations base_R_WB (N, 3, 3)
    and the joints at q (N, n): the frame on the robot read where the file draws it, turned with the base as
    `contact_points` moves a point, R R_WF0^T R_frame."""
    R_frame = loop_eqs.frames_now(spec, tuple((c.body, c.R_W0) for c in contacts), q)
    return base_R_WB[:, None] @ spec.floating.R_WF0.T @ R_frame


def ground_points(spec: RobotSpec, contacts: tuple[Contact, ...], base0, q0: np.ndarray) -> np.ndarray:
    """(k, 3) each contact's point on the ground: where it is at t = 0, the base at `base0` (a one-state
    harness.model.floating.BaseMotion) and the joints at q0 (n,)."""
    return contact_points(spec, contacts, base0, q0[None])[0]


def _targets(spec: RobotSpec, c_W: np.ndarray, base) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(N, k, 3) x, x', x'': where each ground point is seen from the base, on the robot whose base is
    where the file draws it (module docstring)."""
    fb = spec.floating
    R_T = np.swapaxes(base.R_WB, 1, 2)[:, None]  # (N, 1, 3, 3)
    r = c_W[None] - base.p_W[:, None]
    rd, rdd = -base.v_W[:, None], -base.a_W[:, None]
    w, al = base.omega_W[:, None], base.alpha_W[:, None]
    y = (R_T @ r[..., None])[..., 0]
    yd = (R_T @ (rd - cross(w, r))[..., None])[..., 0]
    ydd = (R_T @ (rdd - cross(al, r) - 2.0 * cross(w, rd) + cross(w, cross(w, r)))[..., None])[..., 0]
    return fb.p_WF0 + y @ fb.R_WF0.T, yd @ fb.R_WF0.T, ydd @ fb.R_WF0.T


def _frame_targets(spec: RobotSpec, R_W: np.ndarray, base) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A sole's frame on the ground, R_W (3, 3), seen from the base: its orientation R_F (N, 3, 3), angular
    velocity w_F and acceleration w'_F (N, 3) on the robot whose base is where the file draws it (module
    docstring: the ground's frame is still, the base turns with omega)."""
    turn = spec.floating.R_WF0 @ np.swapaxes(base.R_WB, 1, 2)  # (N, 3, 3) world axes -> the fixed robot's
    return turn @ R_W, -(turn @ base.omega_W[..., None])[..., 0], -(turn @ base.alpha_W[..., None])[..., 0]


def ground_frames(spec: RobotSpec, contacts: tuple[Contact, ...], base0, q0: np.ndarray) -> np.ndarray:
    """(k, 3, 3) each contact's frame on the ground (the body's axes, the world's at q = 0): its orientation at
    t = 0, the base at `base0` and the joints at q0 (n,) (a point's too, unused)."""
    R_frame = loop_eqs.frames_now(spec, tuple((c.body, np.eye(3)) for c in contacts), q0[None])[0]
    return base0.R_WB[0] @ spec.floating.R_WF0.T @ R_frame


def stance(spec: RobotSpec, contacts: tuple[Contact, ...], base_at: Callable, given: Callable, source) -> Callable:
    """t -> (q, q', q''), each (N, n): `given`'s motion with every contact's chain moved to keep its point
    (a sole: its frame) on the ground while the base moves along `base_at` (t -> BaseMotion), swung within its
    lift (module docstring). A contact out of its chain's reach is bad input, named by the contact and the time."""
    def motion(t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        t = np.atleast_1d(np.asarray(t, dtype=float))
        q, qd, qdd = (np.array(x, dtype=float) for x in given(t))
        base, base0, q0 = base_at(t), base_at(np.zeros(1)), given(np.zeros(1))[0][0]
        c_W = ground_points(spec, contacts, base0, q0)
        R_W = ground_frames(spec, contacts, base0, q0) if any(c.sole for c in contacts) else None
        x, xd, xdd = _targets(spec, c_W, base)
        size = max(1.0, float(np.max(np.abs(c_W))))
        for k, c in enumerate(contacts):
            cols = [spec.joint_names.index(j) for j in c.chain]
            R_F, v, a = _frame_targets(spec, R_W[k], base) if c.sole else (None, xd[:, k, :0], xdd[:, k, :0])
            loop = (c.held(x[:, k], R_F),)
            for _ in range(NEWTON_ITERATIONS):
                r, J = loop_eqs.residual_and_jacobian(spec, loop, q)
                if np.max(np.abs(r)) <= NEWTON_TOLERANCE * size:
                    break
                q[:, cols] -= (np.linalg.pinv(J[:, :, cols]) @ r[..., None])[..., 0]
            else:
                worst = int(np.argmax(np.max(np.abs(r), axis=1)))
                raise InputError(source, "contacts", f"contact {c.name!r}: its {c.kind} cannot stay on the ground "
                                                     f"at t = {t[worst]:.6g} s (out of its chain's reach)")
            J_p = np.linalg.pinv(loop_eqs.jacobian(spec, loop, q)[:, :, cols])
            qd[:, cols] = (J_p @ np.concatenate([xd[:, k], v], axis=1)[..., None])[..., 0]
            b = loop_eqs.bias(spec, loop, q, qd)
            qdd[:, cols] = (J_p @ (np.concatenate([xdd[:, k], a], axis=1) - b)[..., None])[..., 0]
            if c.lift is not None:
                w, wd, wdd = c.lift.weight(t)
                for j, value in c.lift.swing:
                    i = spec.joint_names.index(j)
                    q[:, i] += w * value
                    qd[:, i] += wd * value
                    qdd[:, i] += wdd * value
        return q, qd, qdd

    return motion


def generalised_force(spec: RobotSpec, contacts: tuple[Contact, ...], base, q: np.ndarray, F_W: np.ndarray,
                      M_W: np.ndarray, x_W: np.ndarray) -> np.ndarray:
    """(N, 6 + n) what the contacts' wrenches (F_W, M_W each (N, k, 3), M about the point x_W (N, k, 3)) exert
    on the robot at the states (base, q), in the harness's rows (harness/model/floating.py): the base's
    [sum F; sum (x - p_WB) x F + M] (world axes, about the base origin), then each joint's J^T [F; M], J the
    contact body's point and angular Jacobian on the robot read with its base where the file draws it
    (loops.body_jacobian, at the point seen there), the wrench turned into that robot's axes (R_WF0 R_WB^T).
    Kinematics alone: no engine."""
    fb = spec.floating
    out = np.zeros((len(q), 6 + len(spec.joints)))
    turn = fb.R_WF0 @ np.swapaxes(base.R_WB, 1, 2)  # (N, 3, 3) world axes -> the fixed robot's
    for k, c in enumerate(contacts):
        F, M = F_W[:, k], M_W[:, k]
        out[:, :3] += F
        out[:, 3:6] += cross(x_W[:, k] - base.p_W, F) + M
        x = fb.p_WF0 + (turn @ (x_W[:, k] - base.p_W)[..., None])[..., 0]
        J = loop_eqs.body_jacobian(spec, c.body, q, x)
        wrench = np.concatenate([(turn @ F[..., None])[..., 0], (turn @ M[..., None])[..., 0]], axis=1)
        out[:, 6:] += (np.swapaxes(J, 1, 2) @ wrench[..., None])[..., 0]
    return out
