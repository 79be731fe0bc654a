"""Estimators side by side on the joint-torque path (harness/identify/estimators.py), on the bench where the
truth is known: the recording is measured `trials` times under the scenario's measurement (noise
drawn from seeds seed, seed + 1, ...), every estimator fits every trial, and each is judged per base
parameter by its bias (the mean error, in units of its spread over the trials, and against the
standard error of that mean), its RMS error, the coverage of its 95 % intervals, the torques it
predicts on the validation trajectory, and its time. A scenario asks for it with

    [estimators]
    methods = ["ols", "wls", "irls", "iv"]   # default: all four
    trials = 1000

and needs `[torque_identification] validation = ...` and a `[measurement]` with noise.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from harness.base.numerics import parameter_scale
from harness.base.plugins import Stage
from harness.base.series import TimeSeries
from harness.engines.pinocchio import PinocchioModel, build_model
from harness.identify.estimators import DESCRIPTIONS, ESTIMATORS, Instruments, iv
from harness.identify.propagation import propagates, score_covariance
from harness.identify.torque_id import parameter_names, regressor, true_parameters
from harness.identify.trials import over_trials
from harness.sources.measurement import Measurement, measure, savgol
from harness.stages.metrics import joint_load_scale
from harness.stages.shared import families_refused, structural_base_of, torque_config


@dataclass(frozen=True, eq=False)
class Comparison:
    methods: tuple[str, ...]
    beta_true: np.ndarray  # (r,)
    beta: np.ndarray  # (methods, trials, r)
    std: np.ndarray  # (methods, trials, r)
    half: np.ndarray  # (methods, trials, r)
    seconds: np.ndarray  # (methods, trials)
    validation_rel_error: np.ndarray  # (methods, trials): largest |predicted - recorded| / L_J
    samples: int
    edge: int  # samples dropped at each end (the differentiating filter's end effects)
    lags: int  # samples over which the noise stays correlated (harness/identify/estimators.py)
    block: int  # samples per cluster of the least-squares family's standard deviations
    interval: str  # where the IV intervals come from: "sensors" or "residuals"
    iv_half_from_residuals: np.ndarray | None  # (trials, r) beside the sensors' intervals

    def serialise(self, ctx, config) -> dict:
        """results.json's `estimators`: each estimator's bias, spread and coverage over the trials."""
        T = self.beta.shape[1]
        err = self.beta - self.beta_true  # (methods, trials, r)
        stats = over_trials(err, self.half, parameter_scale(self.beta_true))
        bias_in_sd, significant, covered, rms = stats.bias_in_sd, stats.significant, stats.coverage, stats.rms_rel_error
        binomial = stats.binomial
        out = {
            "definition": ("per base parameter over the trials: bias = mean error, bias_in_sd = |bias| / the "
                           "error's standard deviation over the trials, significant where |bias| > 3 standard errors "
                           "of the mean; coverage of the 95 % intervals; rms_rel_error = RMS error / max(|true|, "
                           "1e-6 x largest); validation: largest |predicted - recorded torque| / L_J on the "
                           "validation trajectory"),
            "trials": T, "samples_per_trial": self.samples, "filter_edge_samples_dropped": self.edge,
            "noise_correlated_over_samples": self.lags, "least_squares_samples_per_cluster": self.block,
            "coverage_binomial_standard_error": float(binomial),
            # a calibrated 95 % interval's coverage over T trials falls within 3 binomial standard errors
            # of 0.95 but for 0.27 % of the parameters
            "coverage_band": [float(0.95 - 3 * binomial), float(0.95 + 3 * binomial)],
            "iv_intervals_from": self.interval,
            "methods": {},
        }
        lo, hi = out["coverage_band"]
        for i, name in enumerate(self.methods):
            out["methods"][name] = {
                "description": DESCRIPTIONS[name],
                "max_bias_in_sd": float(np.max(bias_in_sd[i])),
                "median_bias_in_sd": float(np.median(bias_in_sd[i])),
                "significant_biases": int(significant[i].sum()),
                "coverage_min": float(covered[i].min()), "coverage_median": float(np.median(covered[i])),
                "coverage_max": float(covered[i].max()),
                "coverage_outside_band": int(np.sum((covered[i] < lo) | (covered[i] > hi))),
                "median_rms_rel_error": float(np.median(rms[i])), "max_rms_rel_error": float(np.max(rms[i])),
                "validation_rel_error_mean": float(np.mean(self.validation_rel_error[i])),
                "seconds_per_fit": float(np.mean(self.seconds[i])),
                "per_parameter": {"bias_in_sd": [float(x) for x in bias_in_sd[i]],
                                  "coverage": [float(x) for x in covered[i]],
                                  "rms_rel_error": [float(x) for x in rms[i]]},
            }
        if self.iv_half_from_residuals is not None:
            i = self.methods.index("iv")
            cov = (np.abs(err[i]) <= self.iv_half_from_residuals).mean(axis=0)
            out["methods"]["iv"]["coverage_from_residuals"] = {
                "min": float(cov.min()), "median": float(np.median(cov)), "max": float(cov.max()),
                "outside_band": int(np.sum((cov < lo) | (cov > hi))), "per_parameter": [float(x) for x in cov]}
        return out


MAX_TRIALS = 100_000  # estimator trials of one run, each a measurement and a regressor (hours beyond)


@dataclass(frozen=True)
class EstimatorsConfig:
    """`[estimators]`: which estimators (harness/identify/estimators.py) and over how many trials."""

    methods: tuple[str, ...]
    trials: int = 200


def configure(t, scenario) -> EstimatorsConfig:
    """`[estimators] methods = ["ols", "wls", "irls", "iv"], trials = 200`, validated (one-line
    errors naming the key). The estimators are judged on the scenario's validation trajectory."""
    if torque_config(scenario) is None:
        raise t.error("methods", "estimators are judged on a validation trajectory: give "
                                 "[torque_identification] validation = ...")
    if torque_config(scenario).friction and (why := families_refused(scenario.robot, "the estimators fit")):
        raise t.error("methods", why)
    config = EstimatorsConfig(tuple(t.strings("methods", choices=tuple(ESTIMATORS), default=list(ESTIMATORS))),
                              t.integer("trials", default=200, minimum=2))
    if config.trials > MAX_TRIALS:
        raise t.error("trials", f"{config.trials} trials: at most {MAX_TRIALS:,}")
    return config


