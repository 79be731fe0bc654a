"""Drives: the motors behind the joints and the transmission between them, as a lab measures an arm.

A motor k turns with a linear combination of the joints (a gear, a belt, a coupled wrist):

    q_m = N q + o,        q'_m = N q',        q''_m = N q''              (N invertible, n x n)

and, by virtual work (tau_J . q' = tau_m . q'_m for every q'), the torques the motors apply reach the
joints as

    tau_J = N^T tau_m.

N's entries are the gear ratios, of either sign, and the couplings (the Staubli TX40's motor 6 turns
with q5 + q6: N[6, 5] = N[6, 6] = 32). Each motor has its own drive law (harness/model/friction.py: rotor
inertia I_m, viscous and Coulomb friction, an offset and a family's terms), in motor units, acting on
its own motion: the motor must supply tau_m = N^-T tau_R + f_m(q'_m, q''_m), so the joints carry

    tau_J = tau_R + N^T f_m(N q', N q'', N^-T tau_R):

a rotor inertia reflects as N^T diag(I_m) N (off the diagonal where N couples), a friction acts on N q'.
A diagonal N reduces to one term per joint; where a model states no drives, the joints' own laws are
the motors' (N the identity: every figure as it was). `Transmission` is N and o; the drive law through
it is written once here (`torque`, `columns`, `mass`, `reach`), and every engine and fit takes it from here.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from harness.model import friction
from harness.model.friction import JointFriction


@dataclass(frozen=True, eq=False)
class Transmission:
    """q_m = N q + offset; tau_J = N^T tau_m. Rows: motors (named `motors`), columns: the spec's joints."""

    N: np.ndarray  # (n, n) invertible
    offset: np.ndarray  # (n,) each motor's position at q = 0 (rad, or m of a linear motor)
    motors: tuple[str, ...]
    N_inv: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        object.__setattr__(self, "N_inv", np.linalg.inv(self.N))

    @property
    def diagonal(self) -> bool:
        return bool(np.all(self.N == np.diag(np.diag(self.N))))

    @property
    def coupled(self) -> list[tuple[int, list[int]]]:
        """The motors that turn with more than one joint, each with its joints (indices)."""
        return [(k, [int(j) for j in np.flatnonzero(row)]) for k, row in enumerate(self.N) if np.count_nonzero(row) > 1]

    def motor_positions(self, q: np.ndarray) -> np.ndarray:
        """(..., n) joint positions -> motor positions, N q + offset."""
        return q @ self.N.T + self.offset

    def joint_positions(self, q_m: np.ndarray) -> np.ndarray:
        """(..., n) motor positions -> joint positions, N^-1 (q_m - offset)."""
        return (q_m - self.offset) @ self.N_inv.T

    def motor_rates(self, qd: np.ndarray) -> np.ndarray:
        """(..., n) joint velocities (or accelerations) -> the motors', N q'."""
        return qd @ self.N.T

    def joint_rates(self, qd_m: np.ndarray) -> np.ndarray:
        """(..., n) motor velocities (or accelerations) -> the joints', N^-1 q'_m."""
        return qd_m @ self.N_inv.T

    def joint_torques(self, tau_m: np.ndarray) -> np.ndarray:
        """(..., n) motor torques -> what they apply at the joints, N^T tau_m."""
        return tau_m @ self.N

    def motor_torques(self, tau: np.ndarray) -> np.ndarray:
        """(..., n) joint torques -> the motor torques that apply them, N^-T tau."""
        return tau @ self.N_inv

    def describe(self, joints: tuple[str, ...] | list[str]) -> dict:
        """N, the offsets and the coupled motors with the names of their joints (the spec's, in order)."""
        return {"motors": list(self.motors), "N": self.N.tolist(), "offset": self.offset.tolist(),
                "coupled": {self.motors[k]: [joints[j] for j in js] for k, js in self.coupled}}


def torque(frictions: tuple[JointFriction, ...], transmission: Transmission | None, qd: np.ndarray,
           qdd: np.ndarray, tau_rigid: np.ndarray | None = None, q: np.ndarray | None = None) -> np.ndarray:
    """(N, n) at the joints: the drives' law (one per motor, `frictions`) through the transmission,
    N^T f_m(N q + offset, N q', N q'', N^-T tau_R); the joints' own laws where there is no transmission
    (q, the joints' positions, read by a spring)."""
    if transmission is None:
        return friction.torque(frictions, qd, qdd, tau_rigid, q)
    t = transmission
    rigid_m = None if tau_rigid is None else t.motor_torques(tau_rigid)
    qd_m, q_m = at_drives(t, qd, q)
    return t.joint_torques(friction.torque(frictions, qd_m, t.motor_rates(qdd), rigid_m, q_m))


