"""What guards the measured-log path (harness/sources/log/, harness/stages/log_identification.py), in the
fast suite, each claim against a reference that needs no run of the harness to know:
- the split: one validation sample changed leaves the training span bit for bit as it was, and so every
  fitted number of the log run (the fit reads the training span alone, the spans are conditioned apart,
  the friction law is chosen inside the training span); the guard band between the spans is at least
  twice the conditioning's reach;
- a channel's delay: the sign on a shifted signal, and the correction on a ramp, where the answer is exact;
- the prediction's horizons: a body under a constant force drifts by 0.5 da h^2 at horizon h;
- the friction law's cross-validation: folds held out with a guard, scored out of sample (noise
  predicted from other data is worse than no prediction at all, and fitted in-sample it is better);
- gates at their limit, in both directions.
The arm is a two-link arm with drives whose every per-joint value differs from the other joint's, so
that a joint read for another shows."""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest

from harness.api import load_scenario
from harness.base.series import TimeSeries
from harness.identify import delay
from harness.identify.friction_law import FrictionLawConfig, blocked_folds, choose
from harness.model.friction import JointFriction
from harness.runner.gates import Gate, check
from harness.sources.bench import record, write_log
from harness.sources.log import load
from harness.sources.log.schema import Prediction
from harness.sources.log.segments import guard_band
from tests.conftest import ROOT, numbers_of, two_link_bench, write_frame

URDF = ROOT / "examples" / "two_link_arm" / "two_link_arm.urdf"
DRIVES = {"shoulder": dict(armature=0.031, viscous=0.42, coulomb=0.63, offset=0.05, coulomb_velocity=0.021),
          "elbow": dict(armature=0.012, viscous=0.17, coulomb=0.24, offset=-0.03, coulomb_velocity=0.033)}
GATE = '[[gates]]\nmetric = "log_identification.validation_rel_error.consistent"\nlimit = 0.05\n'


def _model(folder) -> str:
    (folder / "arm.toml").write_text(f'[model]\nname = "arm"\n[urdf]\nfile = "{URDF}"\n' + "".join(
        f"[joints.{j}]\n" + "".join(f"{k} = {v!r}\n" for k, v in d.items()) for j, d in DRIVES.items()))
    return "arm.toml"


@pytest.fixture(scope="module")
def arm_log(tmp_path_factory):
    """A 6 s bench log of the arm at 500 Hz (t, q, q', tau: the engine's own torques, no noise), and a
    scenario that identifies the arm from it, filtered at 15 Hz, validated on its last 30 %."""
    folder = tmp_path_factory.mktemp("arm")
    model = _model(folder)
    bench = two_link_bench(folder, model, 6.0, 3000)
    write_log(record(bench), bench.robot.joint_names, folder / "log.csv")
    (folder / "s.toml").write_text(
        f'[scenario]\nmodel = "{model}"\n[data]\nfile = "log.csv"\n'
        'columns = { t = "t", q = "q{j}", qd = "qd{j}", tau = "tau{j}" }\nunits = { q = "rad", qd = "rad/s", '
        'tau = "N m" }\ncutoff = 15.0\nvalidation = { from = 0.7 }\n' + GATE)
    return folder


def _with_validation_sample_changed(folder, name: str) -> None:
    """folder/name/: the arm's log and scenario with one torque sample of the validation span made 1000
    times larger (a glitch no filter can hide: carried across the split, it would move every fit)."""
    df = pd.read_csv(folder / "log.csv")
    row = int(0.85 * len(df))
    df.loc[row, "tau2"] *= 1000.0
    (folder / name).mkdir(exist_ok=True)
    write_frame(df, folder / name / "log.csv")
    (folder / name / "arm.toml").write_text((folder / "arm.toml").read_text())
    (folder / name / "s.toml").write_text((folder / "s.toml").read_text())


