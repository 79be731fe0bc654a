"""Prescribed motions: each type's q' and q'' are the derivatives of its q (central differences)."""

from __future__ import annotations

import numpy as np
import pytest

from harness.sources.motion import ConstantAcceleration, Exponential, Locked, Polynomial, Sinusoids

MOTIONS = [
    Locked(0.3),
    ConstantAcceleration(acceleration=2.0, position=0.1, velocity=-0.4),
    Polynomial((0.5, -1.0, 0.25, 0.125, -0.0625)),
    Sinusoids(offset=0.2, sin=((0.5, 3.0), (0.1, 7.0)), cos=((0.5, 4.0),)),
    Exponential(amplitude=1 / 150, rate=0.9, offset=0.1),
]


@pytest.mark.parametrize("motion", MOTIONS, ids=lambda m: m.kind)
def test_derivatives_match_central_differences(motion):
    t = np.linspace(0.0, 2.0, 41)
    h = 1e-4
    q, qd, qdd = motion.evaluate(t)
    qp, qdp, _ = motion.evaluate(t + h)
    qm, qdm, _ = motion.evaluate(t - h)
    # central differences: truncation h^2/6 q''' ~ 1e-8 * 350 (sinusoid, w = 7): 1e-6 absolute
    np.testing.assert_allclose((qp - qm) / (2 * h), qd, atol=1e-6)
    np.testing.assert_allclose((qdp - qdm) / (2 * h), qdd, atol=1e-6)
    np.testing.assert_allclose((qp - 2 * q + qm) / h**2, qdd, atol=1e-4)  # round-off 1e-16/h^2


def test_constant_acceleration_from_rest_is_half_a_t_squared():
    t = np.array([0.0, 0.3, 1.5, 2.0])
    q, qd, qdd = ConstantAcceleration(2.0).evaluate(t)
    np.testing.assert_array_equal(q, t**2)
    np.testing.assert_array_equal(qd, 2 * t)
    np.testing.assert_array_equal(qdd, 2.0)
