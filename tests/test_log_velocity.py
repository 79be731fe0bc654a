"""A log's velocity columns against its positions' rate of change (harness/sources/log/velocity.py):
the lag of each found to a microsecond on a motion the test knows exactly, the columns that lag beyond
LAG_STEPS median steps realigned and no other touched."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from harness.sources.log.raw import RawLog
from harness.sources.log.velocity import LAG_STEPS, judged, lags

STEP = 0.01  # s
T = np.arange(0.0, 30.0, STEP)


def _q(x):
    return np.sin(1.3 * x) + 0.4 * np.sin(3.1 * x + 0.5)


def _qd(x):
    return 1.3 * np.cos(1.3 * x) + 1.24 * np.cos(3.1 * x + 0.5)


LATE = (0.0373, -0.0121, 0.0)  # s: joint 1 late by 3.73 steps, joint 2 early by 1.21 steps, joint 3 still


def _log() -> RawLog:
    """Three joints: two move, each velocity column off its positions by LATE; the third held still."""
    q = np.stack([_q(T), 0.5 * _q(T + 1.0), np.full_like(T, 0.2)], axis=1)
    qd = np.stack([_qd(T - LATE[0]), 0.5 * _qd(T + 1.0 - LATE[1]), np.zeros_like(T)], axis=1)
    return RawLog(T, ("a", "b", "c"), q, qd, np.zeros_like(q), Path("log.csv"))


def test_each_columns_lag_is_found_between_grid_points_and_a_still_joint_says_nothing():
    """Lags of 3.73 and -1.21 steps found to 1e-6 s (1e-4 of a step: the positions' central differences and
    the velocity's linear interpolation err by O(h^2) of the motion's third derivative, alike on either
    side of the lag); the still joint is not judged."""
    found = lags(_log().t, _log().q, _log().qd)
    assert np.allclose(found.lag_s[:2], LATE[:2], rtol=0.0, atol=1e-6)
    assert found.judged.tolist() == [True, True, False]
    assert found.late.tolist() == [abs(LATE[0]) > LAG_STEPS * STEP, abs(LATE[1]) > LAG_STEPS * STEP, False]


def test_a_late_column_is_realigned_the_others_untouched_and_the_rows_it_cannot_reach_dropped():
    log = _log()
    out, record, said = judged(log, log, list(log.joints))
    late = np.abs(np.array(LATE)) > LAG_STEPS * STEP
    assert record["late_joints"] == [j for j, x in zip(log.joints, late, strict=True) if x] == ["a"]
    kept = T + record["per_joint"]["a"]["lag_s"] <= T[-1]
    assert record["rows_dropped"] == int(np.sum(~kept)) == 4  # 37.3 ms of 10 ms rows at the end
    assert np.array_equal(out.t, T[kept]) and np.array_equal(out.qd[:, 1:], log.qd[kept, 1:])
    assert np.abs(out.qd[:, 0] - _qd(out.t)).max() < 2e-4 * np.abs(_qd(T)).max()  # on time: linear interpolation's
    # error between 10 ms samples of this motion, h^2/8 of its third derivative
    assert np.abs(log.qd[kept, 0] - _qd(T[kept])).max() > 0.05 * np.abs(_qd(T)).max()  # as logged: 3.73 steps off
    assert "realigned by their lags" in said and "a 37.3 ms" in said


@pytest.mark.parametrize("choice", ["used", "no velocities"])
def test_velocities_used_as_logged_or_absent_are_left_as_they_are(choice):
    log = _log() if choice == "used" else dataclasses.replace(_log(), qd=None)
    out, record, said = judged(log, log, list(log.joints), "used")
    assert out is log
    if choice == "used":
        assert record["late_joints"] == ["a"] and not record["realigned"] and "used as logged" in said
    else:
        assert record is None and said is None


def test_a_column_stamped_early_is_realigned_the_other_way_and_the_rows_at_the_start_dropped():
    log = _log()
    early = dataclasses.replace(log, qd=np.stack([_qd(T + 0.0523), log.qd[:, 1], log.qd[:, 2]], axis=1))
    out, record, _ = judged(early, early, list(log.joints))
    assert record["per_joint"]["a"]["lag_s"] == pytest.approx(-0.0523, abs=1e-6)
    kept = T - 0.0523 >= T[0] - 1e-9
    assert record["rows_dropped"] == int(np.sum(~kept)) and np.array_equal(out.t, T[kept])
    assert np.abs(out.qd[:, 0] - _qd(out.t)).max() < 2e-4 * np.abs(_qd(T)).max()


@pytest.mark.parametrize("noise", [0.0, 0.01], ids=["exact positions", "noisy positions"])
def test_a_lag_is_realigned_only_where_it_explains_the_velocitys_disagreement_with_the_rate(noise):
    """Joint a's column 50 ms (5 steps) late. On exact positions the lag explains the whole disagreement
    with the positions' rate (the residual ratio at round-off of the interpolation's, far under SHIFT_GAIN):
    realigned. On positions with 0.01 rad of white noise, their differences carry 1.4 rad/s of it against
    the lag's 0.15 rad/s (50 ms of accelerations of about 3 rad/s^2): the lag is still found near 50 ms but
    leaves 98.9 % of the disagreement (1.41^2 / (1.41^2 + 0.15^2)), so the column is left as logged and the
    record says why; the Panda's real log is such a case (its 2 to 9 ms lags leave 99.8 %)."""
    from harness.base.numerics import SHIFT_GAIN

    rng = np.random.default_rng(3)
    log = _log()
    log = dataclasses.replace(log, q=log.q + noise * rng.standard_normal(log.q.shape) * [1, 0, 0],
                              qd=np.stack([_qd(T - 0.05), log.qd[:, 1], log.qd[:, 2]], axis=1))
    out, record, said = judged(log, log, list(log.joints))
    a = record["per_joint"]["a"]
    assert a["judged"] and abs(a["lag_s"] - 0.05) < (1e-6 if noise == 0 else 5e-3)
    if noise == 0:
        assert a["residual_ratio"] < 1e-3 and record["late_joints"] == ["a"] and record["realigned"]
    else:
        assert SHIFT_GAIN < a["residual_ratio"] < 1.0 and record["late_joints"] == [] and not record["realigned"]
        assert out is log and said is None