def test_one_validation_sample_changed_leaves_the_training_span_bit_identical(arm_log):
    """The spans are conditioned apart: not a bit of the training span moves when a validation sample
    does (a log filtered whole, then split, moves the training span's end by the filter's reach), and
    the validation span does move. The guard band between them is at least twice the conditioning's
    reach (each span trimmed by it at the split)."""
    _with_validation_sample_changed(arm_log, "changed")
    sc, changed = load_scenario(arm_log / "s.toml"), load_scenario(arm_log / "changed" / "s.toml")
    a, b = load(sc.data, sc.robot), load(changed.data, changed.robot)
    for k in ("t", "q", "qd", "qdd", "tau"):
        assert np.array_equal(getattr(a.training, k), getattr(b.training, k)), k
    assert not np.array_equal(a.validation.tau, b.validation.tau)
    reach = guard_band(sc.data, 500.0)
    assert reach == pytest.approx(3 / 15.0)
    assert a.guard_band_s >= 2 * reach
    assert a.training.t[-1] < a.validation.t[0]


@pytest.fixture(scope="module")
def arm_runs(arm_log):
    """The arm identified from its log, and from the log with one validation sample changed."""
    import harness

    _with_validation_sample_changed(arm_log, "changed_run")
    return harness.run(arm_log / "s.toml"), harness.run(arm_log / "changed_run" / "s.toml")


def test_every_fitted_number_is_the_training_spans_alone(arm_runs):
    """The delays, the friction laws chosen, the least squares, the consistent fit, the training span's
    errors and every exported file are bit for bit those of the unchanged log; only the validation
    span's errors move. A fit, a delay, a law choice or a conditioning that read any row of the
    validation span would move by orders of magnitude more than round-off."""
    before, after = (r.results["log_identification"] for r in arm_runs)
    for key in ("delays", "friction_law", "least_squares", "consistent"):
        assert numbers_of(after[key]) == numbers_of(before[key]), key
    assert numbers_of(after["errors"]["training"]) == numbers_of(before["errors"]["training"])
    assert after["errors"]["validation"]["consistent"]["rel_error"] > 2 * before["errors"]["validation"][
        "consistent"]["rel_error"]
    assert arm_runs[0].output.files == arm_runs[1].output.files


def test_the_arm_comes_back_from_its_own_log(arm_runs):
    """Not a vacuous fit: on a noise-free bench log its held-out torques are the engine's within 1 %
    (the conditioning's differences at 15 Hz), and the friction law was chosen (by cross-validation)."""
    li = arm_runs[0].results["log_identification"]
    assert li["validation_rel_error"]["consistent"] < 0.01
    assert li["friction_law"]["chosen"] and li["friction_law"]["guard_s"] == pytest.approx(0.2)


def test_a_fit_takes_the_training_span_and_refuses_the_validation_span(arm_log):
    """The training span is a type (TrainingSpan) the fitting steps take: handed the validation span
    they refuse it, a harness bug, before reading a row; a delay corrected on it or a span of it stays
    one. What the fit finds the judging applies to the validation span (log_judge.as_fitted): a delay
    found on the training rows moves the validation span's torques as it moved the training span's."""
    from harness.sources.log.condition import TrainingSpan
    from harness.stages.log_identification import delays
    from harness.stages.log_judge import as_fitted
    from harness.stages.log_model import log_model

    sc = load_scenario(arm_log / "s.toml")
    split = load(sc.data, sc.robot)
    model = log_model(sc.robot, sc.gravity_W)
    assert isinstance(split.training, TrainingSpan) and not isinstance(split.validation, TrainingSpan)
    with pytest.raises(TypeError, match="training span alone"):
        delays("correct", model, split.validation)
    lags = delay.Delays(np.array([0.004, 0.0]), np.full(2, 0.1), np.ones(2), np.array([-0.02, 0.02]),
                        np.zeros((2, 2)), np.array([False, True]))  # the first joint's found
    joints = list(sc.robot.joint_names)
    assert isinstance(delay.corrected(split.training, lags, joints), TrainingSpan)
    assert isinstance(split.training.span(slice(0, 50)), TrainingSpan)
    judged = as_fitted(split.validation, lags, np.array([2.0, 3.0]), joints)
    by_hand = delay.corrected(split.validation, lags, joints)
    assert len(by_hand.t) < len(split.validation.t)  # read 4 ms later: the last rows have no later reading
    np.testing.assert_array_equal(judged.tau, by_hand.tau * [2.0, 3.0])
    assert as_fitted(split.validation, None, None, joints) is split.validation


