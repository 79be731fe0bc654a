"""The friction columns of a filtered log filtered as its torques were (harness/identify/filtered.py):
the same columns where the filter passes everything (so the right columns are the ones replaced, with
a coupled transmission too), and on one joint's Coulomb turn the smoothing velocity of the robot
where comparing tanh of the filtered velocity with the filtered torque gives the filter's."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import butter, sosfiltfilt

from harness.engines.pinocchio import build_model
from harness.identify import filtered
from harness.identify.laws import Law, extra_regressor
from harness.identify.span_rows import span_regressor
from harness.identify.torque_id import regressor
from harness.model.load import load_spec
from harness.sources.log.condition import FilteredColumns
from tests.conftest import MODELS

PASS_ALL = np.array([[1.0, 0.0, 0.0, 1.0, 0.0, 0.0]])  # a second-order section that passes everything


@pytest.mark.parametrize("model", ["ur5_friction.toml", "tx40.toml"])
def test_a_filter_that_passes_everything_leaves_every_friction_column_as_it_was(model):
    """At 300 random states in two stretches of rows kept every third sample: the Coulomb columns
    rewritten (through the TX40's coupled wrist: motor 6 on joints 5 and 6) and every family's columns
    equal the unfiltered regressor's bit for bit, and no other column moves."""
    spec = load_spec(MODELS / model)
    n = len(spec.joint_names)
    rng = np.random.default_rng(4)
    q, qd, qdd = (rng.uniform(-1, 1, (300, n)) for _ in range(3))
    rows = [np.arange(0, 150, 3), np.arange(0, 150, 3)]
    t = np.arange(300) * 1e-3
    stretches = ((qd[:150], rows[0]), (qd[150:], rows[1]))
    keep = np.concatenate([rows[0], 150 + rows[1]])
    columns = FilteredColumns(PASS_ALL, stretches, t[keep])
    laws = tuple(Law("stribeck+load_coulomb", 0.02 + 0.01 * k, 0.1) for k in range(n))
    spec = spec.with_frictions(tuple(law.shapes for law in laws))
    pm = build_model(spec, np.array([0, 0, -9.81]))
    W = regressor(pm, q[keep], qd[keep], qdd[keep], with_friction=True)
    rewritten = span_regressor(pm, q[keep], qd[keep], qdd[keep], filtered.coulomb(columns, t[keep], laws,
                                                                                   spec.transmission))
    assert np.array_equal(rewritten, W)
    rigid = rng.standard_normal((len(keep), n))
    E = extra_regressor(laws, qd[keep], rigid, spec.transmission)
    assert E.shape[1] == 2 * n and np.array_equal(extra_regressor(laws, qd[keep], rigid, spec.transmission,
                                                                  columns, t[keep]), E)


def test_filtered_coulomb_columns_find_the_robots_turn_where_the_filtered_velocity_finds_the_filters():
    """One joint swinging at 0.5 Hz, its torque 2 tanh(q'/0.01) + 0.3 q' sampled at 1 kHz and filtered
    at 5 Hz (Butterworth order 4, zero phase), kept every 5th sample: over v_c from 0.002 to 0.1 the
    least-squares residual of [q', s] is smallest at the true 0.01 (within 5 %) with s filtered as the
    torque was, and at a v_c at least 1.5 times larger with s = tanh(F[q'] / v_c) (measured: 0.0100,
    and the grid's largest, 0.1)."""
    t = np.arange(0.0, 20.0, 1e-3)
    qd = 0.8 * np.sin(2 * np.pi * 0.5 * t)[:, None]
    sos = butter(4, 5.0, fs=1000.0, output="sos")
    tau = sosfiltfilt(sos, 2 * np.tanh(qd / 0.01) + 0.3 * qd, axis=0)
    rows = np.arange(500, len(t) - 500, 5)
    qd_f = sosfiltfilt(sos, qd, axis=0)
    columns = FilteredColumns(sos, ((qd_f, rows),), t[rows])
    grid = np.geomspace(0.002, 0.1, 200)

    def best(column_of) -> float:
        res = [np.linalg.norm(tau[rows] - (A := np.column_stack([qd_f[rows], column_of(v)]))
                              @ np.linalg.lstsq(A, tau[rows], rcond=None)[0]) for v in grid]
        return float(grid[int(np.argmin(res))])

    parallel = best(lambda v: filtered.coulomb(columns, t[rows], (Law(coulomb_velocity=v),), None))
    plain = best(lambda v: np.tanh(qd_f[rows] / v))
    assert abs(parallel / 0.01 - 1) <= 0.05 and plain >= 1.5 * 0.01, (parallel, plain)


@pytest.mark.slow  # two searches of six joints' laws, about 5 s
def test_the_law_search_with_a_filter_that_passes_everything_is_the_search_without_one():
    """friction_law.choose on a 1.5 s bench recording of ur5_friction (families allowed), once with the
    friction columns read through a pass-all filter at the full rate (every sample kept) and once
    computed directly: the same law for every joint and the same held-out errors, to round-off."""
    import dataclasses

    from harness.api import load_scenario
    from harness.identify.friction_law import FrictionLawConfig, choose
    from harness.identify.torque_id import regressor
    from harness.sources.bench import record
    from harness.stages.log_model import log_model
    from tests.conftest import SCENARIOS

    sc = load_scenario(SCENARIOS / "ur5_friction.toml")
    rec = record(dataclasses.replace(sc, duration=1.5, output_steps=300))
    joints = sc.robot.joint_names
    q, qd, qdd, tau = rec.joint_data(joints)
    model = log_model(sc.robot, sc.gravity_W)
    W = regressor(model.pm, q, qd, qdd, with_friction=True)
    passing = FilteredColumns(PASS_ALL, ((qd, np.arange(len(qd))),), rec.t, 1e9)
    found = [choose(W, model.base.independent, model.link_part, tau, qd, rec.t, sc.robot.frictions,
                    FrictionLawConfig(), 0.0, None, columns, q=q) for columns in (None, passing)]
    assert found[0].laws == found[1].laws
    assert found[1].chosen_error == pytest.approx(found[0].chosen_error, rel=1e-9)


@pytest.mark.parametrize(("order", "cutoff_hz"), [(4, 10.0), (3, 20.0), (6, 50.0)])
def test_the_columns_filter_is_scipys_sosfiltfilt_bit_for_bit(order, cutoff_hz):
    """The column filter, its initial conditions computed once (the law search filters thousands of
    columns), is scipy.signal.sosfiltfilt to the last bit: one column, several, and one too short for
    the padding (scipy's own answer)."""
    from scipy.signal import sosfilt_zi

    from harness.sources.log.condition import zero_phase

    sos = butter(order, cutoff_hz, fs=1000.0, output="sos")
    rng = np.random.default_rng(order)
    for x in (rng.normal(size=(5000, 1)), rng.normal(size=(3000, 7)), np.cumsum(rng.normal(size=(200, 2)), axis=0)):
        np.testing.assert_array_equal(zero_phase(sos, x, sosfilt_zi(sos)), sosfiltfilt(sos, x, axis=0))
    with pytest.raises(ValueError, match="padlen"):
        zero_phase(sos, rng.normal(size=(10, 1)), sosfilt_zi(sos))


def test_two_stretches_joined_filter_each_on_its_own():
    """A log cut at a gap keeps each stretch's full-rate velocities: the joined columns are each
    stretch's filtered columns, in order, at the rows asked for."""
    sos = butter(4, 10.0, fs=1000.0, output="sos")
    rng = np.random.default_rng(5)
    parts = []
    for start in (0.0, 10.0):
        qd = np.cumsum(rng.normal(size=(3000, 2)), axis=0) * 1e-3
        rows = np.arange(100, 2900, 10)
        parts.append(FilteredColumns(sos, ((qd, rows),), start + rows / 1000.0, 10.0))
    joined = FilteredColumns.joined(parts)
    t = np.concatenate([parts[0].t[::3], parts[1].t[5:]])
    expected = np.concatenate([parts[0].filtered(np.tanh, parts[0].t[::3]), parts[1].filtered(np.tanh, parts[1].t[5:])])
    np.testing.assert_array_equal(joined.filtered(np.tanh, t), expected)
    qd, rows = parts[1].stretches[0]
    np.testing.assert_array_equal(parts[1].filtered(np.tanh, parts[1].t[5:]),
                                  sosfiltfilt(sos, np.tanh(qd), axis=0)[rows][5:])
