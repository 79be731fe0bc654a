"""Numbers written once for every layer (harness/base/numerics.py)."""

from __future__ import annotations

import numpy as np
import pytest

from harness.base.numerics import evenly_spaced


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
