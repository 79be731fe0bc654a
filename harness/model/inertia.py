"""A rigid body's inertia, written once: the 10-parameter layout, the parallel-axis term, rigid
unions and the pseudo-inertia.

The ten inertial parameters of one body, in a frame with origin O (Pinocchio's dynamic
parameters, `pin.Inertia.toDynamicParameters`):

    theta = [m, m c_x, m c_y, m c_z, I_xx, I_xy, I_yy, I_xz, I_yz, I_zz]   (PARAMETER_NAMES)

with m in kg, c the centre of mass from O in m, I the inertia about O in kg m^2, all in the
frame's axes. The pseudo-inertia J = [[Sigma, h], [h^T, m]], Sigma = tr(I)/2 1 - I, h = m c, is
positive semidefinite exactly when the parameters are those of a mass distribution (Wensing, Kim
and Slotine, IEEE RA-L 2018); Pinocchio's `PseudoInertia` gives the same matrix for m != 0
(tests/test_inertia.py), and it is written here in numbers since a fit's parameters may have
m <= 0, where Pinocchio's conversion divides by m.
"""

from __future__ import annotations

import numpy as np

from harness.base.numerics import PARAMETER_FLOOR

PARAMETER_NAMES = ("m", "mcx", "mcy", "mcz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")
KINDS = ((0,), (1, 2, 3), (4, 5, 6, 7, 8, 9))  # m; m c; the inertia about O
MOMENT_FLOOR = 1e-12  # of a model's largest principal moment: what an engine is given for a moment of zero
# (MuJoCo refuses a moving body without one: harness/model/mjspec.py)


def parallel_axis(mass: float, d: np.ndarray) -> np.ndarray:
    """m (|d|^2 1 - d d^T): what a mass whose centre sits at d adds to an inertia about the origin."""
    return mass * (d @ d * np.eye(3) - np.outer(d, d))


def not_rigid(mass: float, moments: np.ndarray) -> str:
    """Why a body of `mass` and principal `moments` (about its centre of mass) is no rigid body of
    finite size, or "": mass not positive, a moment not positive (a point or a thin rod), or the
    triangle inequality broken."""
    p = np.sort(np.asarray(moments, dtype=float))
    return ("mass not positive" if mass <= 0 else "a principal moment not positive" if p[0] <= 0
            else "triangle inequality broken" if p[2] > (p[0] + p[1]) * (1 + 1e-12) else "")


def union(parts: list[tuple[float, np.ndarray, np.ndarray]]) -> tuple[float, np.ndarray, np.ndarray, np.ndarray]:
    """Rigidly joined parts [(mass, centre of mass, inertia about it)], one frame for all, as one
    body: (mass, centre of mass, principal moments, principal axes as right-handed columns)."""
    mass = sum(m for m, _, _ in parts)
    com = sum(m * c for m, c, _ in parts) / mass
    total = sum(I + parallel_axis(m, c - com) for m, c, I in parts)
    principal, axes = np.linalg.eigh(total)
    if np.linalg.det(axes) < 0:
        axes[:, 2] *= -1
    return mass, com, principal, axes


def inertia_about_origin(theta: np.ndarray) -> np.ndarray:
    """(3, 3) the inertia I about the frame origin of one body's ten parameters."""
    xx, xy, yy, xz, yz, zz = theta[4:]
    return np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])


def about_centre_of_mass(theta: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """(m, c, I_c) of one body's ten parameters: its mass, centre of mass and inertia about it,
    in the frame of the parameters (m > 0)."""
    m = float(theta[0])
    c = theta[1:4] / m
    return m, c, inertia_about_origin(theta) - parallel_axis(m, c)


def pseudo_inertia(theta: np.ndarray) -> np.ndarray:
    """(4, 4) J of one body's ten parameters (about its frame origin)."""
    inertia = inertia_about_origin(theta)
    sigma = 0.5 * np.trace(inertia) * np.eye(3) - inertia
    h = np.asarray(theta[1:4], dtype=float)
    return np.block([[sigma, h[:, None]], [h[None, :], np.array([[theta[0]]])]])


def from_pseudo_inertia(J: np.ndarray) -> np.ndarray:
    """(10,) the ten parameters of a pseudo-inertia J (the inverse of `pseudo_inertia`): m = J_44,
    h = J_{1:3,4}, and I = tr(Sigma) 1 - Sigma, since tr(Sigma) = tr(I)/2."""
    sigma = J[:3, :3]
    inertia = np.trace(sigma) * np.eye(3) - sigma
    return np.array([J[3, 3], *J[:3, 3], inertia[0, 0], inertia[0, 1], inertia[1, 1], inertia[0, 2],
                     inertia[1, 2], inertia[2, 2]])


def nearest_physical(theta: np.ndarray, margin: float) -> np.ndarray:
    """(10,) the parameters whose pseudo-inertia is nearest to theta's (Frobenius norm) among those
    with every eigenvalue at least `margin`: the eigenvalues below it raised to it."""
    J = pseudo_inertia(theta)
    J = (J + J.T) / 2
    w, V = np.linalg.eigh(J)
    return from_pseudo_inertia((V * np.maximum(w, margin)) @ V.T)


def kind_scale(true: np.ndarray) -> np.ndarray:
    """(10,) the largest value of each parameter's kind in one body (m; m c, at least m r_g with
    r_g = sqrt(max I / m) the radius of gyration, since a centre of mass on the joint point has
    m c = 0 and its own largest value is round-off; I_O)."""
    out = np.zeros(10)
    for g in KINDS:
        out[list(g)] = np.max(np.abs(true[list(g)]))
    out[1:4] = max(out[1], np.sqrt(true[0] * out[4]))
    return out


def model_kind_scales(thetas: np.ndarray) -> np.ndarray:
    """(n, 10) `kind_scale` of every body of a model, each kind at least PARAMETER_FLOOR of the model's
    largest of that kind: a point mass on its joint (the iCub's hips) has no inertia and no m c of its
    own, and a scale of zero would divide by zero where its parameters are weighed."""
    scales = np.array([kind_scale(t) for t in thetas]).reshape(-1, 10)
    floor = PARAMETER_FLOOR * scales.max(axis=0, initial=0.0)
    return np.maximum(scales, floor)
