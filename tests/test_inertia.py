"""The 10-parameter layout and the pseudo-inertia (harness/model/inertia.py) against Pinocchio's own
`Inertia` and `PseudoInertia`, on random bodies. Tolerances: 1e-12 relative to the largest entry, a
few roundings of numbers of order one."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from harness.model.inertia import from_pseudo_inertia, nearest_physical, pseudo_inertia

BODIES = [pin.Inertia.Random() for _ in range(20)]


@pytest.mark.parametrize("body", BODIES)
def test_the_pseudo_inertia_is_pinocchios(body):
    theta = body.toDynamicParameters()
    ours, theirs = pseudo_inertia(theta), body.toPseudoInertia().toMatrix()
    np.testing.assert_allclose(ours, theirs, rtol=0, atol=1e-12 * np.abs(theirs).max())


@pytest.mark.parametrize("body", BODIES)
def test_the_parameters_come_back_from_the_pseudo_inertia(body):
    J = body.toPseudoInertia().toMatrix()
    theirs = pin.PseudoInertia.FromMatrix(J).toDynamicParameters()
    np.testing.assert_allclose(from_pseudo_inertia(J), theirs, rtol=0, atol=1e-12 * np.abs(theirs).max())


def test_the_nearest_physical_body_leaves_a_physical_one_alone_and_mends_one_that_is_not():
    theta = BODIES[0].toDynamicParameters()
    margin = 1e-9
    assert np.linalg.eigvalsh(pseudo_inertia(theta))[0] > margin
    np.testing.assert_allclose(nearest_physical(theta, margin), theta, rtol=0, atol=1e-12)
    broken = theta.copy()
    broken[0] = -0.5  # a negative mass
    mended = nearest_physical(broken, margin)
    assert np.linalg.eigvalsh(pseudo_inertia(mended))[0] >= margin * (1 - 1e-9)
    # no nearer physical J: a step from the mended J towards the broken one leaves the cone
    J_b, J_m = pseudo_inertia(broken), pseudo_inertia(mended)
    assert np.linalg.eigvalsh(J_m + 1e-3 * (J_b - J_m))[0] < margin
