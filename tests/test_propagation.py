"""The sensors' specification propagated to the IV estimate's covariance (harness/identify/propagation.py),
each piece against an independent computation: the encoder's covariance against quantising with
random zeros, Pinocchio's RNEA derivatives against finite differences of RNEA, and the whole
against the spread of the estimates over repeated measurements on the bench."""

from __future__ import annotations

import numpy as np
import pytest

from harness.api import run
from harness.engines.pinocchio import build_model, rnea
from harness.identify.propagation import encoder_covariance, torque_sensitivities
from harness.model.load import load_spec
from harness.sources.measurement import read_encoders
from tests.conftest import MODELS, SCENARIOS


def test_encoder_covariance_is_that_of_counts_with_a_random_zero():
    """A slow then fast path of 40 positions quantised with 20,000 random zeros: the sample
    covariance matches the formula within 4 of its standard errors (about res^2 / 12 / sqrt(T))."""
    rng = np.random.default_rng(0)
    res = 1e-3
    q = np.concatenate([np.linspace(0.0, 0.2 * res, 20), np.linspace(3e-3, 0.05, 20)])
    T = 20_000
    err = np.array([read_encoders(q[:, None], res, rng)[:, 0] - q for _ in range(T)])
    sample = err.T @ err / T  # the error's mean is zero by construction: no mean removed
    expected = encoder_covariance(q, res)
    assert np.max(np.abs(sample - expected)) < 4 * res**2 / 12 / np.sqrt(T) * np.sqrt(2)
    assert np.allclose(np.diag(expected), res**2 / 12)  # a uniform error within one count
    assert expected[0, 1] > 0.9 * res**2 / 12  # readings a fraction of a count apart share their error


def test_torque_sensitivities_are_the_derivatives_of_the_model_torque():
    """Central differences of the RNEA with the drives' viscous friction and rotor inertia (step
    1e-6: truncation ~1e-12 of the derivative, round-off ~1e-10 of the torque / 1e-6)."""
    spec = load_spec(MODELS / "ur5_friction.toml")
    pm = build_model(spec, np.array([0.0, 0.0, -9.80665]))
    # the Coulomb shape is left out on purpose: compare with a model whose Coulomb term is off
    rng = np.random.default_rng(1)
    q, qd, qdd = (rng.uniform(-1.5, 1.5, (5, 6)) for _ in range(3))
    Dq, Dv, Da = torque_sensitivities(pm, q, qd, qdd)
    coulomb = pm.frictions and np.array([f.coulomb for f in pm.frictions])

    def tau(q, qd, qdd):
        t = rnea(pm, q, qd, qdd).tau
        from harness.model.friction import coulomb_shape
        v = np.array([f.coulomb_velocity for f in pm.frictions])
        return t - coulomb * coulomb_shape(qd, v)

    h = 1e-6
    for D, which in ((Dq, 0), (Dv, 1), (Da, 2)):
        for j in range(6):
            step = np.zeros((5, 6))
            step[:, j] = h
            args_p, args_m = [q, qd, qdd], [q, qd, qdd]
            args_p[which], args_m[which] = args_p[which] + step, args_m[which] - step
            fd = (tau(*args_p) - tau(*args_m)) / (2 * h)
            assert np.allclose(D[:, :, j], fd, rtol=1e-6, atol=1e-6 * np.abs(fd).max()), (which, j)


@pytest.mark.slow  # about a minute
def test_intervals_from_the_sensors_cover_as_95_percent_intervals_over_1000_trials(tmp_path):
    """ur5_estimators' sensors (13-bit encoders with random zeros, 2 % + 0.05 N m torque noise,
    differentiated by the Savitzky-Golay filter) and motion, 1000 trials of the IV estimator. For
    every base parameter: the propagated standard deviation within 10 % of the estimates' spread
    over the trials (a spread from 1000 trials is known within 2.2 %); its 95 % interval covers
    within 4 binomial standard errors of 95 % (0.922 to 0.978; the issue asks 0.93 to 0.97, met on
    this seed: README); the bias under 0.2 standard deviations (the issue asks under 1; a mean of
    1000 trials is known within 0.032 of them)."""
    source = (SCENARIOS / "ur5_estimators.toml").read_text()
    source = (source.replace('"../models/', f'"{MODELS}/').replace('"ur5_friction_validation.toml"',
                                                                     f'"{SCENARIOS / "ur5_friction_validation.toml"}"')
              .replace('methods = ["ols", "wls", "irls", "iv"]', 'methods = ["iv"]')
              .replace("trials = 100", "trials = 1000"))
    source = source[:source.index("[[gates]]")] + (
        '[[gates]]\nmetric = "torques.pinocchio_vs_mujoco.max_rel_error"\nlimit = 1e-9\n')
    (tmp_path / "s.toml").write_text(source)
    c = run(tmp_path / "s.toml").output.stages["estimators"].result
    assert c.interval == "sensors"
    err = c.beta[0] - c.beta_true
    spread = err.std(axis=0, ddof=1)
    ratio = np.median(c.std[0], axis=0) / spread
    assert np.all(np.abs(ratio - 1) < 0.1), ratio
    covered = (np.abs(err) <= c.half[0]).mean(axis=0)
    assert np.all(np.abs(covered - 0.95) < 4 * np.sqrt(0.95 * 0.05 / 1000)), covered
    assert np.all(np.abs(err.mean(axis=0)) < 0.2 * spread)
