"""The core's `harness sweep`: the joint-torque estimators side by side (harness/stages/estimators.py,
`[estimators]`) and every identification method the scenario plugs in (harness/stages/identification.py,
sweep_methods), each over `trials` draws of the scenario's measurement noise (seeds seed, seed + 1, ...)
on `workers`. It returns what sweep.json holds: `estimators` and `identification_methods` as results.json
would hold them for that many trials, and `run` (where and how long). A study's sweep
(harness.base.plugins.Study.sweep) is run the same way; `harness sweep` writes either with every number
that is not finite as null, listed in `run.not_finite`."""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from harness.base.progress import Progress
from harness.base.workers import Workers
from harness.runner.pipeline import from_bench, run
from harness.runner.scenario import Scenario
from harness.stages import Context
from harness.stages.identification import sweep_methods


def sweepable(scenario: Scenario) -> bool:
    """Whether the scenario has anything for the core's sweep: `[estimators]` or an identification method."""
    return "estimators" in scenario.configs or bool(scenario.methods)


def identification_sweep(scenario: Scenario, trials: int, workers: Workers, progress: Progress) -> dict:
    t0 = time.perf_counter()
    results: dict = {"scenario": scenario.name, "trials": trials}
    if "estimators" in scenario.configs:
        config = dataclasses.replace(scenario.configs["estimators"], trials=trials)
        swept = dataclasses.replace(scenario, configs={**scenario.configs, "estimators": config})
        out = run(swept, progress=progress, workers=workers)
        done = out.stages["estimators"]
        results["estimators"] = done.stage.serialise(done.result, out.context, done.config)
    if scenario.methods:
        source = from_bench(scenario, progress)
        ctx = Context(scenario, source.truth, source.truth, progress, source.validation, workers=workers)
        with np.errstate(invalid="ignore", divide="ignore"):  # a parameter the trials never move: 0/0, null
            results["identification_methods"] = sweep_methods(ctx, trials)
    results["run"] = {"workers": workers.describe(), "seconds": round(time.perf_counter() - t0, 3)}
    return results


def identification_summary(results: dict) -> list[str]:
    """A line per estimator and per identification method: the coverage of its intervals and its bias."""
    name_of = results.get("scenario", "")
    lines = []
    e = results.get("estimators")
    for name, m in (e["methods"] if e else {}).items():
        lines.append(f"{name_of}: {name}: coverage of the 95 % intervals {m['coverage_min']:.3f} to "
                     f"{m['coverage_max']:.3f} over the base parameters, {m['coverage_outside_band']} outside "
                     f"{e['coverage_band'][0]:.3f} to {e['coverage_band'][1]:.3f}; largest |bias| "
                     f"{m['max_bias_in_sd']:.2f} sd")
    for name, m in results.get("identification_methods", {}).items():
        if m.get("skipped"):
            lines.append(f"{name_of}: {name}: skipped: {m['skipped']}")
            continue
        b = m["base_parameters"]
        if b is None:
            lines.append(f"{name_of}: {name}: no parameters; validation error {m['validation_rel_error_mean']:.3g} "
                         "on average")
            continue
        coverage = ("no intervals (no covariance)" if b["coverage_min"] is None else
                    f"coverage of the 95 % intervals {b['coverage_min']:.3f} to {b['coverage_max']:.3f}, "
                    f"{b['coverage_outside_band']} outside {b['coverage_band'][0]:.3f} to {b['coverage_band'][1]:.3f}")
        lines.append(f"{name_of}: {name}: largest |bias| {b['max_bias_in_sd']:.2f} sd ({b['significant_biases']} of "
                     f"{b['count']} beyond 3 standard errors); {coverage}")
    return lines
