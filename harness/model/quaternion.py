"""Unit quaternions (w, x, y, z) for orientations that have no singularity, batch-first."""

from __future__ import annotations

import numpy as np


def to_matrix(q: np.ndarray) -> np.ndarray:
    """(..., 4) -> (..., 3, 3) rotation matrices (body to world for a body's orientation)."""
    w, x, y, z = np.moveaxis(q, -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], -2)


def from_matrix(R: np.ndarray) -> np.ndarray:
    """(..., 3, 3) -> (..., 4), w >= 0, by the largest of the four squared components."""
    R = np.asarray(R, dtype=float)
    tr = np.trace(R, axis1=-2, axis2=-1)
    d = np.diagonal(R, axis1=-2, axis2=-1)
    squares = np.stack([1 + tr, 1 + 2 * d[..., 0] - tr, 1 + 2 * d[..., 1] - tr, 1 + 2 * d[..., 2] - tr], -1)
    k = np.argmax(squares, axis=-1)
    s = np.sqrt(np.take_along_axis(squares, k[..., None], -1)[..., 0]) * 2  # 4 * |q_k|
    off = {  # products 4 q_a q_b from the antisymmetric and symmetric parts
        "wx": R[..., 2, 1] - R[..., 1, 2], "wy": R[..., 0, 2] - R[..., 2, 0], "wz": R[..., 1, 0] - R[..., 0, 1],
        "xy": R[..., 0, 1] + R[..., 1, 0], "xz": R[..., 0, 2] + R[..., 2, 0], "yz": R[..., 1, 2] + R[..., 2, 1],
    }
    q = np.stack([
        np.choose(k, [s / 4, off["wx"] / s, off["wy"] / s, off["wz"] / s]),
        np.choose(k, [off["wx"] / s, s / 4, off["xy"] / s, off["xz"] / s]),
        np.choose(k, [off["wy"] / s, off["xy"] / s, s / 4, off["yz"] / s]),
        np.choose(k, [off["wz"] / s, off["xz"] / s, off["yz"] / s, s / 4]),
    ], -1)
    return q * np.where(q[..., :1] < 0, -1.0, 1.0)


def angle(q: np.ndarray) -> np.ndarray:
    """(..., 4) -> (...,) the rotation's angle in [0, pi], 2 atan2(|(x, y, z)|, |w|): accurate at every angle,
    where arccos of the trace loses half the digits near zero."""
    q = np.asarray(q, dtype=float)
    return 2.0 * np.arctan2(np.linalg.norm(q[..., 1:], axis=-1), np.abs(q[..., 0]))


def derivative(q: np.ndarray, omega_B: np.ndarray) -> np.ndarray:
    """q' = q (x) (0, omega_B) / 2 for body-frame angular velocity omega_B."""
    w, x, y, z = np.moveaxis(q, -1, 0)
    a, b, c = np.moveaxis(omega_B, -1, 0)
    return 0.5 * np.stack([-x * a - y * b - z * c, w * a + y * c - z * b,
                           w * b + z * a - x * c, w * c + x * b - y * a], -1)
