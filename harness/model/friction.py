"""Joint friction and rotor inertia: the torque a joint's drive adds to the rigid-body torque tau_R.

    tau_J = tau_R + I_a q'' + f_v q' + f_c s + f_o                       (viscous + Coulomb + offset)
                  + f_va |q'| + f_ca |s|                                 (asymmetric by direction)
                  + f_s s exp(-(q'/v_s)^2)                               (Stribeck)
                  + f_l |tau_R| s                                        (load-dependent Coulomb)
                  + k q                                                  (a spring)

    s = tanh(q' / v_c) (v_c > 0), sign(q') (v_c = 0)

per joint: `armature` I_a (the rotor's inertia reflected through the gear, kg m^2 or kg), `viscous`
f_v, `coulomb` f_c, `offset` f_o (a constant torque: a sensor's bias, an unbalanced cable) and
`coulomb_velocity` v_c, the velocity over which the Coulomb term turns (0: a sharp sign). This is
the friction model of the literature on arm identification (Gautier and Khalil; Gaz et al. 2019
with a sigmoid in place of the sign). Three families add to it, each what harmonic-drive joints
show: `viscous_asymmetry` f_va and `coulomb_asymmetry` f_ca (moving positively the viscous and
Coulomb coefficients are f_v + f_va and f_c + f_ca, negatively f_v - f_va and f_c - f_ca);
`stribeck` f_s with `stribeck_velocity` v_s (the extra torque to break away, fading over v_s);
`load_coulomb` f_l (the Coulomb torque grows by f_l per N m the joint carries, |tau_R|, the
rigid-body torque without the drive's); and a fourth, `spring`, a torque in proportion to the position,
`stiffness` k (N m/rad or N/m; a spring at rest at q0 is k q with f_o = -k q0: MuJoCo's joint
`stiffness` at `springref` q0, a counterbalance's linear part). Each is linear in its coefficients once
v_c and v_s are chosen. The law is written once, here; every engine and model takes it from here.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

IDENTIFIED_KEYS = ("armature", "viscous", "coulomb", "offset")  # linear in the torque: identifiable
EXTRA_KEYS = ("viscous_asymmetry", "coulomb_asymmetry", "stribeck", "load_coulomb", "stiffness")  # the families'
# coefficients
FRICTION_KEYS = (*IDENTIFIED_KEYS, "coulomb_velocity", *EXTRA_KEYS, "stribeck_velocity")
NONNEGATIVE_KEYS = ("armature", "viscous", "coulomb", "stribeck", "load_coulomb", "stiffness")  # a physical drive's:
# the offset
# and the asymmetries have either sign
BOUNDED_BY = {"viscous_asymmetry": "viscous", "coulomb_asymmetry": "coulomb"}  # |asymmetry| <= its symmetric term
FAMILIES = {  # name -> the coefficients it adds to viscous + Coulomb + offset, simplest first
    "viscous_coulomb": (),
    "stribeck": ("stribeck",),
    "load": ("load_coulomb",),
    "asymmetric": ("viscous_asymmetry", "coulomb_asymmetry"),
    "spring": ("stiffness",),
}


@dataclass(frozen=True)
class JointFriction:
    armature: float = 0.0
    viscous: float = 0.0
    coulomb: float = 0.0
    offset: float = 0.0
    coulomb_velocity: float = 0.0
    viscous_asymmetry: float = 0.0
    coulomb_asymmetry: float = 0.0
    stribeck: float = 0.0
    load_coulomb: float = 0.0
    stribeck_velocity: float = 0.0
    stiffness: float = 0.0

    @property
    def none(self) -> bool:
        return not any(getattr(self, k) for k in (*IDENTIFIED_KEYS, *EXTRA_KEYS))

    @property
    def family(self) -> str:
        """The simplest family (FAMILIES) that holds every coefficient this joint has."""
        for name, keys in FAMILIES.items():
            if all(getattr(self, k) == 0 or k in keys for k in EXTRA_KEYS):
                return name
        return "+".join(k for k in EXTRA_KEYS if getattr(self, k))

    def as_dict(self) -> dict[str, float]:
        return {k: float(getattr(self, k)) for k in FRICTION_KEYS}


NO_FRICTION = JointFriction()


def coulomb_shape(qd: np.ndarray, coulomb_velocity: np.ndarray) -> np.ndarray:
    """s(q'), (N, n): tanh(q' / v_c) where v_c > 0, sign(q') where v_c = 0."""
    v = np.asarray(coulomb_velocity, dtype=float)
    if np.all(v > 0):  # every joint's turn smooth (the law search asks millions of samples at a time)
        return np.tanh(qd / v)
    with np.errstate(divide="ignore", invalid="ignore"):
        smooth = np.tanh(qd / np.where(v > 0, v, 1.0))
    return np.where(v > 0, smooth, np.sign(qd))


def columns(frictions: tuple[JointFriction, ...], qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
    """(N, n, 4): per joint the regressor of [armature, viscous, coulomb, offset]: q'', q', s(q'), 1."""
    v = np.array([f.coulomb_velocity for f in frictions])
    return np.stack([qdd, qd, coulomb_shape(qd, v), np.ones_like(qd)], axis=-1)


def extra_shape(key: str, qd: np.ndarray, s: np.ndarray, stribeck_velocity: np.ndarray,
                tau_rigid: np.ndarray | None, q: np.ndarray | None = None) -> np.ndarray:
    """(..., n): the shape of one of EXTRA_KEYS at velocities qd with Coulomb shape s: |q'|, |s|,
    s exp(-(q'/v_s)^2) (zero where v_s = 0), |tau_R| s (zero where tau_rigid is not given), q (zero where
    the positions q are not given)."""
    if key == "stiffness":
        return np.zeros_like(s) if q is None else np.broadcast_to(q, np.shape(s)).astype(float)
    if key == "viscous_asymmetry":
        return np.abs(qd)
    if key == "coulomb_asymmetry":
        return np.abs(s)
    if key == "stribeck":
        v_s = stribeck_velocity
        with np.errstate(divide="ignore", over="ignore", under="ignore", invalid="ignore"):
            return np.where(v_s > 0, s * np.exp(-((qd / np.where(v_s > 0, v_s, 1.0)) ** 2)), 0.0)
    return np.zeros_like(s) if tau_rigid is None else np.abs(tau_rigid) * s


def extra_shapes(qd: np.ndarray, s: np.ndarray, stribeck_velocity: np.ndarray,
                 tau_rigid: np.ndarray | None, q: np.ndarray | None = None) -> np.ndarray:
    """(..., n, e): the shapes of EXTRA_KEYS at velocities qd with Coulomb shape s (`extra_shape`)."""
    return np.stack([extra_shape(key, qd, s, stribeck_velocity, tau_rigid, q) for key in EXTRA_KEYS], axis=-1)


def extra_columns(frictions: tuple[JointFriction, ...], qd: np.ndarray,
                  tau_rigid: np.ndarray | None = None, q: np.ndarray | None = None) -> np.ndarray:
    """(N, n, e): per joint the regressor of EXTRA_KEYS: |q'|, |s|, s exp(-(q'/v_s)^2) (zero where
    v_s = 0), |tau_R| s (zero where tau_rigid, (N, n), is not given) and q (zero where q is not given)."""
    v = np.array([f.coulomb_velocity for f in frictions])
    return extra_shapes(qd, coulomb_shape(qd, v), np.array([f.stribeck_velocity for f in frictions]), tau_rigid, q)


def extra_values(frictions: tuple[JointFriction, ...]) -> np.ndarray:
    """(n, e): the EXTRA_KEYS coefficients per joint."""
    return np.array([[getattr(f, k) for k in EXTRA_KEYS] for f in frictions]).reshape(-1, len(EXTRA_KEYS))


def _needs_load(frictions: tuple[JointFriction, ...], tau_rigid: np.ndarray | None) -> None:
    if tau_rigid is None and any(f.load_coulomb for f in frictions):
        raise ValueError("load-dependent friction (load_coulomb) needs the rigid-body torque the joint carries")


def _needs_position(frictions: tuple[JointFriction, ...], q: np.ndarray | None) -> None:
    if q is None and any(f.stiffness for f in frictions):
        raise ValueError("a spring (stiffness) needs the joint's position")


def values(frictions: tuple[JointFriction, ...]) -> np.ndarray:
    """(n, 4): [armature, viscous, coulomb, offset] per joint."""
    return np.array([[getattr(f, k) for k in IDENTIFIED_KEYS] for f in frictions]).reshape(-1, 4)


def torque(frictions: tuple[JointFriction, ...], qd: np.ndarray, qdd: np.ndarray,
           tau_rigid: np.ndarray | None = None, q: np.ndarray | None = None) -> np.ndarray:
    """(N, n): the whole law of every joint (the module's docstring); tau_rigid (N, n), the
    rigid-body torque, is needed where a joint has load-dependent friction, q (N, n) where one has a spring."""
    out = np.einsum("nja,ja->nj", columns(frictions, qd, qdd), values(frictions))
    if np.any(extra_values(frictions)):
        _needs_load(frictions, tau_rigid)
        _needs_position(frictions, q)
        out = out + np.einsum("nja,ja->nj", extra_columns(frictions, qd, tau_rigid, q), extra_values(frictions))
    return out


def rigid_torque(frictions: tuple[JointFriction, ...], tau: np.ndarray, qd: np.ndarray, qdd: np.ndarray,
                 q: np.ndarray | None = None) -> np.ndarray:
    """(N, n): the rigid-body torque tau_R a drive torque tau (N, n) leaves the bodies, the law (`torque`)
    inverted: tau = tau_R + f(q, q', q'') + f_l |tau_R| s, f every term but the load's; with r = tau - f,
    tau_R (1 + f_l s sign(tau_R)) = r, and since |f_l s| < 1 (a model's |f_l| is under 1:
    harness/model/drive_tables.py) tau_R has r's sign: tau_R = r / (1 + f_l s sign(r))."""
    load = np.array([f.load_coulomb for f in frictions])
    r = tau - torque(tuple(replace(f, load_coulomb=0.0) for f in frictions), qd, qdd, q=q)
    if not np.any(load):
        return r
    s = coulomb_shape(qd, np.array([f.coulomb_velocity for f in frictions]))
    return r / (1.0 + load * s * np.sign(r))


@dataclass(frozen=True, eq=False)
class Dry:
    """What an engine applies as a force beside its own damping (f_v q') and armature (I_a, in its mass
    matrix): f_c s + f_o and every family's terms, at velocities qd (..., n), with the rigid-body torque
    tau_rigid where a joint's friction depends on the load. Built once per model, called at every
    step of a simulation."""

    coulomb: np.ndarray  # (n,), or (B, n) for a batch whose rows' laws differ (`rows`)
    offset: np.ndarray
    coulomb_velocity: np.ndarray  # v_c, 1 where a sharp sign (see `sharp`)
    extra: np.ndarray  # (n, e) or (B, n, e): EXTRA_KEYS
    stribeck_velocity: np.ndarray
    frictions: tuple[JointFriction, ...]
    any: bool  # whether it is anything but zero (decided once: it is asked at every step)
    has_extra: bool  # whether a joint has a family's term
    needs_load: bool  # whether a joint's friction depends on its load
    needs_position: bool  # whether a joint has a spring (its torque depends on its position)
    sharp: np.ndarray | None  # (n,) or (B, n) bool: the joints whose Coulomb term is a sharp sign, None if none

    @classmethod
    def of(cls, frictions: tuple[JointFriction, ...]) -> Dry:
        """One law for every row it is called at: each field (n,)."""
        return cls._made([frictions], lambda a: a[0])

    @classmethod
    def rows(cls, laws: list[tuple[JointFriction, ...]], index: np.ndarray) -> Dry:
        """A batch's law: row b of the velocities (B, n) it is called at is under laws[index[b]] (each
        field (B, n)): a batch of rollouts whose laws differ, in one call per stage."""
        return cls._made(laws, lambda a: a[index])

    @classmethod
    def _made(cls, laws: list[tuple[JointFriction, ...]], pick) -> Dry:
        k = np.stack([values(fr) for fr in laws])  # (L, n, 4)
        extra = np.stack([extra_values(fr) for fr in laws])  # (L, n, e)
        v_c = np.array([[f.coulomb_velocity for f in fr] for fr in laws]).reshape(k.shape[:2])
        v_s = np.array([[f.stribeck_velocity for f in fr] for fr in laws]).reshape(k.shape[:2])
        return cls(pick(k[..., 2]), pick(k[..., 3]), pick(np.where(v_c > 0, v_c, 1.0)), pick(extra), pick(v_s),
                   tuple(f for fr in laws for f in fr), bool(np.any(k[..., 2:]) or np.any(extra)),
                   bool(np.any(extra)), bool(np.any(extra[..., EXTRA_KEYS.index("load_coulomb")])),
                   bool(np.any(extra[..., EXTRA_KEYS.index("stiffness")])),
                   pick(v_c == 0) if np.any(v_c == 0) else None)

    def __call__(self, qd: np.ndarray, tau_rigid: np.ndarray | None = None, load: bool = True,
                 q: np.ndarray | None = None) -> np.ndarray:
        """`load` False: without the load-dependent term (no rigid-body torque needed); q the positions,
        which a spring reads. coulomb_shape's s, with the division guarded once at construction (it is
        called at every stage of a step)."""
        s = np.tanh(qd / self.coulomb_velocity)
        if self.sharp is not None:
            s = np.where(self.sharp, np.sign(qd), s)
        out = self.coulomb * s + self.offset
        if self.has_extra:
            if load:
                _needs_load(self.frictions, tau_rigid)
            else:
                tau_rigid = None
            if self.needs_position and q is None:
                raise ValueError("a spring (stiffness) needs the joint's position")
            out = out + np.einsum("...ja,...ja->...j", extra_shapes(qd, s, self.stribeck_velocity, tau_rigid, q),
                                  self.extra)
        return out


def dry(frictions: tuple[JointFriction, ...], qd: np.ndarray, tau_rigid: np.ndarray | None = None,
        q: np.ndarray | None = None) -> np.ndarray:
    """Dry.of(frictions)(qd, tau_rigid, q=q)."""
    return Dry.of(frictions)(qd, tau_rigid, q=q)
