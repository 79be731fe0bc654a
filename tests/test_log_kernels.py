"""The measured-log path's kernels, each on synthetic data against an independent reference, in the fast
suite: a logger's hold is a whole repeated row, the torque constants' interval is the bootstrap draws'
quantiles at its level, a delay between grid points is the vertex of its parabola, the refinement's
second pass starts from the first pass's delays, the default low-pass reads the accelerations' noise
from the velocities they are differences of. Each pins a one-line mutant that only slow tests (or
no test) saw: np.all -> np.any in the hold, a 90 % interval labelled 95 %, the vertex's sign, a second
pass from zero delays."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from harness.model.load import load_spec
from tests.conftest import ROOT

ARM = ROOT / "examples" / "two_link_arm" / "two_link_arm.toml"


def test_a_hold_is_a_whole_repeated_row_not_a_quantised_position_beside_a_still_channel():
    """400 rows of a two-joint log: positions quantised to 1 mrad (they repeat while the torques move),
    the elbow's torque channel constant (a channel that reads nothing), and 7 rows that repeat the row
    before them whole (a logger's hold). The check drops those 7 and keeps every other row, counting
    the repeated positions it keeps; a hold read off any one channel would drop hundreds."""
    from harness.sources.log.checks import check
    from harness.sources.log.raw import RawLog

    robot = load_spec(ARM)
    t = np.arange(400) * 0.002
    q = np.round(np.stack([0.2 * np.sin(2 * t), 0.1 * np.cos(3 * t)], axis=1), 3)
    tau = np.stack([5 + np.sin(7 * t), np.full_like(t, 0.25)], axis=1)
    held = np.array([50, 51, 120, 200, 201, 202, 333])
    for k in held:  # in order: a hold of two rows repeats the row before both
        q[k], tau[k] = q[k - 1], tau[k - 1]
    raw = RawLog(t, tuple(robot.joint_names), q, None, tau, Path("log.csv"))
    same_q = np.all(q[1:] == q[:-1], axis=1)
    checked = check(raw, robot)
    assert checked.record["repeated_rows_dropped"] == len(held)
    assert checked.record["repeated_positions_kept"] == int(same_q.sum()) - len(held) > 50
    assert len(checked.kept.t) == len(t) - len(held) and not np.isin(t[held], checked.kept.t).any()


def test_the_torque_constants_interval_is_the_draws_quantiles_at_its_level():
    """`_interval` of 10,000 draws: the standard deviation and the draws' quantiles at (1 -+ LEVEL) / 2
    by numpy's own quantile (a 90 % interval labelled 95 % is 12 % narrower on normal draws)."""
    from harness.identify import scale

    draws = np.random.default_rng(5).normal(size=(10_000, 3)) * [1.0, 2.0, 0.5]
    std, ci = scale._interval(draws)
    assert scale.LEVEL == 0.95
    np.testing.assert_allclose(ci, np.quantile(draws, [0.025, 0.975], axis=0).T, rtol=1e-12)
    np.testing.assert_allclose(std, draws.std(axis=0, ddof=1), rtol=1e-12)


@pytest.mark.parametrize("d0", [0.0013, -0.0007, 0.00049])
def test_a_delay_between_grid_points_is_the_vertex_of_its_residuals_parabola(d0):
    """Squared residuals a (d - d0)^2 + c at a grid of 1 ms around the best point, d0 off the grid on
    either side (an asymmetric triple): the vertex is d0 and its residual sqrt(c), to round-off."""
    from harness.identify.delay import vertex

    h, a, c = 1e-3, 4e5, 0.09
    at = round(d0 / h) * h
    residuals = np.sqrt(a * (at + np.array([-h, 0.0, h]) - d0) ** 2 + c)
    found, residual = vertex(residuals, at, h)
    assert found == pytest.approx(d0, abs=1e-15) and residual == pytest.approx(np.sqrt(c), rel=1e-12)


def test_a_delay_estimated_between_grid_points_on_a_lagging_channel_is_found_there():
    """estimate() on a channel 1.3 grid steps late, the regressor three columns that cannot absorb a
    shift in time (no cosine beside its sine): found at 1.3 steps within a tenth of one, on the side the
    channel lags (a vertex of the wrong sign lands at 0.7)."""
    from harness.identify import delay

    t = np.arange(4000) * 1e-3
    W = np.stack([np.sin(2.1 * t), np.cos(5.3 * t), np.ones_like(t)], axis=1)
    late = 1.3e-3
    tau = (np.sin(2.1 * (t - late)) + 0.5 * np.cos(5.3 * (t - late)) + 0.2)[:, None]
    found = delay.estimate(t, tau, W[:, None, :], largest=0.01, step=1e-3, filtered=True)
    assert found.delay[0] == pytest.approx(late, abs=1e-4)


def test_the_refinements_second_pass_starts_from_the_first_pass_delays(monkeypatch):
    """The passes of stages/refinement.py `run` with every computation but their order replaced: the
    first pass starts at zero delays, and each later one at the delays the pass before found (a second
    pass started from zero moved the refitted candidates' errors 0.0099 -> 0.0101 on ur5_bench_log,
    which no gate saw)."""
    from harness.identify.refine import RefineConfig
    from harness.stages import refinement

    started, n = [], 2

    def refine(spec, gravity_W, t, q, qd, qdd, tau, rigid, laws, config, lag):
        started.append(np.array(lag))
        return SimpleNamespace(delay=np.asarray(lag) + [1e-3, -2e-3], frictions=(), cost={"start": 1.0, "refined": 1.0},
                               torque_rel_error={"start": 0.01, "refined": 0.01})

    for name, value in (("refine", refine), ("identified_spec", lambda *a: "spec"), ("_rigid", lambda *a: None),
                        ("_refit", lambda *a: (None, (), ())), ("judge", lambda *a: (1.0, 0.01)),
                        ("_judged", lambda *a: {}), ("_beside", lambda ctx: {})):
        monkeypatch.setattr(refinement, name, value)
    judged = SimpleNamespace(t={"training": None}, states={"training": (None, None, None)},
                             measured={"training": None})
    li = SimpleNamespace(joints=["a", "b"][:n], judged=judged, fit=SimpleNamespace(theta=None), frictions=(),
                         laws=SimpleNamespace(laws=()), gravity=SimpleNamespace(gravity_W=None))
    ctx = SimpleNamespace(done={"log_identification": li}, scenario=SimpleNamespace(robot=None, gravity_W=None),
                          progress=lambda *a: None)
    refinement.run(ctx, RefineConfig(passes=3))
    np.testing.assert_array_equal(started[0], [0.0, 0.0])
    np.testing.assert_allclose(started[1], [1e-3, -2e-3])
    np.testing.assert_allclose(started[2], [2e-3, -4e-3])


@dataclasses.dataclass(frozen=True)
class _Source:
    """The [data] keys the defaults read: none given."""

    cutoff: float | None = None
    decimate: int = 1
    decimate_given: bool = False


def _slow_log(noise: float, with_velocities: bool = True, cut: slice | None = None):
    """20 s at 500 Hz of two joints moving slowly (0.3 and 0.45 Hz: a lab's slow excitation), their
    positions exact, their logged velocities exact plus white noise of `noise` rad/s (seed 0); `cut`
    rows removed (a gap bridged by interpolation)."""
    from harness.sources.log.raw import RawLog

    t = np.arange(10_000) / 500.0
    w = 2 * np.pi * np.array([0.3, 0.45])
    q, qd, qdd = np.sin(w * t[:, None]), w * np.cos(w * t[:, None]), -(w**2) * np.sin(w * t[:, None])
    qd = qd + noise * np.random.default_rng(0).standard_normal(qd.shape)
    keep = np.ones(len(t), dtype=bool)
    if cut is not None:
        keep[cut] = False
    raw = RawLog(t[keep], ("a", "b"), q[keep], qd[keep] if with_velocities else None, np.zeros((keep.sum(), 2)),
                 Path("log.csv"))
    return raw, qdd


def test_the_default_filter_reads_the_noise_of_the_velocities_the_accelerations_come_from():
    """Slow motion with a quiet velocity sensor: white noise of 1e-4 rad/s on logged velocities of RMS
    1.3 and 2.0 rad/s is under the velocity's noise threshold (median level about 5e-5 and 3.4e-5 against
    NOISY = 1e-4), but differentiated at 500 Hz it is sqrt(2) x 500 x 1e-4 = 0.071 rad/s^2 of noise on
    accelerations of RMS 2.5 and 5.6 rad/s^2: the accelerations' noise level the defaults read is that
    ratio (within 10 %: a white noise's median over 0.6745 is its RMS to 1 % on 10,000 samples), over
    ACCELERATION_NOISE = 1 %, and a low-pass is chosen. The same exact positions without a velocity
    column (their differences are what is differentiated), or logged without noise and with 50 ms cut
    out (a kink where the gap is bridged: one sample, not noise), are left unfiltered."""
    from harness.sources.log import defaults

    raw, qdd = _slow_log(1e-4)
    s = defaults.spectra(raw, 500.0)
    expected = np.sqrt(2) * 500.0 * 1e-4 / np.sqrt(np.mean(qdd**2, axis=0))
    np.testing.assert_allclose(s.acceleration_level, expected, rtol=0.1)
    assert np.all(s.level < defaults.NOISY) and np.all(s.acceleration_level > defaults.ACCELERATION_NOISE)
    source = _Source()
    chosen, record = defaults.resolve(source, raw, 500.0)
    assert record["differentiated"] == "logged velocities" and chosen.cutoff == record["cutoff_hz"]
    assert defaults.CUTOFF_FACTOR * max(s.band) <= chosen.cutoff <= min(s.noise_cutoff)
    for quiet in (_slow_log(1e-4, with_velocities=False)[0], _slow_log(0.0, cut=slice(4000, 4025))[0]):
        assert not defaults.noisy(defaults.spectra(quiet, 500.0))
        assert defaults.resolve(source, quiet, 500.0) == (source, None)
