"""Quaternions carry orientation through the forward simulation: checked against scipy and
finite differences."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from harness.model import quaternion


def test_matrix_round_trip_and_scipy_agreement():
    rot = Rotation.random(500, random_state=3)
    R = rot.as_matrix()
    q = quaternion.from_matrix(R)
    np.testing.assert_allclose(quaternion.to_matrix(q), R, atol=1e-15)
    xyzw = rot.as_quat()
    scipy_wxyz = np.column_stack([xyzw[:, 3], xyzw[:, :3]]) * np.sign(xyzw[:, 3:4])
    np.testing.assert_allclose(q, scipy_wxyz, atol=1e-15)


def test_derivative_is_body_angular_velocity():
    """R' = R omega~ with omega in body components: central differences of to_matrix along
    q' (h = 1e-6, error ~1e-12)."""
    rng = np.random.default_rng(5)
    q = quaternion.from_matrix(Rotation.random(50, random_state=4).as_matrix())
    w = rng.normal(size=(50, 3))
    qd = quaternion.derivative(q, w)
    h = 1e-6
    R_dot = (quaternion.to_matrix(q + h * qd) - quaternion.to_matrix(q - h * qd)) / (2 * h)
    W = np.einsum("nji,njk->nik", quaternion.to_matrix(q), R_dot)
    np.testing.assert_allclose(np.stack([W[:, 2, 1], W[:, 0, 2], W[:, 1, 0]], -1), w, atol=1e-8)
