"""Least squares over a long log, block by block (harness/identify/streaming.py), against the dense fit."""

from __future__ import annotations

import numpy as np
import pytest

from harness.engines.pinocchio import build_model, rnea
from harness.identify.estimators import ols
from harness.identify.streaming import fit_long
from harness.identify.torque_id import regressor, structural_base, true_parameters
from harness.model.load import load_spec
from tests.conftest import MODELS


def _motion(n: int, samples: int, rate: float = 1000.0):
    """Three sines a joint, 0.1 to 0.5 Hz: q, q', q'' (samples, n) in closed form."""
    rng = np.random.default_rng(0)
    t = np.arange(samples) / rate
    w, amp, phase = rng.uniform(0.6, 3.0, (3, n)), rng.uniform(0.2, 0.8, (3, n)), rng.uniform(0, 6, (3, n))
    arg = w[:, None, :] * t[None, :, None] + phase[:, None, :]
    return ((amp[:, None] * np.sin(arg)).sum(0), (amp[:, None] * w[:, None] * np.cos(arg)).sum(0),
            -(amp[:, None] * w[:, None] ** 2 * np.sin(arg)).sum(0))


@pytest.mark.slow  # a few seconds: a whole pipeline or a subprocess
def test_block_by_block_equals_the_dense_fit_and_the_truth():
    """The Panda with its drives, 8,000 samples at 1 kHz in blocks of 3,000 (the last one short).
    Each base parameter's error is measured by the torque it moves, |d beta_k| ||W_k|| / ||tau||:
    normal equations square the condition number of the column-scaled regressor (18.5 here), so
    they keep round-off times 18.5^2, about 1e-13; held to 1e-12 against the truth and against the
    dense QR fit (measured 1e-14; the dense fit's own error 7e-16). With 2 % torque noise the
    classical standard deviations are within 10 % of the dense fit's (cluster-robust) for the
    median parameter."""
    spec = load_spec(MODELS / "panda_arm.toml")
    pm = build_model(spec, np.array([0.0, 0.0, -9.81]))
    base = structural_base(pm, spec.limits, with_friction=True)
    q, qd, qdd = _motion(len(spec.joint_names), 8_000)
    tau = rnea(pm, q, qd, qdd).tau
    truth = base.of(true_parameters(pm, True))
    W1 = regressor(pm, q, qd, qdd, True)[:, base.independent]
    weight = np.linalg.norm(W1, axis=0) / np.linalg.norm(tau)
    fit = fit_long(pm, base, q, qd, qdd, tau, True, chunk=3000)
    assert fit.samples == 8_000
    assert np.max(np.abs(fit.beta - truth) * weight) < 1e-12
    dense = ols(W1, tau.reshape(-1), tau.shape[1])
    assert np.max(np.abs(fit.beta - dense.beta) * weight) < 1e-12
    noisy = tau + 0.02 * np.abs(tau).mean(axis=0) * np.random.default_rng(1).standard_normal(tau.shape)
    fit, dense = fit_long(pm, base, q, qd, qdd, noisy, True, chunk=3000), ols(W1, noisy.reshape(-1), tau.shape[1])
    assert abs(np.median(fit.std / dense.std) - 1) < 0.1
