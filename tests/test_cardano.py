"""Cardano angles (paper Eqs. 29, 33, 34) against an independent rotation library and finite
differences, and the continuous extraction through gimbal lock."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from harness.papers.graph_theory_2021.cardano import A_0i, D, D_dot, angles_from_rotation, cond_D, gimbal_flags

rng = np.random.default_rng(20211119)


def _Rx(a):
    return Rotation.from_euler("x", np.reshape(a, (-1, 1))).as_matrix()


def _Ry(b):
    return Rotation.from_euler("y", b).as_matrix()


def test_A_0i_is_intrinsic_xyz_of_scipy():
    theta = rng.uniform(-np.pi, np.pi, size=(200, 3))
    expected = Rotation.from_euler("XYZ", theta).as_matrix()  # intrinsic x-y-z: Rx Ry Rz
    np.testing.assert_allclose(A_0i(theta), expected, atol=1e-15)


def _path(t):
    """A smooth angle path and its first two derivatives."""
    w = np.array([1.3, 0.7, 2.1])
    return (np.sin(w * t[:, None]) + [0.2, -0.4, 1.0],
            w * np.cos(w * t[:, None]),
            -(w**2) * np.sin(w * t[:, None]))


def test_D_maps_angle_rates_to_body_angular_velocity():
    """omega_B = A^T dA/dt (skew part), with dA/dt by central differences (h = 1e-6: error 1e-12)."""
    t, h = np.linspace(0.0, 3.0, 50), 1e-6
    theta, theta_dot, _ = _path(t)
    A = A_0i(theta)
    A_dot = (A_0i(_path(t + h)[0]) - A_0i(_path(t - h)[0])) / (2 * h)
    W = np.einsum("nji,njk->nik", A, A_dot)  # skew(omega_B)
    omega_B = np.stack([W[:, 2, 1], W[:, 0, 2], W[:, 1, 0]], axis=-1)
    np.testing.assert_allclose(np.einsum("nij,nj->ni", D(theta), theta_dot), omega_B, atol=1e-8)


def test_D_dot_is_the_time_derivative_of_D():
    t, h = np.linspace(0.0, 3.0, 50), 1e-6
    theta, theta_dot, _ = _path(t)
    numeric = (D(_path(t + h)[0]) - D(_path(t - h)[0])) / (2 * h)
    np.testing.assert_allclose(D_dot(theta, theta_dot), numeric, atol=1e-8)


def test_extraction_inverts_A_0i_away_from_lock():
    theta = rng.uniform([-np.pi, -1.4, -np.pi], [np.pi, 1.4, np.pi], size=(300, 3))
    back = angles_from_rotation(A_0i(theta))
    np.testing.assert_allclose(A_0i(back), A_0i(theta), atol=1e-14)


def test_body_spinning_about_the_vertical_has_continuous_angles_through_lock():
    """B1 of kr500: e1 vertical, R = Ry(-pi/2) Rx(phi). Its continuous angles are
    alpha = gamma = pi/2 and beta = phi - pi/2 (derivation in harness.papers.graph_theory_2021.cardano); the lock rows
    (phi = k pi) take the same alpha as their neighbours."""
    phi = np.linspace(0.0, 4.2 * np.pi, 400)
    phi[[0, 95, 190]] = [0.0, np.pi, 2 * np.pi]  # exact lock rows
    R = _Ry(-np.pi / 2) @ _Rx(phi)
    theta = angles_from_rotation(R)
    np.testing.assert_allclose(A_0i(theta), R, atol=1e-14)
    np.testing.assert_allclose(theta[:, 0], np.pi / 2, atol=1e-12)
    np.testing.assert_allclose(theta[:, 2], np.pi / 2, atol=1e-12)
    np.testing.assert_allclose(theta[:, 1], phi - np.pi / 2, atol=1e-12)
    assert cond_D(theta[0]) > 1e15  # D singular up to round-off at the lock rows


def test_gimbal_flags_catch_ill_conditioned_rows_and_crossings_between_rows():
    phi = np.array([0.0, 0.5, 1.0, 3.1, 3.2, 4.0])  # lock at 0, and crossed between 3.1 and 3.2
    theta = np.column_stack([np.full(6, np.pi / 2), phi - np.pi / 2, np.full(6, np.pi / 2)])
    np.testing.assert_array_equal(gimbal_flags(theta), [True, False, False, True, True, False])


def test_axis_rotation_is_scipys_rotation_vector():
    """harness.model.kinematics.axis_rotation (Rodrigues' formula, written to spare scipy.spatial's import)
    against scipy's Rotation.from_rotvec: unit and non-unit axes, angles over several turns, 1e-14."""
    from scipy.spatial.transform import Rotation

    from harness.model.kinematics import axis_rotation

    rng = np.random.default_rng(3)
    for axis in (rng.normal(size=3), np.array([0.0, 0.0, 1.0]), np.array([0.0, 2.0, 0.0])):
        s = rng.uniform(-20.0, 20.0, 200)
        expected = Rotation.from_rotvec(np.outer(s, axis)).as_matrix()
        np.testing.assert_allclose(axis_rotation(axis, s), expected, rtol=0, atol=1e-14 * max(1, np.abs(s).max()))
        np.testing.assert_array_equal(axis_rotation(axis, s, samples_last=True),
                                      np.moveaxis(axis_rotation(axis, s), 0, -1))  # the same bits, samples last


def test_cross_and_skew_are_numpys_cross_product_to_the_bit():
    """harness.model.kinematics.cross (written for its per-call cost) gives np.cross's bits for every
    broadcast of shapes the models use, in either layout, and skew(a) b = a x b within a few roundings of |a| |b|
    (the same two products, summed with an exact zero in another order)."""
    from harness.model.kinematics import cross, skew

    rng = np.random.default_rng(5)
    for sa, sb in (((3,), (3,)), ((5, 3), (3,)), ((3,), (4, 2, 3)), ((4, 1, 3), (1, 6, 3)), ((100, 7, 3),) * 2):
        a, b = rng.normal(size=sa), rng.normal(size=sb)
        np.testing.assert_array_equal(cross(a, b), np.cross(a, b))
        np.testing.assert_array_equal(cross(np.moveaxis(a, -1, 0), np.moveaxis(b, -1, 0), axis=0),
                                      np.moveaxis(np.cross(a, b), -1, 0))  # component-major
    a, b = rng.normal(size=(50, 7, 3)), rng.normal(size=(50, 7, 3))
    scale = np.max(np.linalg.norm(a, axis=-1) * np.linalg.norm(b, axis=-1))
    np.testing.assert_allclose(np.einsum("...ab,...b->...a", skew(a), b), np.cross(a, b), rtol=0,
                               atol=4 * np.finfo(float).eps * scale)
