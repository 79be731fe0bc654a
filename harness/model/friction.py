"""Joint friction and rotor inertia: the torque a joint's drive adds to the rigid-body torque.

    tau_J = tau_rigid + I_a q'' + f_v q' + f_c s(q') + f_o,   s(q') = tanh(q' / v_c)  (v_c > 0)
                                                               s(q') = sign(q')        (v_c = 0)

per joint: `armature` I_a (the rotor's inertia reflected through the gear, kg m^2 or kg), `viscous`
f_v, `coulomb` f_c, `offset` f_o (a constant torque: a sensor's bias, an unbalanced cable) and
`coulomb_velocity` v_c, the velocity over which the Coulomb term turns (0: a sharp sign). This is
the friction model of the literature on arm identification (Gautier and Khalil; Gaz et al. 2019
with a sigmoid in place of the sign). It is written once, here; every engine and model takes it
from here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

FRICTION_KEYS = ("armature", "viscous", "coulomb", "offset", "coulomb_velocity")
IDENTIFIED_KEYS = ("armature", "viscous", "coulomb", "offset")  # linear in the torque: identifiable


@dataclass(frozen=True)
class JointFriction:
    armature: float = 0.0
    viscous: float = 0.0
    coulomb: float = 0.0
    offset: float = 0.0
    coulomb_velocity: float = 0.0

    @property
    def none(self) -> bool:
        return not (self.armature or self.viscous or self.coulomb or self.offset)

    def as_dict(self) -> dict[str, float]:
        return {k: float(getattr(self, k)) for k in FRICTION_KEYS}


NO_FRICTION = JointFriction()


def coulomb_shape(qd: np.ndarray, coulomb_velocity: np.ndarray) -> np.ndarray:
    """s(q'), (N, n): tanh(q' / v_c) where v_c > 0, sign(q') where v_c = 0."""
    v = np.asarray(coulomb_velocity, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        smooth = np.tanh(qd / np.where(v > 0, v, 1.0))
    return np.where(v > 0, smooth, np.sign(qd))


def columns(frictions: tuple[JointFriction, ...], qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
    """(N, n, 4): per joint the regressor of [armature, viscous, coulomb, offset]: q'', q', s(q'), 1."""
    v = np.array([f.coulomb_velocity for f in frictions])
    return np.stack([qdd, qd, coulomb_shape(qd, v), np.ones_like(qd)], axis=-1)


def values(frictions: tuple[JointFriction, ...]) -> np.ndarray:
    """(n, 4): [armature, viscous, coulomb, offset] per joint."""
    return np.array([[getattr(f, k) for k in IDENTIFIED_KEYS] for f in frictions]).reshape(-1, 4)


def torque(frictions: tuple[JointFriction, ...], qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
    """(N, n): I_a q'' + f_v q' + f_c s(q') + f_o of every joint."""
    return np.einsum("nja,ja->nj", columns(frictions, qd, qdd), values(frictions))


def passive(frictions: tuple[JointFriction, ...], qd: np.ndarray) -> np.ndarray:
    """(..., n): the part that depends on the velocity alone, f_v q' + f_c s(q') + f_o (what an
    engine applies as a force; the armature enters its mass matrix)."""
    v = np.array([f.coulomb_velocity for f in frictions])
    k = values(frictions)
    return k[:, 1] * qd + k[:, 2] * coulomb_shape(qd, v) + k[:, 3]
