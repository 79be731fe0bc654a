"""Measurement conditions (rounding, noise, sampling, differentiated accelerations) and the
honesty of the stated uncertainty (sweeps)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from harness.base.workers import Workers
from harness.papers.graph_theory_2021.readings import exact, read
from harness.papers.graph_theory_2021.sweep import run_sweep
from harness.runner.scenario import load_scenario
from harness.sources.bench import record
from harness.sources.measurement import Measurement, Noise, measure
from tests.conftest import SCENARIOS


@pytest.fixture(scope="module")
def recording():
    return record(load_scenario(SCENARIOS / "kr500_rail.toml"))


def test_noise_has_the_stated_statistics(recording):
    """1 % relative plus 0.5 N absolute on forces: (measured - true) / std is standard normal.
    Over 101 x 7 x 3 = 2121 values its mean is within 4 / sqrt(n) = 0.09 of 0 and its standard
    deviation within 4 sqrt(1 / (2 n)) = 0.06 of 1 (four standard errors)."""
    m = Measurement(noise={"forces": Noise(relative=0.01, absolute=0.5)}, seed=3)
    z = ((measure(recording, m).F_W - recording.F_W) / np.sqrt(0.5**2 + (0.01 * recording.F_W) ** 2)).ravel()
    n = z.size
    assert abs(z.mean()) < 4 / np.sqrt(n)
    assert abs(z.std() - 1) < 4 * np.sqrt(1 / (2 * n))
    # other channels untouched; the same seed gives the same data, another seed other data
    np.testing.assert_array_equal(measure(recording, m).M_W, recording.M_W)
    np.testing.assert_array_equal(measure(recording, m).F_W, measure(recording, m).F_W)
    assert not np.array_equal(measure(recording, m).F_W, measure(recording, m.with_seed(4)).F_W)


def test_rounding_keeps_the_stated_digits(recording):
    rounded = measure(recording, Measurement(significant_digits=4))
    x, y = recording.F_W.ravel(), rounded.F_W.ravel()
    big = np.abs(x) > 1e-300
    assert np.all(np.abs(y[big] - x[big]) <= 0.5e-3 * np.abs(x[big]) * (1 + 1e-12))
    assert all(float(f"{v:.3e}") == v for v in y[big][:500])


def test_sampling_keeps_every_kth_step(recording):
    sub = measure(recording, Measurement(every=4))
    np.testing.assert_array_equal(sub.t, recording.t[::4])
    np.testing.assert_array_equal(sub.F_W, recording.F_W[::4])


@pytest.mark.slow  # a second or more: a whole pipeline, or processes
def test_differentiated_accelerations_converge_to_the_sensors():
    """Accelerations from positions and angles (cubic Savitzky-Golay, 7 samples), the joint points'
    too: the error against the acceleration sensors falls by at least 3 each time the step halves
    (second order: 4 in the limit); B1 passes gimbal lock six times on the way (omega = D theta'
    needs no inverse of D). The joints move at constant acceleration in kr500_rail, which a cubic
    filter differentiates exactly: their q' and q'' agree to round-off (1e-8) at every step."""
    sc = load_scenario(SCENARIOS / "kr500_rail.toml")
    errors = []
    for steps in (400, 800, 1600):
        rec = record(dataclasses.replace(sc, output_steps=steps))
        m = Measurement(differentiate=True)
        arms = sc.robot.inner_joint_arms_B()
        truth = exact(rec, arms)
        d = read(truth, measure(rec, m), m, arms)  # the core's channels and the study's readings
        inner = slice(10, -10)  # the filter's end effects
        err = [np.max(np.abs(getattr(d, c)[inner] - getattr(truth, c)[inner])) / np.max(np.abs(getattr(truth, c)))
               for c in ("a_W", "aO_W", "omega_W", "omegadot_W")]
        errors.append(err)
        for c in ("qd", "qdd"):
            want = getattr(rec, c)[inner]
            assert np.max(np.abs(getattr(d, c)[inner] - want)) <= 1e-8 * np.max(np.abs(want))
    errors = np.array(errors)
    assert np.all(errors[1:] < errors[:-1] / 3), errors
    assert errors[-1].max() < 2e-2


