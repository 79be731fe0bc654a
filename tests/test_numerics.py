"""Numbers written once for every layer (harness/base/numerics.py)."""

from __future__ import annotations

import numpy as np
import pytest

from harness.base.numerics import RANGE_FLOOR, evenly_spaced, range_scale


@pytest.mark.parametrize("n", [1, 2, 7, 101, 4000])
@pytest.mark.parametrize("count", [1, 2, 5, 100, 250])
def test_evenly_spaced_rows_are_the_distinct_rounded_points_of_an_even_grid(n, count):
    rows = evenly_spaced(n, count)
    grid = np.linspace(0, n - 1, count).round().astype(int)  # the points themselves, each where it falls
    np.testing.assert_array_equal(rows, np.unique(grid))
    assert rows[0] == 0 and (count == 1 or rows[-1] == n - 1)
    # points at least one row apart round to distinct rows; closer ones reach every row
    assert len(rows) == min(n, count)


def test_evenly_spaced_of_nothing_is_empty():
    assert evenly_spaced(0, 10).size == 0 and evenly_spaced(10, 0).size == 0


def test_a_joint_that_does_not_move_is_judged_against_its_kinds_largest_range_not_its_own():
    """Three hinges (ranges 2 rad, 0.5 rad, 3e-16 rad: a still passive joint) and two slides (0.2 m and
    none at all): each joint's own range where it has one, a still hinge RANGE_FLOOR of the hinges' largest
    (2e-3 rad, not 3e-16), a still slide RANGE_FLOOR m (1 mm; no slide moves beyond it)."""
    t = np.linspace(0.0, 1.0, 50)
    q = np.stack([2 * t, 0.5 * t**2, 1.0 + 3e-16 * t, 0.2 * t, np.zeros_like(t)], axis=1)
    scale = range_scale(q, [True, True, True, False, False])
    np.testing.assert_allclose(scale, [2.0, 0.5, RANGE_FLOOR * 2.0, 0.2, RANGE_FLOOR], rtol=1e-12)
    assert range_scale(q[:, :1] * 1e-6, [True])[0] == RANGE_FLOOR  # a small motion: 1 mrad at least


@pytest.mark.parametrize("rank_short", [False, True])
def test_a_fits_residual_read_off_its_qr_is_numpys_least_squares_residual(rank_short):
    """fit_residual against numpy's lstsq (an SVD) on columns of sizes 1e-3 to 1e3, full rank and with a
    column repeating another (the minimum-norm cut-off's): the same residual to 1e-12 of it, a residual
    under 1e-3 of |y| (where |y|^2 - |A x|^2 would keep few of its digits)."""
    from harness.base.numerics import fit_residual

    rng = np.random.default_rng(4)
    A = rng.normal(size=(3000, 8)) * np.logspace(-3, 3, 8)
    if rank_short:
        A[:, 5] = 2.0 * A[:, 2]
    y = A @ rng.normal(size=8) + 1e-4 * rng.normal(size=3000) * np.linalg.norm(A) / np.sqrt(3000)
    x = np.linalg.lstsq(A, y, rcond=None)[0]
    expected = float(np.linalg.norm(y - A @ x))
    assert expected < 1e-3 * np.linalg.norm(y)
    assert fit_residual(A, y) == pytest.approx(expected, rel=1e-12)