def test_a_mobile_manipulators_late_velocities_are_realigned_on_quantised_positions():
    """The shape the issue's robot publishes: 100 Hz, slow motion (0.2 and 0.45 Hz), encoders quantised to
    1e-4 rad, velocities 160 ms late. The quantisation puts about 0.004 rad/s of noise on the positions'
    differences against the lag's 0.3 rad/s, so the lag explains nearly all the disagreement (the residual
    ratio under 1e-2, far under SHIFT_GAIN): found to 1 ms and realigned."""
    t = np.arange(0.0, 80.0, 0.01)
    motion = (lambda x: 0.8 * np.sin(2 * np.pi * 0.2 * x) + 0.3 * np.sin(2 * np.pi * 0.45 * x + 1.0),
              lambda x: 0.8 * 2 * np.pi * 0.2 * np.cos(2 * np.pi * 0.2 * x)
              + 0.3 * 2 * np.pi * 0.45 * np.cos(2 * np.pi * 0.45 * x + 1.0))
    q = np.round(motion[0](t) / 1e-4)[:, None] * 1e-4
    log = RawLog(t, ("torso",), q, motion[1](t - 0.16)[:, None], np.zeros_like(q), Path("joint_states.csv"))
    _, record, said = judged(log, log, ["torso"])
    found = record["per_joint"]["torso"]
    assert abs(found["lag_s"] - 0.16) < 1e-3 and found["residual_ratio"] < 1e-2
    assert record["realigned"] and "torso 160 ms" in said