def _positions_log(arm_log, name: str, step: float | None, spike: bool = False) -> load_scenario:
    """folder/name/: the arm's log with positions and torques only and no cutoff given; its positions
    read through an encoder of `step` rad (None: exact), and with `spike` one position of the validation
    span 0.05 rad off."""
    df = pd.read_csv(arm_log / "log.csv")[["t", "q1", "q2", "tau1", "tau2"]]
    if step is not None:
        df[["q1", "q2"]] = np.round(df[["q1", "q2"]].to_numpy() / step) * step
    if spike:
        df.loc[int(0.85 * len(df)), "q1"] += 0.05
    folder = arm_log / name
    folder.mkdir(exist_ok=True)
    write_frame(df, folder / "log.csv")
    (folder / "arm.toml").write_text((arm_log / "arm.toml").read_text())
    (folder / "s.toml").write_text(
        '[scenario]\nmodel = "arm.toml"\n[data]\nfile = "log.csv"\ncolumns = { t = "t", q = "q{j}", tau = "tau{j}" }'
        '\nunits = { q = "rad", tau = "N m" }\nvalidation = { from = 0.7 }\n' + GATE)
    return load_scenario(folder / "s.toml")


def _white_quantisation_cutoff(q: np.ndarray, step: float, rate: float, qdd_power: float, f_from: float) -> float:
    """The cut-off at which a quantiser's error, as white noise of its own variance, differentiated twice
    (|H(f)|^2 = (2 sin(pi f / fs))^4 fs^4, one-sided density 2 var / fs), carries between f_from and the
    cut-off 1e-4 of the motion's acceleration power: the default's rule written out."""
    var = np.var(np.round(q / step) * step - q)
    f = np.linspace(f_from, rate / 2, 200_001)
    density = 2 * var / rate * rate**4 * 16 * np.sin(np.pi * f / rate) ** 4
    passed = np.concatenate([[0.0], np.cumsum((density[1:] + density[:-1]) / 2 * np.diff(f))])
    return float(f[np.searchsorted(passed, 1e-4 * qdd_power)])


def test_a_quantised_encoder_gets_the_highest_cutoff_its_noise_allows_and_exact_positions_none(arm_log):
    """Where no cutoff is given, positions read through a 2e-4 rad encoder step are filtered where the
    accelerations' noise let through reaches 1 % of the motion's (RMS): on each joint, the quantiser's
    error taken as white noise of its own variance, differentiated twice, and the motion's acceleration
    power from the log's exact velocities, both over the training span, give that cut-off independently;
    the data's is within -5 % and +15 % of it (a quantiser's error is whitest when the joint moves many
    steps a sample: at the reversals it is correlated and quieter at high frequency, so the measured
    cut-off sits at or above the white one; 15 % in a cut-off is a factor 2 in noise power). The lowest
    joint's decides, and it is said; the exact positions of the same motion are left unfiltered."""
    quantised = _positions_log(arm_log, "encoder", 2e-4)
    split = load(quantised.data, quantised.robot)
    chosen = split.whole.meta["defaults"]
    df = pd.read_csv(arm_log / "log.csv")
    training = df["t"].to_numpy() < 0.7 * df["t"].iloc[-1]
    for j, found in enumerate(chosen["noise_cutoff_hz"]):
        qdd = np.gradient(df[f"qd{j + 1}"].to_numpy()[training], 1 / 500.0)
        white = _white_quantisation_cutoff(df[f"q{j + 1}"].to_numpy()[training], 2e-4, 500.0, np.var(qdd),
                                           10 * chosen["motion_band_hz"][j])
        assert 0.95 * white <= found <= 1.15 * white, (j, found, white)
    assert split.source.cutoff == chosen["cutoff_hz"] == min(chosen["noise_cutoff_hz"])
    assert any("low-pass chosen" in w for w in split.whole.meta["warnings"])
    exact = _positions_log(arm_log, "exact", None)
    plain = load(exact.data, exact.robot)
    assert plain.whole.meta["defaults"] is None and plain.source.cutoff is None


