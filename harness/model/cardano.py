"""Cardano angles, the x-y-z sequence: theta = (alpha, beta, gamma), R(theta) = Rx(alpha) Ry(beta) Rz(gamma)
maps the turned frame's components to the fixed frame's; the turned frame's angular velocity in its own
axes is omega_B = D(theta) theta', so that its angular acceleration is D theta'' + D' theta'. D is
singular where cos(beta) = 0 (gimbal lock: only alpha + gamma or gamma - alpha is determined there).

These are a ball joint's coordinates in the harness (harness/model/mjcf.py): MuJoCo's `ball` joint read as
the three hinges about its body's x, y and z axes at q = 0, applied in that order (as MuJoCo applies a
body's hinges, each about its axis as the ones before it have turned it). The body's rotation from its
pose at q = 0 is then R(theta), in the body's axes, which is MuJoCo's ball quaternion and Pinocchio's
spherical joint's; their joint velocity is omega_B, their acceleration omega_B', and a torque tau on the
ball (the body's axes) does D^T tau on the hinges (`ball_state`)."""

from __future__ import annotations

import numpy as np


def rotation(theta: np.ndarray) -> np.ndarray:
    """R(theta) = Rx(alpha) Ry(beta) Rz(gamma), shape (..., 3) -> (..., 3, 3)."""
    return np.moveaxis(rotation_components(np.moveaxis(np.asarray(theta, dtype=float), -1, 0)), (0, 1), (-2, -1))


def rotation_components(theta_c: np.ndarray) -> np.ndarray:
    """`rotation` in component-major form: angles (3, ...) -> entries (3, 3, ...), contiguous, so that
    a batch of rotations is nine whole arrays."""
    a, b, g = np.asarray(theta_c, dtype=float)
    ca, sa, cb, sb, cg, sg = np.cos(a), np.sin(a), np.cos(b), np.sin(b), np.cos(g), np.sin(g)
    out = np.empty((3, 3) + a.shape)
    sa_sb, ca_sb = sa * sb, ca * sb
    np.multiply(cb, cg, out=out[0, 0])
    np.multiply(cb, sg, out=out[0, 1])
    np.negative(out[0, 1], out=out[0, 1])
    out[0, 2] = sb
    out[1, 0] = ca * sg + sa_sb * cg
    out[1, 1] = ca * cg - sa_sb * sg
    np.multiply(sa, cb, out=out[1, 2])
    np.negative(out[1, 2], out=out[1, 2])
    out[2, 0] = sa * sg - ca_sb * cg
    out[2, 1] = sa * cg + ca_sb * sg
    np.multiply(ca, cb, out=out[2, 2])
    return out


def rate_matrix(theta: np.ndarray) -> np.ndarray:
    """D(theta): omega_B = D(theta) theta', the angular velocity in the turned frame, (..., 3) -> (..., 3, 3)."""
    _, b, g = np.moveaxis(np.asarray(theta, dtype=float), -1, 0)
    cb, sb, cg, sg = np.cos(b), np.sin(b), np.cos(g), np.sin(g)
    zero, one = np.zeros_like(b), np.ones_like(b)
    return np.stack([
        np.stack([cb * cg, sg, zero], axis=-1),
        np.stack([-cb * sg, cg, zero], axis=-1),
        np.stack([sb, zero, one], axis=-1),
    ], axis=-2)


def rate_matrix_dot(theta: np.ndarray, theta_dot: np.ndarray) -> np.ndarray:
    """D'(theta, theta'), the time derivative of `rate_matrix`, (..., 3) -> (..., 3, 3)."""
    _, b, g = np.moveaxis(np.asarray(theta, dtype=float), -1, 0)
    _, bd, gd = np.moveaxis(np.asarray(theta_dot, dtype=float), -1, 0)
    cb, sb, cg, sg = np.cos(b), np.sin(b), np.cos(g), np.sin(g)
    zero = np.zeros_like(b)
    return np.stack([
        np.stack([-bd * sb * cg - gd * cb * sg, gd * cg, zero], axis=-1),
        np.stack([bd * sb * sg - gd * cb * cg, -gd * sg, zero], axis=-1),
        np.stack([bd * cb, zero, zero], axis=-1),
    ], axis=-2)


def ball_state(theta: np.ndarray, theta_d: np.ndarray, theta_dd: np.ndarray) -> tuple[np.ndarray, ...]:
    """A ball joint's state from its hinges' (theta, theta', theta''), each (N, 3): its quaternion (N, 4)
    (w, x, y, z) of R(theta), its angular velocity omega_B = D theta' and acceleration D theta'' + D' theta'
    (N, 3), both in the body's axes, and D (N, 3, 3), whose transpose takes the ball's torque to the hinges'."""
    from harness.model.quaternion import from_matrix

    D = rate_matrix(theta)
    omega = (D @ theta_d[:, :, None])[:, :, 0]
    omegadot = (D @ theta_dd[:, :, None] + rate_matrix_dot(theta, theta_d) @ theta_d[:, :, None])[:, :, 0]
    return from_matrix(rotation(theta)), omega, omegadot, D