def run(ctx, config: EstimatorsConfig | None) -> Comparison | None:
    sc = ctx.scenario
    cfg = config
    if cfg is None:
        return None
    torque = torque_config(sc)
    friction = torque.friction
    joints = sc.robot.joint_names
    pm = build_model(sc.robot, sc.gravity_W)
    base = structural_base_of(ctx)
    cols = base.independent
    rec = ctx.truth
    m = sc.measurement
    edge = m.filter_window // 2 if m.differentiate else 0
    # two outputs of the differentiating filter share no encoder reading beyond a window apart
    lags = m.filter_window - 1 if m.differentiate else 0
    block = 3 * (lags + 1) if lags else 1  # the least-squares family's clusters (harness/identify/estimators.py)
    rows = np.arange(0, len(rec.t), m.every)
    usable = (len(rows) - 2 * edge) // block * block  # whole clusters only
    keep = slice(edge, edge + usable)
    idx = [rec.joint_index(j) for j in joints]
    # the instruments: the regressor of the motion the robot was asked to follow, its velocities
    # and accelerations differentiated by the same filter as the measured ones (else the filter's
    # own distortion of the signal, the same in every trial, would bias the estimate)
    q_ref, qd_ref, qdd_ref = (x[rows][:, idx] for x in (rec.drive.q_ref, rec.drive.qd_ref,
                                                                       rec.drive.qdd_ref))
    if m.differentiate:
        qd_ref, qdd_ref = (savgol(q_ref, rec.t[rows], m.filter_window, k) for k in (1, 2))
    Z1 = regressor(pm, q_ref[keep], qd_ref[keep], qdd_ref[keep], with_friction=friction)[:, cols]
    # the Coulomb shapes s(q') are the columns nonlinear in a measured signal (harness/identify/estimators.py)
    names = parameter_names(joints, friction)
    nonlinear = np.array([names[c].endswith(".coulomb") for c in cols])
    from_residuals = Instruments(Z1, nonlinear)
    sensors = propagates(m)  # the IV intervals from the sensors' specification, where it is complete
    instruments = Instruments(Z1, nonlinear, score_covariance(pm, Z1, rec.t[rows], keep, q_ref, qd_ref, qdd_ref,
                                                              rec.tau[rows][:, idx], m)) if sensors else from_residuals
    val = ctx.recorded(torque.validation)
    qv, qdv, qddv, tauv = val.joint_data(joints)
    Wv = regressor(pm, qv, qdv, qddv, with_friction=friction)[:, cols]
    load = joint_load_scale(sc.robot, val)
    methods = list(cfg.methods)
    T = cfg.trials
    both = "iv" in methods and sensors
    bench = _Bench(pm, rec, m, tuple(joints), cols, friction, keep=keep, methods=tuple(methods),
                   instruments=instruments, from_residuals=from_residuals if both else None,
                   lags=lags, Wv=Wv, tauv=tauv, load=load)
    ctx.progress("estimators side by side", 0.0)
    trials = ctx.workers.map(_setup, (bench,), _trial, range(T),
                             lambda done, total: ctx.progress("estimators side by side", done / total))
    beta, std, half, seconds, val_err = (np.stack([t[i] for t in trials], axis=1) for i in range(5))
    half_residuals = np.stack([t[5] for t in trials]) if both else None
    return Comparison(tuple(methods), base.of(true_parameters(pm, friction)), beta, std, half, seconds,
                      val_err, usable, edge, lags, block, "sensors" if sensors else "residuals", half_residuals)


