"""Prescribed joint motions: q(t), q'(t), q''(t) for one joint, evaluated for many times at once.

Each motion type is a small dataclass read from a `[motion.<joint>]` table of a scenario file.
Positions are joint coordinates: radians for revolute joints, metres for prismatic ones, zero at
the model's initial pose.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar, Protocol

import numpy as np

from harness.base.tomlio import Table

if TYPE_CHECKING:
    from harness.model.spec import RobotSpec


class Motion(Protocol):
    kind: ClassVar[str]

    def evaluate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(q, q', q'') at times t, each of shape t.shape."""
        ...

    def describe(self) -> str: ...


@dataclass(frozen=True)
class Locked:
    """Held at a fixed position: q = position."""

    position: float = 0.0
    kind: ClassVar[str] = "locked"

    @classmethod
    def from_table(cls, t: Table) -> Locked:
        return cls(t.number("position", default=0.0))

    def evaluate(self, t):
        zero = np.zeros_like(t, dtype=float)
        return zero + self.position, zero, zero.copy()

    def describe(self) -> str:
        return f"locked at {self.position:g}"


@dataclass(frozen=True)
class ConstantAcceleration:
    """q = position + velocity t + acceleration t^2 / 2."""

    acceleration: float
    position: float = 0.0
    velocity: float = 0.0
    kind: ClassVar[str] = "constant_acceleration"

    @classmethod
    def from_table(cls, t: Table) -> ConstantAcceleration:
        return cls(t.number("acceleration"), t.number("position", default=0.0),
                   t.number("velocity", default=0.0))

    def evaluate(self, t):
        t = np.asarray(t, dtype=float)
        q = self.position + self.velocity * t + 0.5 * self.acceleration * t**2
        return q, self.velocity + self.acceleration * t, np.full_like(t, self.acceleration)

    def describe(self) -> str:
        return (f"constant acceleration {self.acceleration:g} from q={self.position:g}, "
                f"q'={self.velocity:g}")


@dataclass(frozen=True)
class Polynomial:
    """q = sum_k c_k t^k with coefficients [c_0, c_1, ...]."""

    coefficients: tuple[float, ...]
    kind: ClassVar[str] = "polynomial"

    @classmethod
    def from_table(cls, t: Table) -> Polynomial:
        return cls(tuple(t.vector("coefficients", length=None)))

    def evaluate(self, t):
        t = np.asarray(t, dtype=float)
        c = np.polynomial.Polynomial(self.coefficients or (0.0,))
        return c(t), c.deriv(1)(t), c.deriv(2)(t)

    def describe(self) -> str:
        return "polynomial " + " + ".join(f"{c:g} t^{k}" for k, c in enumerate(self.coefficients))


@dataclass(frozen=True)
class Sinusoids:
    """q = offset + sum a_k sin(w_k t) + sum b_k cos(v_k t); `sin` and `cos` list [amplitude, omega]."""

    offset: float = 0.0
    sin: tuple[tuple[float, float], ...] = ()
    cos: tuple[tuple[float, float], ...] = ()
    kind: ClassVar[str] = "sinusoids"

    @classmethod
    def from_table(cls, t: Table) -> Sinusoids:
        return cls(t.number("offset", default=0.0), _pairs(t, "sin"), _pairs(t, "cos"))

    def evaluate(self, t):
        t = np.asarray(t, dtype=float)
        q = np.full_like(t, self.offset)
        qd, qdd = np.zeros_like(t), np.zeros_like(t)
        for a, w in self.sin:
            q += a * np.sin(w * t)
            qd += a * w * np.cos(w * t)
            qdd -= a * w**2 * np.sin(w * t)
        for a, w in self.cos:
            q += a * np.cos(w * t)
            qd -= a * w * np.sin(w * t)
            qdd -= a * w**2 * np.cos(w * t)
        return q, qd, qdd

    def describe(self) -> str:
        terms = [f"{a:g} sin({w:g} t)" for a, w in self.sin] + [f"{a:g} cos({w:g} t)" for a, w in self.cos]
        return " + ".join([f"{self.offset:g}"] + terms)


@dataclass(frozen=True)
class Exponential:
    """q = offset + amplitude exp(rate t)."""

    amplitude: float
    rate: float
    offset: float = 0.0
    kind: ClassVar[str] = "exponential"

    @classmethod
    def from_table(cls, t: Table) -> Exponential:
        return cls(t.number("amplitude"), t.number("rate"), t.number("offset", default=0.0))

    def evaluate(self, t):
        e = self.amplitude * np.exp(self.rate * np.asarray(t, dtype=float))
        return self.offset + e, self.rate * e, self.rate**2 * e

    def describe(self) -> str:
        return f"{self.offset:g} + {self.amplitude:g} exp({self.rate:g} t)"


def _pairs(t: Table, name: str) -> tuple[tuple[float, float], ...]:
    return tuple((float(a), float(w)) for a, w in t.rows(name, columns=2, default=[]))


MOTION_TYPES: dict[str, type] = {m.kind: m for m in (Locked, ConstantAcceleration, Polynomial, Sinusoids,
                                                      Exponential)}


def read_motion(t: Table) -> Motion:
    kind = t.string("type", choices=tuple(MOTION_TYPES))
    motion = MOTION_TYPES[kind].from_table(t)
    t.finish()
    return motion


def read_scenario_motions(motion_table: Table, robot: RobotSpec, duration: float,
                          output_steps: int) -> dict[str, Motion]:
    """`[motion]`: every joint of the robot (a closed chain's actuated ones), no other, finite over the run."""
    motion = {}
    for name in motion_table.data:
        if name not in robot.joint_names:
            raise motion_table.error(name, f"joint {name!r} is not in model {robot.name!r} "
                                           f"(joints: {', '.join(robot.joint_names)})")
        if robot.loops and name not in robot.actuated:
            raise motion_table.error(name, f"joint {name!r} is passive: its motion follows from the loops of "
                                           f"{robot.name!r} (actuated: {', '.join(robot.actuated)})")
    for j in (robot.actuated if robot.loops else robot.joint_names):
        if j not in motion_table.data:
            raise motion_table.error(j, f"missing: every joint of model {robot.name!r} needs a "
                                        "motion (use type = \"locked\" to hold it)")
        motion[j] = read_motion(motion_table.table(j))
        with np.errstate(over="ignore", invalid="ignore"):
            values = np.stack(motion[j].evaluate(np.linspace(0.0, duration, output_steps + 1)))
        if not np.all(np.isfinite(values)):
            bad = np.flatnonzero(~np.all(np.isfinite(values), axis=0))[0]
            raise motion_table.error(j, f"the motion is not finite within the run (from t = "
                                        f"{bad * duration / output_steps:g} s on, q, q' or q'' overflows)")
    motion_table.finish()
    return motion