@pytest.mark.slow  # 1000 trials: about 20 s
def test_noise_sweep_intervals_cover_about_95_percent():
    """kr500_noise, 1000 trials: every parameter identified in every trial has its 95 % interval
    containing the true value in 90 % to 98 % of the trials. The binomial standard error at 1000
    trials is 0.7 %; measured, the coverage lies between 92.3 % and 96.1 % (least squares with a
    noisy regressor is biased by 0.1 to 0.3 standard deviations), so each bound keeps at least
    two standard errors from what is measured."""
    sc = load_scenario(SCENARIOS / "kr500_noise.toml")
    sweep = run_sweep(sc, 1000, Workers(processes=2), levels=(1.0,))
    always = [p for p in sweep["parameters"] if p["identifiable_fraction"] == 1.0]
    assert len(always) >= 30
    for p in always:
        assert 0.90 <= p["coverage_ci95"] <= 0.98, (p["body"], p["name"], p["coverage_ci95"])


def test_a_bench_samples_then_reads_then_differentiates_what_it_read(recording):
    """Order of the measurement: sampling, then noise and rounding of each reading, then the
    derivatives of the rounded, sampled readings (not of the full-rate truth); the graph-theory
    study's own readings (its angles, from a stream of its own) in the same order."""

    from harness.papers.graph_theory_2021 import readings
    from harness.sources.measurement import add_noise, add_noise_to, differentiate, round_significant, study_stream

    m = Measurement(significant_digits=4, encoder_resolution=1e-4, every=2, differentiate=True, seed=5,
                    noise={"positions": Noise(absolute=1e-4), "angles": Noise(absolute=1e-4)})
    arms = load_scenario(SCENARIOS / "kr500_rail.toml").robot.inner_joint_arms_B()
    got = measure(recording, m)
    rows = np.arange(0, len(recording.t), 2)
    sampled = recording.span(rows)
    noisy = add_noise(sampled, m.noise, np.random.default_rng(5))
    p_read = round_significant(noisy["p_W"], 4)
    np.testing.assert_array_equal(got.p_W, p_read)
    # joint positions: rounded to 4 digits, then read in counts of 1e-4 rad from a zero anywhere
    # within a count: on a grid of 1e-4 per joint, within half a count of what was there
    q4 = round_significant(recording.q[rows], 4)
    counts = (got.q - got.q[0]) / 1e-4
    np.testing.assert_allclose(counts, np.round(counts), rtol=0, atol=1e-6)
    assert np.max(np.abs(got.q - q4)) <= 0.5e-4 * (1 + 1e-9)
    derived = differentiate(sampled.t, got.q, p_read, 7)
    for c in ("qd", "qdd", "a_W"):
        np.testing.assert_array_equal(getattr(got, c), derived[c])
    # the study's readings: its angles sampled, read with their noise and rounded, then differentiated
    truth = readings.exact(recording, arms)
    view = readings.read(truth, got, m, arms)
    theta = add_noise_to({"theta": truth.theta[rows]}, {"angles": ("theta",)}, m.noise,
                         study_stream(m, readings.STREAM))["theta"]
    theta_read = round_significant(theta, 4)
    np.testing.assert_array_equal(view.theta, theta_read)
    derived = readings.differentiate(sampled.t, p_read, theta_read, 7, arms)
    for c in ("aO_W", "omega_W", "omegadot_W"):
        np.testing.assert_array_equal(getattr(view, c), derived[c])


def test_differentiating_replaces_every_acceleration_sensor(recording):
    """With `differentiate`, no acceleration reaches the identification from an accelerometer: a
    30 % noise on the acceleration sensors changes none of the derived channels, the joint points'
    no more than the centres' (how close they come to the truth: the convergence test above)."""
    arms = load_scenario(SCENARIOS / "kr500_rail.toml").robot.inner_joint_arms_B()
    truth = exact(recording, arms)
    plain, shaken = Measurement(differentiate=True), Measurement(differentiate=True,
                                                                  noise={"accelerations": Noise(relative=0.3)})
    clean = read(truth, measure(recording, plain), plain, arms)
    noisy = read(truth, measure(recording, shaken), shaken, arms)
    for c in ("a_W", "aO_W"):
        np.testing.assert_array_equal(getattr(noisy, c), getattr(clean, c))
        assert not np.array_equal(getattr(noisy, c), getattr(truth, c))
