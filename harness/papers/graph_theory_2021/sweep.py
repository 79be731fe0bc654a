"""Monte Carlo over measurement noise: the simulation runs once, the measurement is drawn N times.

Trial k uses seed (scenario seed + k), so a sweep is the same wherever its trials run (this
process, forked processes, a Dask cluster: harness/base/workers.py).
For every parameter: the distribution of its error over the trials in which it was identifiable,
and the coverage of its 95 % intervals (the fraction of trials whose interval contains the true
value), which is what makes the stated uncertainty honest or not. The same is repeated, with
fewer trials, at scaled noise levels, for the error against noise level.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from harness.base.workers import IN_PROCESS, Workers
from harness.papers.graph_theory_2021.dynamics import build_graph_model
from harness.papers.graph_theory_2021.identification import PARAMETERS
from harness.papers.graph_theory_2021.readings import exact, read
from harness.papers.graph_theory_2021.solve import identify, measured_rows, parameter_scale
from harness.runner.scenario import Scenario
from harness.sources.bench import record
from harness.sources.measurement import Measurement, measure

LEVELS = (0.25, 0.5, 1.0, 2.0, 4.0)


def config_of(scenario: Scenario):
    """This study's configuration (study.Config) in a scenario that asks for it."""
    return next(c for s, c in scenario.studies if s.name == "graph_theory_2021")


def _setup(scenario: Scenario, recording) -> dict:
    """Once per worker: the models the trials share."""
    arms = scenario.robot.inner_joint_arms_B()
    return dict(scenario=scenario, recording=recording, arms=arms, readings=exact(recording, arms),
                model=build_graph_model(config_of(scenario).tested, scenario.gravity_W),
                truth=build_graph_model(scenario.robot, scenario.gravity_W))


def _trial(state: dict, task: tuple[int, float]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    seed, level = task
    sc = state["scenario"]
    m: Measurement = sc.measurement.scaled(level).with_seed(seed)
    measured = read(state["readings"], measure(state["recording"], m), m, state["arms"])
    ident = identify(state["model"], measured, measured_rows(measured, sc.sample_times), m, state["truth"],
                     with_system=False)
    x = np.stack([ls.beta for ls in ident.per_body])
    half = np.stack([ls.ci_half_width for ls in ident.per_body])
    std = np.stack([ls.std for ls in ident.per_body])
    return x, std, half


def run_sweep(scenario: Scenario, trials: int, workers: Workers = IN_PROCESS,
              progress: Callable[[int, int], None] | None = None, levels: tuple[float, ...] = LEVELS) -> dict:
    """`trials` measurements at the scenario's noise, and max(trials // 10, 20) at each other level
    of `levels`, identified on `workers` (harness/base/workers.py). sweep.json's "run" says where and
    how long; everything else is the same wherever the trials ran."""
    t0 = time.perf_counter()
    recording = record(scenario)
    truth = build_graph_model(scenario.robot, scenario.gravity_W)
    true = np.column_stack([truth.m, truth.m, truth.m, truth.J])
    base = scenario.measurement.seed
    level_trials = max(trials // 10, 20)
    tasks = [(base + k, 1.0) for k in range(trials)]
    tasks += [(base + trials + k, f) for f in levels if f != 1.0 for k in range(level_trials)]
    results = workers.map(_setup, (scenario, recording), _trial, tasks, progress)
    x, std, half = (np.array([r[i] for r in results]) for i in range(3))  # (tasks, n, 6)
    task_levels = np.array([t[1] for t in tasks])
    main = task_levels == 1.0
    scale = parameter_scale(true)
    rows = []
    bodies = truth.topology.bodies
    for i, body in enumerate(bodies):
        for c, name in enumerate(PARAMETERS):
            xi, hi = x[main, i, c], half[main, i, c]
            ok = np.isfinite(xi)
            err = xi[ok] - true[i, c]
            covered = np.abs(err) <= hi[ok]
            rows.append({
                "body": body, "name": name, "true": float(true[i, c]),
                "identifiable_fraction": float(ok.mean()),
                "trials": int(ok.sum()),
                "error_mean": float(err.mean()) if ok.any() else None,
                "error_std": float(err.std(ddof=1)) if ok.sum() > 1 else None,
                "rel_error_rms": float(np.sqrt(np.mean((err / scale[i, c]) ** 2))) if ok.any() else None,
                "stated_std_mean": float(np.mean(std[main, i, c][ok])) if ok.any() else None,
                "coverage_ci95": float(covered.mean()) if ok.any() else None,
                "errors": (err / scale[i, c]).tolist(),
            })
    by_level = []
    for f in sorted(set(levels) | {1.0}):
        sel = task_levels == f
        rel = np.abs(x[sel] - true) / scale
        by_level.append({"level": f, "trials": int(sel.sum()),
                         "median_rel_error": {f"{b}.{p}": float(np.nanmedian(rel[:, i, c]))
                                              if np.isfinite(rel[:, i, c]).any() else None
                                              for i, b in enumerate(bodies) for c, p in enumerate(PARAMETERS)}})
    covered = [r["coverage_ci95"] for r in rows if r["identifiable_fraction"] == 1.0]
    return {
        "schema": {"name": "harness-sweep", "version": 1},
        "scenario": scenario.name, "measurement": scenario.measurement.describe(),
        "trials": trials, "seeds": [base, base + trials - 1],
        "coverage_min": min(covered) if covered else None,
        "coverage_max": max(covered) if covered else None,
        "parameters": rows, "levels": by_level,
        "run": {"workers": workers.describe(), "seconds": round(time.perf_counter() - t0, 3)},
    }