@dataclass(frozen=True, eq=False)
class _Bench:
    """What every trial shares: the recording (the truth), its measurement, the instruments and the
    validation trajectory. Sent once to each worker."""

    pm: PinocchioModel
    rec: TimeSeries  # the ideal recording
    m: Measurement  # the scenario's
    joints: tuple[str, ...]
    cols: np.ndarray  # the base parameters' columns of the regressor
    friction: bool
    keep: slice  # the rows the differentiating filter leaves whole
    methods: tuple[str, ...]
    instruments: Instruments
    from_residuals: Instruments | None  # IV again with intervals from the residuals, for comparison
    lags: int
    Wv: np.ndarray  # the validation trajectory's regressor, base columns
    tauv: np.ndarray
    load: np.ndarray


def _setup(bench: _Bench) -> _Bench:
    return bench


def _trial(b: _Bench, k: int) -> tuple:
    """Trial k: the measurement drawn from seed + k, every method's fit of it."""
    n = len(b.joints)
    meas = measure(b.rec, b.m.with_seed(b.m.seed + k))
    q, qd, qdd, tau = (x[b.keep] for x in meas.joint_data(b.joints))
    W1 = regressor(b.pm, q, qd, qdd, with_friction=b.friction)[:, b.cols]
    r = len(b.cols)
    beta, std, half = (np.empty((len(b.methods), r)) for _ in range(3))
    seconds, val_err = np.empty(len(b.methods)), np.empty(len(b.methods))
    for i, name in enumerate(b.methods):
        est = ESTIMATORS[name](W1, tau.reshape(-1), n, b.instruments, b.lags)
        beta[i], std[i], half[i], seconds[i] = est.beta, est.std, est.ci_half_width, est.seconds
        val_err[i] = np.max(np.abs((b.Wv @ est.beta).reshape(b.tauv.shape) - b.tauv) / b.load)
    # what the data alone would have said of the same estimate
    half_residuals = (iv(W1, tau.reshape(-1), n, b.from_residuals, b.lags).ci_half_width
                      if b.from_residuals is not None else None)
    return beta, std, half, seconds, val_err, half_residuals


STAGE = Stage("estimators", "estimators side by side (Monte Carlo over the measurement noise)", run,
              Comparison.serialise, "Estimators side by side", table="estimators", configure=configure,
              recordings=lambda c, sc: (torque_config(sc).validation,) if c is not None else ())
