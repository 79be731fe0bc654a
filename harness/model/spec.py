"""RobotSpec: a tree of rigid bodies and one-degree-of-freedom joints, as harness/model/load.py
reads it from a model file (TOML, or a URDF or MJCF named by one), and the loops that close it when
it is a closed chain's (harness/model/loops.py). Geometry in the world frame at the initial
pose (all joint coordinates zero): each body's centre of mass `p_W_com0`, principal axes `R_WB0` and
moments `I_B`; each joint's point `p_W0` and axis `axis_W0`."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from harness.model.drives import Transmission
from harness.model.friction import NO_FRICTION, JointFriction

WORLD = "world"
JOINT_TYPES = ("revolute", "prismatic")
BODY_SHAPES = ("cylinder", "rod", "point", "explicit", "massless")
LOOP_KINDS = ("connect", "weld", "joint")
FLOATING_BASE_FIXED = "the floating base is taken as fixed to the world at the file's pose"  # ends its note


@dataclass(frozen=True)
class Cylinder:
    """A homogeneous cylinder whose axis is the body's e1 direction."""

    length: float
    radius: float
    density: float

    @property
    def mass(self) -> float:
        return self.density * np.pi * self.radius**2 * self.length

    @property
    def principal_inertia(self) -> np.ndarray:
        """[J11, J22, J33] about the centre of mass (Eq. 24)."""
        m, r, l = self.mass, self.radius, self.length
        transverse = m * (3.0 * r**2 + l**2) / 12.0
        return np.array([m * r**2 / 2.0, transverse, transverse])


@dataclass(frozen=True, eq=False)
class Body:
    """A rigid body B_i. Frames: W is the world frame e(0), B the body frame e(i) at O_ci."""

    name: str
    mass: float  # kg; 0 only for a massless body
    I_B: np.ndarray  # (3, 3) inertia tensor about the centre of mass, body components
    R_WB0: np.ndarray  # (3, 3) orientation at the initial pose: columns e1(i), e2(i), e3(i)
    p_W_com0: np.ndarray  # (3,) centre of mass O_ci at the initial pose
    cylinder: Cylinder | None = None

    @property
    def massless(self) -> bool:
        return self.mass == 0.0

    @property
    def principal_inertia(self) -> np.ndarray:
        """[J11, J22, J33]: the diagonal of I_B (the body axes are principal axes)."""
        return np.diag(self.I_B).copy()

    def arm_B(self, point_W0: np.ndarray) -> np.ndarray:
        """(3,) the body-fixed vector from O_ci to a point of the body given at the initial pose
        (a joint point O_J: the paper's c_{i,j}), in body components."""
        return self.R_WB0.T @ (np.asarray(point_W0) - self.p_W_com0)


@dataclass(frozen=True, eq=False)
class Joint:
    """A joint O_j between its inner (parent) and outer (child) body."""

    name: str
    type: str  # "revolute" or "prismatic"
    parent: str  # body name or "world"
    child: str
    p_W0: np.ndarray  # (3,) joint point at the initial pose
    axis_W0: np.ndarray  # (3,) unit axis at the initial pose
    friction: JointFriction = NO_FRICTION  # rotor inertia and friction of its drive (harness/model/friction.py)

    @property
    def revolute(self) -> bool:
        return self.type == "revolute"


@dataclass(frozen=True, eq=False)
class Loop:
    """A loop closure: a point (connect) or a frame (weld) of body a joined to one of body b, or a
    coupling of two joints (joint: q_follower = ratio q_leader + offset, a URDF <mimic> or an MJCF
    joint equality) (harness/model/loops.py gives its constraint equations)."""

    name: str
    kind: str  # "connect", "weld" or "joint"
    body_a: str  # a spec body, or WORLD (a coupling: WORLD, it joins no point)
    body_b: str
    point_a_W0: np.ndarray  # (3,) the joined point of body a where it is at q = 0, world components
    point_b_W0: np.ndarray  # (3,) that of body b
    R_W_frame_a0: np.ndarray | None = None  # weld: (3, 3) the joined frame of body a at q = 0
    R_W_frame_b0: np.ndarray | None = None
    follower: str = ""  # joint: the joint that follows (no degree of freedom of its own)
    leader: str = ""  # joint: the joint it follows
    ratio: float = 1.0  # joint: q_follower = ratio q_leader + offset (rad or m, as each joint moves)
    offset: float = 0.0

    @classmethod
    def coupling(cls, name: str, follower: str, leader: str, ratio: float, offset: float) -> Loop:
        """A joint coupling q_follower = ratio q_leader + offset."""
        zero = np.zeros(3)
        return cls(name, "joint", WORLD, WORLD, zero, zero, follower=follower, leader=leader, ratio=float(ratio),
                   offset=float(offset))

    @property
    def rows(self) -> int:
        return {"connect": 3, "weld": 6, "joint": 1}[self.kind]

    @property
    def joins_points(self) -> bool:
        """Whether the loop joins two points (connect, weld), not two joints' coordinates."""
        return self.kind != "joint"


@dataclass(frozen=True, eq=False)
class FloatingBase:
    """A floating base (harness/model/floating.py): the file's six-degree-of-freedom joint from the world
    and the rigid body it moves, in the world frame at q = 0 (the file's pose), with what is fixed to it.
    The spec's joints from the world are on this body; a reader of fixed bases takes it fixed there."""

    joint: str  # the file's name of the free (MJCF) or floating (URDF) joint
    body: Body
    R_WF0: np.ndarray  # (3, 3) the base's frame F (the MJCF body's, the URDF link's) at q = 0
    p_WF0: np.ndarray  # (3,) its origin: the free joint's pose is F's (harness/model/floating.py)
    joints: tuple[str, ...] = ()  # the spec's joints from the world that are on the base (an MJCF file's other
    # root bodies' joints are on the ground)