def test_what_the_data_decide_they_decide_from_the_training_rows(arm_log):
    """The default cutoff is chosen from the training span alone: a 0.05 rad spike in a position of the
    validation span (a spectrum read whole would widen the band) leaves the cutoff and the training
    span bit for bit as they were."""
    a, b = (_positions_log(arm_log, name, 2e-4, spike) for name, spike in (("clean", False), ("spiked", True)))
    sa, sb = load(a.data, a.robot), load(b.data, b.robot)
    assert sa.source.cutoff == sb.source.cutoff is not None
    for k in ("t", "q", "qd", "qdd", "tau"):
        assert np.array_equal(getattr(sa.training, k), getattr(sb.training, k)), k
    assert not np.array_equal(sa.validation.q, sb.validation.q)


def test_a_lagging_channel_is_found_late_by_its_delay_with_the_sign_of_the_lag():
    """A channel that lags by d reads tau(t - d): on a regressor column f(t) of incommensurate
    sinusoids, the delay found is +d (the parabola through the grid's best point to a tenth of its
    0.5 ms step), and found (inside the search, a residual well below the one at zero delay)."""
    t = np.arange(0.0, 4.0, 0.001)

    def f(x):
        return np.sin(2 * np.pi * 1.3 * x) + 0.5 * np.sin(2 * np.pi * 3.7 * x + 0.4)

    for d in (0.004, -0.0065):
        lags = delay.estimate(t, f(t - d)[:, None], f(t)[:, None, None])
        assert lags.delay[0] == pytest.approx(d, abs=5e-5)
        assert lags.found[0]


def test_a_delay_estimated_but_not_found_is_said_with_its_estimate():
    """Of three channels: one found at 4 ms (said once, as behind the encoders, when only estimated),
    one whose best candidate sits at the search's edge (-19.5 ms: said, with the edge named), and one
    whose 3 ms estimate does not beat zero delay clearly (said, not corrected); a clean channel at
    0.2 ms not found is not worth a line."""
    from harness.stages.log_identification import delay_warnings

    lags = delay.Delays(np.array([0.004, -0.0195, 0.003, 0.0002]), np.array([0.1, 0.5, 0.95, 1.0]),
                        np.array([1.0, 0.6, 1.0, 1.0]), np.array([-0.02, 0.02]), np.zeros((4, 2)),
                        np.array([False, True, False, False]))
    said = delay_warnings(lags, ["a", "b", "c", "d"], "estimate")
    assert len(said) == 2 and said[0].endswith("a 4 ms")
    assert "estimated but not found" in said[1] and said[1].endswith("b -19.5 ms (at the edge), c 3 ms")
    assert delay_warnings(lags, ["a", "b", "c", "d"], "correct") == [said[1]]
    assert delay_warnings(None, ["a"], "estimate") == []


def test_a_found_delay_is_corrected_by_reading_the_channel_that_much_later():
    """On a ramp the correction is exact: a channel lagging by d reads a (t - d); read d later it is a t,
    to round-off, and the rows whose later reading would pass the end are dropped."""
    t = np.arange(0.0, 1.0, 0.001)
    d = 0.0042
    lagging = TimeSeries(t, ("j",), np.zeros((len(t), 1)), np.zeros((len(t), 1)), np.zeros((len(t), 1)),
                         3.0 * (t - d)[:, None])
    lags = delay.Delays(np.array([d]), np.array([0.1]), np.array([1.0]), np.array([-0.02, 0.02]),
                        np.zeros((1, 2)), np.array([False]))
    corrected = delay.corrected(lagging, lags, ["j"])
    np.testing.assert_allclose(corrected.tau[:, 0], 3.0 * corrected.t, rtol=0, atol=1e-12)
    assert corrected.t[-1] <= t[-1] - d and len(corrected.t) >= len(t) - 6


SLIDE = """<robot name="slide"><link name="base"/>
<joint name="x" type="prismatic"><parent link="base"/><child link="cart"/><axis xyz="1 0 0"/>
<limit lower="-100" upper="100" effort="100" velocity="100"/></joint>
<link name="cart"><inertial><mass value="{mass}"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0"
iyz="0"/></inertial></link></robot>"""


