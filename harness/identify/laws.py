"""A joint's friction law as the identification handles it: its family (harness/model/friction.py,
FAMILIES) and the velocities its shapes turn over (`Law`), and the regressor columns of the families'
coefficients (`extra_regressor`), read by every fit that identifies them (the friction search of
harness/identify/friction_law.py, the log's least squares and consistent fit, the bench's joint-torque fit)."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from harness.identify import filtered
from harness.model import drives, friction
from harness.model.drives import Transmission
from harness.model.friction import EXTRA_KEYS, FAMILIES, JointFriction


@dataclass(frozen=True)
class Law:
    """One joint's law: its family and the velocities its shapes turn over. The one type of a law: a
    joint's friction values (model/friction.py, JointFriction) are made from a law and coefficients
    (`friction`), given a law's velocities (`shaping`) or read into one (`at_velocities_of`) here alone."""

    family: str = "viscous_coulomb"
    coulomb_velocity: float = 0.0
    stribeck_velocity: float = 0.0

    @property
    def terms(self) -> tuple[str, ...]:
        """The EXTRA_KEYS coefficients it adds (a model's own law may join families: "a+b")."""
        return FAMILIES[self.family] if self.family in FAMILIES else tuple(self.family.split("+"))

    @property
    def shapes(self) -> JointFriction:
        """A friction with this law's velocities and no coefficient: what its columns are built from."""
        return self.friction()

    def friction(self, armature: float = 0.0, viscous: float = 0.0, coulomb: float = 0.0, offset: float = 0.0,
                 **terms: float) -> JointFriction:
        """A joint's friction of this law: its velocities, and the coefficients given (the family's
        terms by name)."""
        return JointFriction(float(armature), float(viscous), float(coulomb), float(offset), self.coulomb_velocity,
                             stribeck_velocity=self.stribeck_velocity, **{k: float(v) for k, v in terms.items()})

    def shaping(self, f: JointFriction) -> JointFriction:
        """f at this law's velocities, its coefficients kept."""
        return replace(f, coulomb_velocity=self.coulomb_velocity, stribeck_velocity=self.stribeck_velocity)

    def at_velocities_of(self, f: JointFriction) -> Law:
        """This law, its family kept, at f's velocities."""
        return replace(self, coulomb_velocity=f.coulomb_velocity, stribeck_velocity=f.stribeck_velocity)

    @classmethod
    def of(cls, f: JointFriction) -> Law:
        """A model's own law for one joint."""
        return cls(f.family, f.coulomb_velocity, f.stribeck_velocity)


def spring_positions(q: np.ndarray | None, tried: bool, laws) -> np.ndarray | None:
    """q, refused where a spring's column would need it and it is not given (a spring `tried`, or a law's)."""
    if q is None and (tried or any("stiffness" in law.terms for law in laws)):
        raise ValueError("a spring's column needs the joints' positions")
    return q


def extra_terms(laws: tuple[Law, ...]) -> list[tuple[int, str]]:
    return [(j, key) for j, law in enumerate(laws) for key in law.terms]


def extra_regressor(laws: tuple[Law, ...], qd: np.ndarray, tau_rigid: np.ndarray | None,
                    transmission: Transmission | None = None, columns=None, t: np.ndarray | None = None,
                    q: np.ndarray | None = None) -> np.ndarray:
    """(N n, e): the columns of the families' coefficients (extra_terms), each on its joint's rows; with
    a transmission, each motor's at its rates, positions and load, reaching joint j times N[k, j]. With a
    filtered span's `columns` (at its times `t`), each shape of the velocities filtered as the torques were
    (harness/identify/filtered.py); a spring's, the positions q (N, n), as the linear columns are."""
    terms = extra_terms(laws)
    N, n = qd.shape
    out = np.zeros((N, n, len(terms)))
    if not terms:
        return out.reshape(N * n, 0)
    qd, q = drives.at_drives(transmission, qd, spring_positions(q, False, laws))
    if transmission is not None:
        tau_rigid = None if tau_rigid is None else transmission.motor_torques(tau_rigid)
    if columns is None:
        shapes = friction.extra_columns(tuple(law.shapes for law in laws), qd, tau_rigid, q)  # (N, n, e)

    def shape(j: int, key: str) -> np.ndarray:  # drive j's column of `key`, filtered where the span was
        if columns is None:
            return shapes[:, j, EXTRA_KEYS.index(key)]
        if key == "stiffness":
            return q[:, j]
        if key == "load_coulomb" and tau_rigid is None:
            return np.zeros(N)
        column = filtered.drive_term(columns, t, laws[j], j, transmission, key)
        return np.abs(tau_rigid[:, j]) * column if key == "load_coulomb" else column

    reaching = drives.reach(transmission, n)
    for c, (k, key) in enumerate(terms):  # drive k's column on every joint j it reaches, times N[k, j]
        column = shape(k, key)
        for j, _, factor in (r for r in reaching if r[1] == k):
            out[:, j, c] = factor * column
    return out.reshape(N * n, len(terms))
