"""`harness run`: each scenario through the pipeline, its folder written whole or not at all and never
beside another run's files (harness/runner/folder.py), one line per gate."""

from __future__ import annotations

import argparse
import gc
import sys
import time
from contextlib import closing
from pathlib import Path

from harness.base.tomlio import InputError
from harness.cli.common import (
    DEFAULT_SCENARIO,
    EXIT_GATE_FAILED,
    EXIT_OK,
    REPORT_FILE,
    print_gates,
    resolve_scenario,
    workers,
    write_ci,
)
from harness.runner.gates import summary_line
from harness.runner.results import said_first
from harness.sources.base_motion import model_notes

BORN: float | None = None  # time.perf_counter() when the `harness` command started (its package imported), by `entry`
ENDS_WITH_COMMAND = False  # True in the child `entry` forks: the process ends when the command does


def since_start() -> float:
    """Seconds since the `harness` command started: since its package was imported, which `entry` notes
    (the child it forks keeps the same clock), not since its process started (a process that waited
    before starting the harness, a wrapper's, is not the harness's time); 0 where the command is
    called from Python (`main`), whose imports are timed on their own."""
    return max(time.perf_counter() - BORN, 0.0) if BORN is not None else 0.0


def cmd_run(args: argparse.Namespace) -> int:
    start = time.perf_counter()
    started = since_start()  # the harness's imports before `start`
    # in the child `entry` forks, the modules' objects live as long as the process: the cyclic garbage
    # collector is kept from walking them while they are made, and from then on (gc.freeze: 20 ms of
    # a kr500_rail run); a process that goes on after the command (main() called from Python) keeps
    # its collector as it was
    freeze = ENDS_WITH_COMMAND and gc.isenabled()
    if freeze:
        gc.disable()
    import mujoco  # noqa: F401  every run needs both engines: their import is timed here, not in a stage
    import pinocchio  # noqa: F401

    import harness.api  # the pipeline and the report: their import is timed here too
    import harness.report  # noqa: F401
    from harness.base.workers import WorkersError
    from harness.runner.scenario import load_scenario

    if freeze:
        gc.freeze()
        gc.enable()
    imported = started + time.perf_counter() - start  # Python, mujoco, pinocchio, numpy, scipy, the harness
    names = args.scenarios or [DEFAULT_SCENARIO]
    pool = workers(args, " ".join(names))
    scenarios, reading = [], []  # all validated before any work
    for a in names:
        t0 = time.perf_counter()
        scenarios.append(load_scenario(resolve_scenario(a)))
        reading.append(time.perf_counter() - t0)
    seen = set()
    for s in scenarios:
        if s.name in seen:
            raise InputError(s.source, "", f"scenario {s.name!r} is named twice")
        seen.add(s.name)
    _claim_folders(args, scenarios)
    for s in scenarios:
        for note in model_notes(s):  # what reading the model assumed
            print(f"harness: warning: {s.name}: {note}", file=sys.stderr)
        for entry in s.methods:
            if entry.skipped is not None:
                print(f"harness: warning: {s.name}: identification method {entry.name} skipped: {entry.skipped}",
                      file=sys.stderr)
    try:  # the workers cannot be reached or started: the address, or dask not installed
        with pool.opened():  # started once for every scenario
            passed, verdicts = _run_each(args, scenarios, reading, pool, imported)
    except WorkersError as exc:
        raise InputError(" ".join(names), "--dask", str(exc)) from None
    write_ci(args, verdicts)
    return EXIT_OK if passed else EXIT_GATE_FAILED


def _out(args: argparse.Namespace, name: str, several: bool) -> Path:
    """A scenario's output folder: --out itself for one scenario, a folder of its name in --out for
    several, reports/NAME by default."""
    if args.out is None:
        return args.reports / name
    return args.out / name if several else args.out


def _claim_folders(args: argparse.Namespace, scenarios: list) -> None:
    """Before any work: every scenario's output folder is one it may write (harness/runner/folder.py);
    with several, --out is no run's folder (their folders go inside it)."""
    from harness.runner.folder import claim, held

    several = len(scenarios) > 1
    if several and args.out is not None:
        there = held(args.out, "--out")
        if there is not None and there.kind:
            raise InputError(args.out, "--out", f"holds a {there.kind} of {there.name!r}: with several scenarios, "
                                                "--out is the folder that gets one folder per scenario")
    for s in scenarios:
        claim(_out(args, s.name, several), "run", s.name, args.replace)


def _run_each(args: argparse.Namespace, scenarios: list, reading: list[float], workers,
              imported: float) -> tuple[bool, list]:
    from harness.api import run
    from harness.base.progress import Progress
    from harness.report import render
    from harness.runner.folder import place
    from harness.runner.results import RECORDING_FILE, RESULTS_FILE, write_results

    passed, verdicts = True, []
    for scenario, read in zip(scenarios, reading, strict=True):
        out = _out(args, scenario.name, len(scenarios) > 1)
        progress = Progress(scenario.name, args.quiet)
        with closing(progress):  # a bar in progress ends its line before anything else is printed
            result = run(scenario, progress, workers)
        progress("writing the report", None)
        results = result.results
        failed = [f"identification method {name} failed: {m['failed']}"
                  for name, m in results.get("identification_methods", {}).items()
                  if isinstance(m, dict) and isinstance(m.get("failed"), str)]
        for warning in said_first(results) + failed:  # the start check's findings first
            print(f"harness: warning: {scenario.name}: {warning}", file=sys.stderr)  # once per run, not per row
        results["run"]["timings"] = {"starting the harness and importing the engines and libraries": imported,
                                     "reading the scenario, its model and plugins": read,
                                     **results["run"]["timings"]}
        imported = 0.0
        page = render(results, result.recording, [s.stage for s in result.output.stages.values()])
        try:
            data_file = results["data"]["file"] if "data" in results else RECORDING_FILE
            place(out, {
                data_file: result.recording.write_csv,
                RESULTS_FILE: lambda p, r=results: write_results(p, r),
                REPORT_FILE: lambda p, text=page: p.write_text(text),
                **{name: (lambda p, text=text: p.write_text(text)) for name, text in result.output.files.items()},
            }, "run", scenario.name, results["run"]["id"], args.replace)
        except OSError as exc:
            raise InputError(out, "--out", f"cannot write output ({exc.strerror or exc})") from None
        _print_summary(results, out)
        passed &= results["passed"]
        verdicts.append((scenario.name, results["gates"]))
    return passed, verdicts


def _print_summary(results: dict, out: Path) -> None:
    print(summary_line(results["scenario"]["name"], results["gates"]))
    print_gates(results["gates"])
    print(f"  report: {out / REPORT_FILE}")