@pytest.mark.parametrize("plan", [Prediction(), Prediction(5, (0.003, 0.3))], ids=["default", "[data] prediction"])
def test_the_prediction_drifts_by_half_the_acceleration_error_times_the_horizon_squared(tmp_path, plan):
    """A cart of 2 kg under a constant 3 N, logged exactly; a model of the cart with 2.5 kg, started
    from the logged states, drifts by 0.5 (3/2.5 - 3/2) h^2 at horizon h (RK4 integrates a parabola
    exactly): each horizon's RMS error is that to 1e-9 of itself, at the horizons and from the number
    of starts the plan asks for."""
    from harness.model.load import load_spec
    from harness.stages.log_judge import prediction

    (tmp_path / "cart.urdf").write_text(SLIDE.format(mass=2.5))
    (tmp_path / "cart.toml").write_text('[model]\nname = "cart"\n[urdf]\nfile = "cart.urdf"\n')
    model = load_spec(tmp_path / "cart.toml")
    t = np.arange(0.0, 1.0, 0.001)
    a_true, a_model = 3.0 / 2.0, 3.0 / 2.5
    q, qd, tau = (0.5 * a_true * t**2)[:, None], (a_true * t)[:, None], np.full((len(t), 1), 3.0)
    out = prediction(np.zeros(3), {"model": model}, t, q, qd, tau, "validation", ["x"], plan=plan)
    assert out["starts"] == plan.starts and list(out["models"]["model"]) == [
        f"h{round(h * 1e3)}ms" for h in plan.horizons]
    for h in plan.horizons:
        assert out["models"]["model"][f"h{round(h * 1e3)}ms"]["q_rms"] == pytest.approx(
            0.5 * abs(a_model - a_true) * h**2, rel=1e-9), h
    none = prediction(np.zeros(3), {"model": model}, t, q, qd, tau, "validation", ["x"], plan=Prediction(0))
    assert not none["models"] and none["note"] == "not made: [data] prediction.starts = 0"


def test_folds_are_held_out_with_a_guard_on_both_sides():
    """Each fold's fit reads every row but the fold's own and those within the guard of it, on either
    side; the folds cover the span once, in order."""
    N, K, guard = 1000, 5, 30
    folds = blocked_folds(N, K, guard)
    covered = np.concatenate([np.arange(N)[f] for f in folds.folds])
    assert np.array_equal(covered, np.arange(N))
    for k, fold in enumerate(folds.folds):
        read = np.concatenate([np.arange(N)[p] for i, p in enumerate(folds.pieces) if not folds.left_out[k, i]])
        distance = np.minimum(np.abs(read - fold.start), np.abs(read - (fold.stop - 1)))
        outside = (read < fold.start) | (read >= fold.stop)
        assert outside.all() and distance.min() > guard - 1
        expected = np.flatnonzero((np.arange(N) < fold.start - guard) | (np.arange(N) >= fold.stop + guard))
        assert np.array_equal(np.sort(read), expected)


def test_the_friction_laws_cross_validation_scores_out_of_sample():
    """Torques that are noise, on a regressor that cannot explain them: predicted from the other folds,
    the held-out error exceeds 1 (a prediction adds its own error to the noise); fitted in-sample it
    would be below 1. The guard, where the conditioning reaches, keeps it out of sample all the same."""
    from harness.model.spec import RobotSpec  # noqa: F401  (the law's input is arrays alone)

    rng = np.random.default_rng(3)
    N, n = 2000, 2
    t = np.arange(N) * 0.01
    qd = np.sin(np.outer(t, [0.7, 1.1])) * 0.5
    W = rng.normal(size=(N * n, 14 * n))
    tau = rng.normal(size=(N, n))
    independent = np.arange(14 * n)
    link_part = (np.zeros(14 * n, bool), np.zeros(14 * n))
    model = tuple(JointFriction(coulomb_velocity=0.01) for _ in range(n))
    for reach in (0.0, 0.2):
        choice = choose(W, independent, link_part, tau, qd, t, model, FrictionLawConfig(families=("viscous_coulomb",)),
                        reach)
        assert choice.model_error > 1.0 and choice.chosen_error > 1.0