@dataclass(frozen=True, eq=False)
class RobotSpec:
    """A validated tree. Bodies and joints are ordered from the root outwards."""

    name: str
    description: str
    source: Path
    bodies: tuple[Body, ...]
    joints: tuple[Joint, ...]
    dh: tuple[tuple[float, float, float, float], ...] | None = None  # (alpha, a, d, theta) when given
    limits: dict[str, tuple[float, float]] | None = None  # joint position limits, when the source has them
    urdf: Path | None = None  # the URDF it was read from, if any
    urdf_fixed: tuple[str, ...] = ()  # joints of that URDF taken as fixed
    drive_limits: dict[str, dict[str, float]] | None = None  # per joint "velocity" and "effort", when given
    gravity_W: np.ndarray | None = None  # (3,) m/s^2 where the description states it (an MJCF's <option>)
    mjcf: Path | None = None  # the MJCF it was read from, if any
    notes: tuple[str, ...] = ()  # what reading it assumed, one line each (a floating base fixed to the world)
    transmission: Transmission | None = None  # the drives' N and offsets (harness/model/drives.py); None: each
    # joint driven on its own through a ratio already folded into its friction and rotor inertia
    loops: tuple[Loop, ...] = ()  # loop closures (harness/model/loops.py): the tree is a closed chain's
    actuated: tuple[str, ...] = ()  # a closed chain's actuated joints (the others are passive)
    floating: FloatingBase | None = None  # the file's floating base, which every fixed-base reading fixes at
    # the file's pose (said in `notes`); harness/engines/floating.py judges the robot with it free
    cones: dict[str, tuple[tuple[str, ...], float]] | None = None  # an MJCF ball joint's range: its hinges and
    # the largest angle (rad) its rotation may reach

    def body(self, name: str) -> Body:
        return next(b for b in self.bodies if b.name == name)

    def joint(self, name: str) -> Joint:
        return next(j for j in self.joints if j.name == name)

    @property
    def joint_names(self) -> list[str]:
        return [j.name for j in self.joints]

    @property
    def massive_bodies(self) -> tuple[Body, ...]:
        """The bodies that carry mass: the paper's B_1 .. B_n."""
        return tuple(b for b in self.bodies if not b.massless)

    @property
    def frictions(self) -> tuple[JointFriction, ...]:
        """Each drive's law, in the spec's joint order: joint k's own, or with a transmission motor k's
        (in motor units; motor k is row k of N: harness/model/drives.py)."""
        return tuple(j.friction for j in self.joints)

    @property
    def drive_names(self) -> list[str]:
        """Who each of `frictions` belongs to: the joints, or the transmission's motors."""
        return list(self.transmission.motors) if self.transmission is not None else self.joint_names

    def with_frictions(self, frictions: tuple[JointFriction, ...]) -> RobotSpec:
        """The same robot with each joint's friction law replaced, in joint order."""
        return dataclasses.replace(self, joints=tuple(dataclasses.replace(j, friction=f)
                                                      for j, f in zip(self.joints, frictions, strict=True)))

    def rigid(self) -> RobotSpec:
        """The same robot without its drives and their friction and rotor inertia: the rigid bodies alone."""
        joints = tuple(dataclasses.replace(j, friction=NO_FRICTION) for j in self.joints)
        return dataclasses.replace(self, joints=joints, transmission=None)

    def inner_joint(self, body: str) -> Joint:
        return next(j for j in self.joints if j.child == body)

    def inner_joint_arms_B(self) -> np.ndarray:
        """(nb, 3) for each massive body, the arm from its centre of mass to its inner joint point
        O (where aO_W is recorded), in body components."""
        return np.array([b.arm_B(self.inner_joint(b.name).p_W0) for b in self.massive_bodies]).reshape(-1, 3)

    def outer_joints(self, body: str) -> list[Joint]:
        return [j for j in self.joints if j.parent == body]

    def subtree(self, body: str) -> list[str]:
        """The body and every body outboard of it, root first."""
        out = [body]
        for j in self.outer_joints(body):
            out += self.subtree(j.child)
        return out

    def massive_parent(self, body: str) -> tuple[str, list[Joint]]:
        """The nearest massive ancestor of `body` (or the world) and the joints from it to `body`, inner
        first: more than one where massless carriages lie between them."""
        chain = [self.inner_joint(body)]
        parent = chain[0].parent
        while parent != WORLD and self.body(parent).massless:
            chain.insert(0, self.inner_joint(parent))
            parent = chain[0].parent
        return parent, chain

    def hinge_chains(self) -> list[list[Joint]]:
        """Each chain of two or more hinges through massless carriages (`massive_parent`), inner first: a ball
        joint read as its three hinges, a universal joint (a rail's slide and hinge is not one)."""
        chains = (self.massive_parent(b.name)[1] for b in self.massive_bodies)
        return [c for c in chains if len(c) > 1 and all(j.revolute for j in c)]

    def carried_joint(self, joint: str) -> Joint:
        """The joint itself, or, for the inner joint of a massless carriage, the joint the carriage
        carries: they share point and wrench, and its child is the massive body that moves."""
        j = self.joint(joint)
        while self.body(j.child).massless:
            j = self.outer_joints(j.child)[0]
        return j

    def outboard_bodies(self, joint: str) -> list[Body]:
        """Bodies whose motion the joint carries (the child's subtree), in tree order."""
        names = set(self.subtree(self.joint(joint).child))
        return [b for b in self.bodies if b.name in names]


