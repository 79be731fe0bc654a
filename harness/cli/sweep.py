"""`harness sweep` and `harness excite`: a scenario's noisy measurement repeated, and its excitation
optimised into a trajectory to play."""

from __future__ import annotations

import argparse
import json
from contextlib import closing

from harness.base.tomlio import InputError
from harness.cli.common import EXIT_OK, resolve_scenario, workers, write_file_atomically

MAX_TRIALS = 1_000_000  # a sweep holds every trial's estimates in memory


def _sweep_of(scenario):
    """What `harness sweep` runs for the scenario: a study's sweep, else the core's (the joint-torque
    estimators and the identification methods), else None."""
    from harness.base.plugins import Sweep
    from harness.report.sections import identification_sweep_page
    from harness.runner.sweep import identification_summary, identification_sweep, sweepable

    study = next((s for s, _ in scenario.studies if s.sweep is not None), None)
    if study is not None:
        return study.sweep
    return Sweep(identification_sweep, identification_sweep_page, identification_summary) \
        if sweepable(scenario) else None


def cmd_sweep(args: argparse.Namespace) -> int:
    from harness.base.progress import Progress
    from harness.base.workers import WorkersError
    from harness.runner.folder import claim, new_id, place
    from harness.runner.results import with_nulls
    from harness.runner.scenario import load_scenario

    scenario = load_scenario(resolve_scenario(args.scenario))
    sweep = _sweep_of(scenario)
    if sweep is None:
        raise InputError(scenario.source, "studies", "nothing in this scenario can be swept: the graph-theory study's "
                                                     "force path ([studies.graph_theory_2021]), the joint-torque "
                                                     "estimators ([estimators]) or an identification method "
                                                     "([identification]) can")
    if not 2 <= args.trials <= MAX_TRIALS:
        raise InputError(args.scenario, "--trials", f"needs 2 to {MAX_TRIALS:,} trials, got {args.trials}")
    pool = workers(args, args.scenario)
    if scenario.measurement.ideal:
        raise InputError(scenario.source, "measurement", "the scenario measures ideally: there is nothing to sweep")
    out = args.out or args.reports / f"{scenario.name}.sweep"
    claim(out, "sweep", scenario.name, args.replace)
    try:  # the workers cannot be reached or started: the address, or dask not installed
        with pool.opened(), closing(Progress(scenario.name, after=0.0)) as progress:  # a bar ends its line
            results = sweep.run(scenario, args.trials, pool, progress)
    except WorkersError as exc:
        raise InputError(args.scenario, "--dask", str(exc)) from None
    results, not_finite = with_nulls(results)
    results.setdefault("run", {})["not_finite"] = not_finite
    results["run"]["id"] = run = new_id()
    text = sweep.render(results)
    try:
        place(out, {"sweep.json": lambda p: p.write_text(json.dumps(results, indent=1, allow_nan=False) + "\n"),
                    "sweep.html": lambda p: p.write_text(text)}, "sweep", scenario.name, run, args.replace)
    except OSError as exc:
        raise InputError(out, "--out", f"cannot write output ({exc.strerror or exc})") from None
    for line in sweep.summary(results):
        print(line)
    print(f"  report: {out / 'sweep.html'}")
    return EXIT_OK


def cmd_excite(args: argparse.Namespace) -> int:
    from harness.identify.excitation import optimise, trajectory
    from harness.runner.scenario import Scenario, load_scenario
    from harness.stages.shared import with_friction

    scenario = load_scenario(resolve_scenario(args.scenario))
    if not isinstance(scenario, Scenario) or scenario.excitation is None:
        raise InputError(getattr(scenario, "source", args.scenario), "excitation",
                         "the scenario has no [excitation] to optimise")
    optimised, report = optimise(scenario, scenario.excitation, with_friction(scenario))
    t, q, qd, qdd = trajectory(optimised, scenario.excitation)
    cols = {"t": t}
    for k, j in enumerate(scenario.robot.joint_names):
        cols[f"q_{j}"], cols[f"qd_{j}"], cols[f"qdd_{j}"] = q[:, k], qd[:, k], qdd[:, k]
    from harness.base.csvtext import csv_text

    text = csv_text(cols, missing="")
    try:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        write_file_atomically(args.out, text)
    except OSError as exc:
        raise InputError(args.out, "--out", f"cannot write ({exc.strerror or exc})") from None
    used = ", ".join(f"{k} {v:.3f}" for k, v in report["largest_fraction_of_limits"].items())
    print(f"{scenario.name}: wrote {args.out}: {len(t)} rows over {t[-1]:.3f} s at {scenario.excitation.rate:g} Hz, "
          f"at rest at both ends; condition number {report['initial_condition_number']:.3g} -> "
          f"{report['optimised_condition_number']:.3g}; largest fraction of each limit: {used}")
    return EXIT_OK


