"""The two types a motion is held in check their invariants on construction: a TimeSeries (a recording,
a conditioned log) has strictly increasing finite times and every per-row array one finite row per
time; a RawLog (a log as read) has finite times in the file's order, which its checks judge by row."""

import numpy as np
import pytest

from harness.base.series import SeriesError, TimeSeries, read_csv
from harness.base.tomlio import InputError
from harness.sources.log.raw import RawLog

N, J = 6, 2
T = np.arange(N) * 0.01


def _arrays(**changes) -> dict:
    base = {"t": T.copy(), "q": np.zeros((N, J)), "qd": np.zeros((N, J)), "qdd": np.zeros((N, J)),
            "tau": np.ones((N, J))}
    return {**base, **changes}


def _with(name: str, row: int, value: float) -> np.ndarray:
    x = _arrays()[name].copy()
    x[row] = value
    return x


@pytest.mark.parametrize(("changes", "field"), [
    ({"t": np.r_[T[:3], T[2], T[4:]]}, "t"),  # a time repeated
    ({"t": T[::-1].copy()}, "t"),  # backwards
    ({"t": _with("t", 4, np.nan)}, "t"),
    ({"t": _with("t", 5, np.inf)}, "t"),
    ({"t": T.reshape(3, 2)}, "t"),  # not one time per row
    ({"t": T[:0]}, "t"),  # no rows
    ({"q": np.zeros((N - 1, J))}, "q"),  # a row short
    ({"qd": np.zeros((N + 1, J))}, "qd"),
    ({"tau": _with("tau", 2, np.inf)}, "tau"),
    ({"qdd": _with("qdd", 0, np.nan)}, "qdd"),
    ({"q": np.zeros((N, J + 1))}, "q"),  # a column for a joint the series does not have
    ({"tau": np.zeros(N)}, "tau"),  # no joint axis
    ({"F_W": np.zeros((N - 2, J, 3))}, "F_W"),  # a body or wrench channel a row short
    ({"p_W": np.full((N, 1, 3), np.nan)}, "p_W"),
], ids=["t repeated", "t backwards", "t NaN", "t infinite", "t 2-D", "no rows", "q short", "qd long",
        "tau infinite", "qdd NaN", "q a column more", "tau 1-D", "F_W short", "p_W NaN"])
def test_a_time_series_refuses_what_is_not_one(changes, field):
    with pytest.raises(SeriesError) as err:
        TimeSeries(joints=("a", "b"), **_arrays(**changes))
    assert err.value.field == field and str(err.value).startswith(f"TimeSeries {field}: ")


def test_a_time_series_takes_what_is_one_and_keeps_it_through_a_span():
    series = TimeSeries(joints=("a", "b"), **_arrays(qdd=None))
    assert series.qdd is None
    part = series.span(np.array([0, 2, 5]))
    assert part.t.tolist() == T[[0, 2, 5]].tolist() and part.q.shape == (3, J)
    with pytest.raises(SeriesError, match="not strictly increasing at row 1"):
        series.span(np.array([2, 0]))  # a span out of order is not a series either


@pytest.mark.parametrize(("changes", "field"), [
    ({"t": _with("t", 1, np.nan)}, "t"),
    ({"q": _with("q", 3, np.inf)}, "q"),
    ({"tau": np.zeros((N - 1, J))}, "tau"),
    ({"qd": _with("qd", 5, np.nan)}, "qd"),
    ({"q": np.zeros((N, J + 1))}, "q"),
], ids=["t NaN", "q infinite", "tau short", "qd NaN", "q a column more"])
def test_a_raw_log_refuses_what_no_reading_could_give(changes, field):
    a = _arrays(**changes)
    with pytest.raises(SeriesError) as err:
        RawLog(a["t"], ("a", "b"), a["q"], a["qd"], a["tau"], file="log.csv")
    assert err.value.field == field


def test_a_raw_log_keeps_the_files_order_for_its_checks_to_judge():
    """Repeated and backward times are a log's to have: the checks drop the one and refuse the other,
    naming the row (tests/test_log_guards.py); the type does not decide it for them."""
    t = np.array([0.0, 0.01, 0.01, 0.005, 0.02, 0.03])
    raw = RawLog(t, ("a", "b"), np.zeros((N, J)), None, np.ones((N, J)), file="log.csv")
    assert raw.qdd is None and raw.span(slice(1, 4)).t.tolist() == [0.01, 0.01, 0.005]


@pytest.mark.parametrize(("edit", "column"), [("swap", "t"), ("inf", "tau_a")])
def test_a_series_file_edited_into_something_else_is_refused_naming_the_file_and_column(tmp_path, edit, column):
    """A conditioned log written by the harness, edited (two rows swapped; a value made infinite), is
    an InputError naming the file and the column, not a series."""
    series = TimeSeries(joints=("a", "b"), **_arrays())
    path = tmp_path / "data.csv"
    series.write_csv(path)
    lines = path.read_text().splitlines()
    if edit == "swap":
        lines[2], lines[3] = lines[3], lines[2]
    else:
        head = lines[0].split(",")
        cells = lines[4].split(",")
        cells[head.index("tau_a")] = "inf"
        lines[4] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError) as err:
        read_csv(path, bodies=False)
    assert err.value.key == column and str(path) in str(err.value)