@pytest.mark.parametrize("direction, limit, at, passed", [
    ("at_most", 0.5, 0.5, True), ("at_most", 0.5, np.nextafter(0.5, 1.0), False),
    ("at_least", 2.0, 2.0, True), ("at_least", 2.0, np.nextafter(2.0, 0.0), False)])
def test_a_gate_at_its_limit_passes_and_one_ulp_beyond_it_fails(direction, limit, at, passed):
    rows, ok = check((Gate("g", "x.y", limit, direction),), {"x": {"y": float(at)}})
    assert ok is passed and rows[0]["passed"] is passed


def test_a_joint_read_for_another_shows_in_the_torque_constants_scaling():
    """scale.scaled multiplies each joint's torque by its own factor whatever order the series keeps its
    joints in (the fixtures' per-joint values all differ: a swap would show)."""
    from harness.identify.scale import scaled

    t = np.arange(5.0)
    series = TimeSeries(t, ("b", "a"), *(np.ones((5, 2)) for _ in range(3)), np.array([[1.0, 10.0]] * 5))
    out = scaled(series, np.array([2.0, 3.0]), ["a", "b"])
    np.testing.assert_array_equal(out.tau[0], [3.0, 20.0])
    assert dataclasses.replace(series, tau=out.tau).joint_data(["a", "b"])[3][0].tolist() == [20.0, 3.0]


def test_a_file_is_read_at_its_size_and_refused_past_its_limit_without_a_buffer_of_the_limit(tmp_path):
    """A log's bytes: a regular file read whole at its size (its memory that size: under 2 x 1 MiB traced
    for a 1 MiB file whose limit is 2 GiB; asking for limit + 1 bytes reserved 2 GiB at every log read),
    refused past the limit before it is read; a stream (/dev/zero) refused after limit + 1 bytes."""
    import tracemalloc
    from pathlib import Path

    from harness.base.tomlio import MAX_DATA_BYTES, InputError, MiB, read_bounded

    log = tmp_path / "log.csv"
    log.write_bytes(b"t,q1\n" + b"0.001,0.5\n" * (MiB // 10))
    tracemalloc.start()
    try:
        content = read_bounded(log, MAX_DATA_BYTES)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert content == log.read_bytes() and peak < 2 * log.stat().st_size
    with pytest.raises(InputError, match="larger than 0 MiB"):
        read_bounded(log, 1000)
    if Path("/dev/zero").exists():
        with pytest.raises(InputError, match="larger than 1 MiB"):
            read_bounded("/dev/zero", MiB)


def test_the_start_check_diagnoses_from_robust_statistics_never_from_one_cell():
    """The model as given against the torques as read (stages/log_judge.start): a log 10 % above the
    model with 1 % noise has no finding; one cell 1e6 times the torques' size (under the reading's absurd
    bound: a plausible-looking spike) leaves the factors within 1e-3 of the clean log's and is counted
    as left out, where the plain least-squares factor read a sign flip off it; a log whose signs are all
    flipped, or that is 50 times smaller, is still found."""
    from harness.stages.log_judge import start

    rng = np.random.default_rng(3)
    t = np.linspace(0.0, 10.0, 5000)
    model = np.stack([20 * np.sin(t), 5 * np.cos(1.3 * t) + 2], axis=1)
    log = 1.1 * model + 0.01 * 20 * rng.standard_normal(model.shape)
    clean = start(model, log, ["a", "b"])
    spiked = log.copy()
    spiked[1234, 0] = -2e7
    plain = float(np.sum(model * spiked) / np.sum(model * model))
    assert plain < 0  # what one cell did to the least-squares factor
    found = start(model, spiked, ["a", "b"])
    assert not clean.findings and not found.findings
    assert found.factor == pytest.approx(clean.factor, rel=1e-3) and found.per_joint["a"]["outliers"] == 1
    assert found.outliers == 1 and clean.outliers == 0
    flipped, small = start(model, -log, ["a", "b"]), start(model, log / 50, ["a", "b"])
    assert flipped.findings[0]["joint"] == "all joints" and "opposite sign" in flipped.findings[0]["likely"]
    assert small.findings[0]["finding"].startswith("factor 0.022") and "far smaller" in small.findings[0]["likely"]