def at_drives(transmission: Transmission | None, qd: np.ndarray, q: np.ndarray | None = None
              ) -> tuple[np.ndarray, np.ndarray | None]:
    """(q', q) at the drives: the joints' own, or through the transmission the motors' (N q', N q + offset)."""
    if transmission is None:
        return qd, q
    return transmission.motor_rates(qd), None if q is None else transmission.motor_positions(q)


def reach(transmission: Transmission | None, n: int) -> list[tuple[int, int, float]]:
    """Where each drive's torque reaches the joints, by tau_J = N^T tau_m column by column: (joint j,
    drive k, N[k, j]) for every N[k, j] != 0, joint by joint; without a transmission each joint's own
    law, (j, j, 1.0). Every regressor column of a drive term (rotor inertia, friction, the families'
    terms) is its motor's column times N[k, j] on joint j's rows: written here once."""
    if transmission is None:
        return [(j, j, 1.0) for j in range(n)]
    return [(int(j), int(k), float(transmission.N[k, j])) for j, k in zip(*np.nonzero(transmission.N.T), strict=True)]


def columns(frictions: tuple[JointFriction, ...], transmission: Transmission | None, qd: np.ndarray,
            qdd: np.ndarray) -> np.ndarray:
    """(N, n_motors, 4): each motor's regressor of its [armature, viscous, coulomb, offset] on its own
    torque, [q''_m, q'_m, s(q'_m), 1] at the motor's rates (`reach` takes them to the joints)."""
    if transmission is None:
        return friction.columns(frictions, qd, qdd)
    return friction.columns(frictions, transmission.motor_rates(qd), transmission.motor_rates(qdd))


def mass(frictions: tuple[JointFriction, ...], transmission: Transmission | None) -> np.ndarray:
    """(n, n): what the rotors add to the joint-space mass matrix, N^T diag(I_m) N (diag(I_a) without a
    transmission)."""
    armature = friction.values(frictions)[:, 0]
    if transmission is None:
        return np.diag(armature)
    return transmission.N.T @ np.diag(armature) @ transmission.N


def across_branches(frictions: tuple[JointFriction, ...], transmission: Transmission | None,
                    carried: np.ndarray) -> tuple[str, int, int] | None:
    """The first motor with rotor inertia that turns two joints neither of which carries the other (on separate
    branches of the tree), as (motor, joint index, joint index); None if there is none. `carried[j, k]` is True where
    joint j's motion carries joint k's body. Its rotor adds I_m N[k, a] N[k, b] to the mass matrix between them,
    which MuJoCo's tendon armature drops (its sparse mass matrix keeps a joint's ancestors only: measured with
    MuJoCo 4.0, the bench then 48 % off Pinocchio's N^T diag(I_m) N on such a drive)."""
    if transmission is None:
        return None
    armature = friction.values(frictions)[:, 0]
    for k, motor in enumerate(transmission.motors):
        turned = np.flatnonzero(transmission.N[k])
        if armature[k] == 0.0:
            continue
        for i, a in enumerate(turned):
            for b in turned[i + 1:]:
                if not (carried[a, b] or carried[b, a]):
                    return motor, int(a), int(b)
    return None


class Dry:
    """What an engine applies as a force beside its own armature and damping, through the transmission:
    N^T dry_m(N q', N^-T tau_R) (harness/model/friction.py, Dry: Coulomb, offset and the families'
    terms of each motor). Built once per model, called at every step of a simulation."""

    def __init__(self, frictions: tuple[JointFriction, ...] | friction.Dry, transmission: Transmission | None):
        """frictions: each motor's law, or a batch's (friction.Dry.rows)."""
        self.law = frictions if isinstance(frictions, friction.Dry) else friction.Dry.of(frictions)
        self.transmission = transmission
        self.any, self.needs_load, self.needs_position = self.law.any, self.law.needs_load, self.law.needs_position

    def __call__(self, qd: np.ndarray, tau_rigid: np.ndarray | None = None, load: bool = True,
                 q: np.ndarray | None = None) -> np.ndarray:
        """At the joints' velocities qd and positions q (a spring's), the rigid torque tau_rigid (a load law's)."""
        t = self.transmission
        if t is None:
            return self.law(qd, tau_rigid, load, q)
        rigid_m = None if tau_rigid is None else t.motor_torques(tau_rigid)
        qd_m, q_m = at_drives(t, qd, q)
        return t.joint_torques(self.law(qd_m, rigid_m, load, q_m))
