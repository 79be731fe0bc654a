"""The `harness` command. It only wires the data flow: scenario -> recording -> results -> report."""

from __future__ import annotations

import argparse
import gc
import json
import os
import shutil
import signal
import sys
import tempfile
import time
import traceback
from collections.abc import Callable
from contextlib import closing
from pathlib import Path

from harness.base.tomlio import InputError, read_toml
from harness.runner.ci import error_summary, error_xml, gate_line, result_word
from harness.runner.gates import summary_line

EXIT_OK, EXIT_GATE_FAILED, EXIT_BAD_INPUT, EXIT_INTERNAL = 0, 1, 2, 3
DEFAULT_SCENARIO = "kr500_rail"
MAX_TRIALS = 1_000_000  # a sweep holds every trial's estimates in memory


def max_jobs() -> int:
    return 4 * (os.cpu_count() or 1)


class _Parser(argparse.ArgumentParser):
    """Usage errors in one line, exit status 2, like every other bad input."""

    def error(self, message: str):
        self.exit(2, f"harness: error: {message} (see harness --help)\n")
REPORT_FILE = "report.html"

DESCRIPTION = """\
Validate robot dynamic models and identification methods against reference engines. MuJoCo
simulates the robot along a scenario's motion and records joint torques, forces and
accelerations; Pinocchio's RNEA is the second opinion. Every model under test (a plugin: Python
code, or a parameter file through a model plugin) is compared with both, along the motion and at
random states; every identification method is judged on the same measured data; each study the
scenario asks for (the seed papers' are two) adds its stages. Each scenario declares accuracy
gates, and every plugin must be judged by one. Start a project of your own with `harness init DIR`.

exit status, chosen by the harness alone whatever a plugin does: 0 every gate passed, 1 a gate
failed, 2 bad input (a one-line message names the file and the key, or the plugin: one that cannot
be imported, breaks its protocol or raises anything, SystemExit included), 3 an internal error (one
line; --debug adds the traceback), 130 interrupted. --junit-xml and --summary are written in every
case."""


def _worker_options(parser: argparse.ArgumentParser, what: str) -> None:
    parser.add_argument("--jobs", type=int, default=1, metavar="K",
                        help=f"run {what} in K forked worker processes (default 1: this process)")
    parser.add_argument("--dask", nargs="?", const="local", default=None, metavar="ADDRESS",
                        help=f"run {what} on Dask, its workers started once for the whole command: a local cluster "
                             "(one worker per core) when no address is given, otherwise the scheduler at ADDRESS "
                             "(e.g. tcp://10.0.0.5:8786), whose workers have harness installed")


def _workers(args: argparse.Namespace, source):
    """The workers --jobs and --dask ask for (harness/base/workers.py); bad values name `source`."""
    from harness.base.workers import Workers

    if not 1 <= args.jobs <= max_jobs():
        raise InputError(source, "--jobs", f"needs 1 to {max_jobs()} processes (4 per core), got {args.jobs}")
    if args.dask is not None and args.jobs != 1:
        raise InputError(source, "--dask", f"the trials run either on Dask or on --jobs {args.jobs} processes, "
                                           "not both")
    if args.dask is not None and not args.dask.strip():
        raise InputError(source, "--dask", "needs a scheduler address (or none, for a local cluster)")
    return Workers(args.jobs, args.dask)


def _resolve_scenario(arg: str) -> Path:
    """A path to a scenario file, or a bare name: ./scenarios/NAME.toml, ./NAME.toml, then the
    built-in scenario of that name (harness/base/builtin.py)."""
    from harness.base.builtin import resolve

    return resolve(arg, "scenarios")


def _parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="harness", description=DESCRIPTION, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--debug", action="store_true", help="on an internal error, show the traceback")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND", parser_class=_Parser)
    run = sub.add_parser(
        "run", help="run scenarios through the whole pipeline and write their reports",
        description="Run each scenario through the whole pipeline: simulate it in MuJoCo, compare every model under "
                    "test with MuJoCo and Pinocchio, judge every identification method, run the stages of each "
                    "study the scenario asks for, check the scenario's gates. Writes recording.csv, results.json "
                    "and report.html into one folder per scenario and prints one line per gate. A model under "
                    "test is a plugin: [model_under_test] name = \"mine\", python = \"my_arm:make\" (see README, "
                    f"'Plugging in'). With no scenario, runs {DEFAULT_SCENARIO}.")
    run.add_argument("scenarios", metavar="SCENARIO", nargs="*",
                     help="scenario file, or the name of one in ./scenarios/ (e.g. kr500_rail)")
    run.add_argument("--out", metavar="DIR", type=Path, default=None,
                     help="output folder: with one scenario, its folder; with several, the folder that gets "
                          "one subfolder per scenario (default: reports/<scenario name>)")
    run.add_argument("--quiet", action="store_true", help="no progress messages")
    _worker_options(run, "the estimators' Monte Carlo trials ([estimators])")
    _ci_options(run)
    report = sub.add_parser("report", help="re-render report.html from a results.json",
                            description="Re-render the HTML report from a results.json and the recording.csv "
                                        "beside it, without simulating again.")
    report.add_argument("results", metavar="RESULTS.json", type=Path)
    report.add_argument("--out", metavar="FILE", type=Path, default=None,
                        help="where to write the report (default: report.html beside RESULTS.json)")
    gate = sub.add_parser("gate", help="re-check the gates of one or more results.json",
                          description="Check gates against existing results without simulating again. The gates "
                                      "are the ones stored in each results.json, or those of --scenario FILE (for "
                                      "example after changing a limit). Exit status 1 if any gate fails.")
    gate.add_argument("results", metavar="RESULTS.json", type=Path, nargs="+")
    gate.add_argument("--scenario", metavar="FILE", type=Path, default=None,
                      help="take the gates from this scenario file instead")
    _ci_options(gate)
    sweep = sub.add_parser(
        "sweep", help="repeat a scenario's noisy measurement N times: error distributions and coverage",
        description="Simulate the scenario once, then draw its measurement noise N times (seeds from the scenario's "
                    "seed on, so the result does not depend on where the trials run: this process, --jobs K forked "
                    "processes or --dask), identify the parameters each time, and write "
                    "the distribution of each parameter's error, how often its 95 % interval contains the true value, "
                    "and the error at scaled noise levels: DIR/sweep.json and DIR/sweep.html. The graph-theory "
                    "study's force path is swept where the scenario has it; otherwise the scenario's joint-torque "
                    "estimators ([estimators]) and identification methods ([identification]) are fitted to the N "
                    "trials (bias, spread, RMS error, and the coverage of their intervals where they give them).")
    sweep.add_argument("scenario", metavar="SCENARIO", help="scenario file or name (e.g. kr500_noise)")
    sweep.add_argument("--trials", type=int, default=200, metavar="N", help="number of trials (default 200)")
    _worker_options(sweep, "the trials")
    sweep.add_argument("--out", metavar="DIR", type=Path, default=None, help="default: reports/<scenario name>")
    excite = sub.add_parser(
        "excite", help="optimise a scenario's excitation and write the trajectory for a robot to play",
        description="Optimise the scenario's [excitation] (a Fourier series per joint, at rest at both ends, within "
                    "the position, velocity, acceleration and torque limits) and write one period of it as CSV: t, "
                    "then q_<joint>, qd_<joint>, qdd_<joint> for every joint, at the scenario's excitation rate.")
    excite.add_argument("scenario", metavar="SCENARIO", help="scenario file or name (e.g. ur5_excitation)")
    excite.add_argument("--out", metavar="FILE", type=Path, required=True, help="the CSV to write")
    audit = sub.add_parser(
        "audit", help="read a collection of robots and check each against Pinocchio's parser and MuJoCo",
        description="Read each robot as the harness reads it, then check it against readers and engines that share "
                    "none of its code: joint torques and mass matrix against Pinocchio's own parser of the same file "
                    "at 100 random states within the limits, torques against MuJoCo's inverse dynamics, the URDF "
                    "against MuJoCo's conversion of it to MJCF read back, every moving body's physical validity, and "
                    "the structural base-parameter count against the rank of Pinocchio's regressor. Writes "
                    "DIR/audit.json (a row per robot) and DIR/audit.html. Exit status 1 when a robot that was read "
                    "disagrees beyond 1e-9; a robot the harness refuses is a row, not a failure.")
    audit.add_argument("robots", metavar="ROBOT|FILE", nargs="*",
                       help="a URDF or MJCF file, or a robot of example-robot-data by name (default: every robot of "
                            "the installed example-robot-data)")
    audit.add_argument("--out", metavar="DIR", type=Path, default=None, help="default: reports/audit")
    audit.add_argument("--identify", action="store_true",
                       help="also identify each robot from a log of its own bench recording (4 s at 250 Hz, the "
                            "last 30 %% held out) through [data] (minutes for a collection)")
    audit.add_argument("--quiet", action="store_true", help="no progress messages")
    sub.add_parser("list", help="list the models, scenarios and installed plugins",
                   description="One line per model and per scenario found in ./models and ./scenarios and built "
                               "into the package, and per plugin (model, identification method, study) installed by "
                               "entry point.")
    init = sub.add_parser(
        "init", help="start a project for your own robot: model file, plugins, scenario, test, CI job",
        description="Write a small project into DIR (which must not exist or be empty): a robot (URDF and model "
                    "file), a plugin module with a model under test and an identification method to make yours, a "
                    "scenario with gates and a validation trajectory, a pytest file using the harness_run fixture, "
                    "and a CI job that uploads the JUnit file. Out of the box `harness run scenario.toml` and "
                    "`python -m pytest` pass in DIR; with --urdf, for your robot.")
    init.add_argument("dir", metavar="DIR", type=Path)
    init.add_argument("--urdf", metavar="FILE", type=Path, default=None,
                      help="your robot's URDF: copied in, every joint given a motion within its limits, and a "
                           "placeholder model (Pinocchio on the URDF) to replace with yours (default: a two-link arm "
                           "with a closed-form model)")
    return parser


def _ci_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--junit-xml", metavar="FILE", type=Path, default=None,
                   help="also write the verdict as JUnit XML: one test case per gate, a failure for each failing gate")
    p.add_argument("--summary", metavar="FILE", type=Path, default=None,
                   help="also write a Markdown table of the gates (for a CI job summary)")


def _write_ci(args: argparse.Namespace, verdicts: list[tuple[str, list[dict]]]) -> None:
    from harness.runner.ci import junit_xml, markdown_summary

    for path, text in ((args.junit_xml, junit_xml), (args.summary, markdown_summary)):
        if path is not None:
            try:
                _write_file_atomically(path, text(verdicts))
            except OSError as exc:
                raise InputError(path, "", f"cannot write ({exc.strerror or exc})") from None


def _write_file_atomically(path: Path, text: str) -> None:
    path = path.resolve()
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(fd, "w") as f:
            f.write(text)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def _write_atomically(out: Path, files: dict[str, Callable[[Path], object]]) -> None:
    """Write every file into a temporary folder beside `out`, then move them in: a failure leaves
    nothing half-written in `out`."""
    out = out.resolve()
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    try:
        for name, write in files.items():
            (tmp / name).parent.mkdir(parents=True, exist_ok=True)
            write(tmp / name)
        out.mkdir(exist_ok=True)
        for name in files:
            (out / name).parent.mkdir(parents=True, exist_ok=True)
            (tmp / name).replace(out / name)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


_BORN: float | None = None  # time.perf_counter() at the start of the `harness` process, noted by `entry`
_ENDS_WITH_COMMAND = False  # True in the child `entry` forks: the process ends when the command does


def _process_age() -> float:
    """Seconds since the `harness` process started (Linux: /proc), 0 where that cannot be read. The
    command runs in a child that `entry` forks, whose own start is the fork: it counts from the
    start of the process that forked it, which `entry` notes beforehand (the interpreter's start and
    the imports of this module happen there)."""
    if _BORN is not None:
        return max(time.perf_counter() - _BORN, 0.0)
    try:
        since_boot = float(Path("/proc/uptime").read_text().split()[0])
        stat = Path("/proc/self/stat").read_text()
        started = int(stat[stat.rindex(")") + 2:].split()[19]) / os.sysconf("SC_CLK_TCK")  # field 22
        return max(since_boot - started, 0.0)
    except (OSError, ValueError, IndexError):
        return 0.0


def cmd_run(args: argparse.Namespace) -> int:
    start = time.perf_counter()
    started = _process_age()  # the interpreter's start and the imports of this module, before `start`
    # in the child `entry` forks, the modules' objects live as long as the process: the cyclic garbage
    # collector is kept from walking them while they are made, and from then on (gc.freeze: 20 ms of
    # a kr500_rail run); a process that goes on after the command (main() called from Python) keeps
    # its collector as it was
    freeze = _ENDS_WITH_COMMAND and gc.isenabled()
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
    workers = _workers(args, " ".join(names))
    scenarios, reading = [], []  # all validated before any work
    for a in names:
        t0 = time.perf_counter()
        scenarios.append(load_scenario(_resolve_scenario(a)))
        reading.append(time.perf_counter() - t0)
    seen = set()
    for s in scenarios:
        if s.name in seen:
            raise InputError(s.source, "", f"scenario {s.name!r} is named twice")
        seen.add(s.name)
        for note in s.robot.notes:  # what reading the model assumed: said before any work
            print(f"harness: warning: {s.name}: {note}", file=sys.stderr)
        for entry in s.methods:
            if entry.skipped is not None:
                print(f"harness: warning: {s.name}: identification method {entry.name} skipped: {entry.skipped}",
                      file=sys.stderr)
    try:  # the workers cannot be reached or started: the address, or dask not installed
        with workers.opened():  # started once for every scenario
            passed, verdicts = _run_each(args, scenarios, reading, workers, imported)
    except WorkersError as exc:
        raise InputError(" ".join(names), "--dask", str(exc)) from None
    _write_ci(args, verdicts)
    return EXIT_OK if passed else EXIT_GATE_FAILED


def _run_each(args: argparse.Namespace, scenarios: list, reading: list[float], workers,
              imported: float) -> tuple[bool, list]:
    from harness.api import run
    from harness.base.progress import Progress
    from harness.report import render
    from harness.runner.results import RECORDING_FILE, RESULTS_FILE, write_results

    passed, verdicts = True, []
    for scenario, read in zip(scenarios, reading, strict=True):
        if args.out is None:
            out = args.reports / scenario.name
        else:
            out = args.out if len(scenarios) == 1 else args.out / scenario.name
        progress = Progress(scenario.name, args.quiet)
        with closing(progress):  # a bar in progress ends its line before anything else is printed
            result = run(scenario, progress, workers)
        progress("writing the report", None)
        results = result.results
        for warning in (results.get("data", {}).get("conditioning", {}).get("warnings", [])
                        + results.get("log_identification", {}).get("warnings", [])):
            print(f"harness: warning: {scenario.name}: {warning}", file=sys.stderr)  # once per run, not per row
        results["run"]["timings"] = {"starting Python and importing the engines and libraries": imported,
                                     "reading the scenario, its model and plugins": read,
                                     **results["run"]["timings"]}
        imported = 0.0
        page = render(results, result.recording, [s.stage for s in result.output.stages.values()])
        try:
            data_file = results["data"]["file"] if "data" in results else RECORDING_FILE
            _write_atomically(out, {
                data_file: result.recording.write_csv,
                RESULTS_FILE: lambda p, r=results: write_results(p, r),
                REPORT_FILE: lambda p, text=page: p.write_text(text),
                **{name: (lambda p, text=text: p.write_text(text)) for name, text in result.output.files.items()},
            })
        except OSError as exc:
            raise InputError(out, "--out", f"cannot write output ({exc.strerror or exc})") from None
        _print_summary(results, out)
        passed &= results["passed"]
        verdicts.append((scenario.name, results["gates"]))
    return passed, verdicts


def _print_summary(results: dict, out: Path) -> None:
    print(summary_line(results["scenario"]["name"], results["gates"]))
    _print_gates(results["gates"])
    print(f"  report: {out / REPORT_FILE}")


def _print_gates(rows: list[dict]) -> None:
    for g in rows:
        print(f"  {result_word(g)}  {gate_line(g)}")


def _read_results(path: Path) -> dict:
    from harness.base.tomlio import MAX_DATA_BYTES, read_bounded

    try:
        results = json.loads(read_bounded(path, MAX_DATA_BYTES).decode("utf-8"))
    except UnicodeDecodeError as exc:
        raise InputError(path, "", f"cannot read file ({exc})") from None
    except json.JSONDecodeError as exc:
        raise InputError(path, "", f"invalid JSON: {exc}") from None
    except RecursionError:
        raise InputError(path, "", "invalid JSON: nested too deeply") from None
    schema = results.get("schema") if isinstance(results, dict) else None
    if not isinstance(schema, dict) or schema.get("name") != "harness-results":
        raise InputError(path, "schema", "not a results.json written by harness")
    for key in ("scenario", "data" if "data" in results else "recording", "run"):
        if not isinstance(results.get(key), dict):
            raise InputError(path, key, "missing or not an object: not a complete results.json")
    return results


def cmd_report(args: argparse.Namespace) -> int:
    from harness.report import render_report

    results = _read_results(args.results)
    kind = "data" if "data" in results else "recording"  # a measured log, or the bench's recording
    rec_name = results[kind].get("file", "recording.csv")
    if not isinstance(rec_name, str) or Path(rec_name).name != rec_name:
        raise InputError(args.results, f"{kind}.file", "must name a file beside results.json")
    recording = args.results.parent / rec_name
    if not recording.is_file():
        raise InputError(recording, "", f"file not found (the report needs the {kind} beside results.json)")
    out = args.out or args.results.parent / REPORT_FILE
    from harness.base.series import read_csv

    rec = read_csv(recording, bodies=kind == "recording")
    stated = results[kind]
    if len(rec.t) != stated.get("rows") or list(rec.joints) != stated.get("joints"):
        raise InputError(recording, "", f"has {len(rec.t)} rows of joints {list(rec.joints)}; results.json "
                                        f"says {stated.get('rows')} rows of {stated.get('joints')}")
    try:
        page = render_report(results, args.results.parent)
    except (KeyError, TypeError) as exc:
        raise InputError(args.results, str(exc).strip("'"), "missing or malformed in results.json") from None
    try:
        _write_file_atomically(out, page)
    except OSError as exc:
        raise InputError(out, "--out", f"cannot write ({exc.strerror or exc})") from None
    print(f"wrote {out}")
    return EXIT_OK


def cmd_gate(args: argparse.Namespace) -> int:
    from harness.runner.gates import from_results, verdict
    from harness.runner.scenario import load_scenario

    gates = None if args.scenario is None else load_scenario(args.scenario).gates
    passed, verdicts = True, []
    for path in args.results:
        results = _read_results(path)
        checked = verdict(gates if gates is not None else from_results(results, path), results,
                          args.scenario or path)
        rows, ok = checked["gates"], checked["passed"]
        name = results.get("scenario", {}).get("name", str(path)) if isinstance(results.get("scenario"), dict) \
            else str(path)
        print(summary_line(name, rows))
        _print_gates(rows)
        passed &= ok
        verdicts.append((name, rows))
    _write_ci(args, verdicts)
    return EXIT_OK if passed else EXIT_GATE_FAILED


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
    from harness.runner.results import with_nulls
    from harness.runner.scenario import load_scenario

    scenario = load_scenario(_resolve_scenario(args.scenario))
    sweep = _sweep_of(scenario)
    if sweep is None:
        raise InputError(scenario.source, "studies", "nothing in this scenario can be swept: the graph-theory study's "
                                                     "force path ([studies.graph_theory_2021]), the joint-torque "
                                                     "estimators ([estimators]) or an identification method "
                                                     "([identification]) can")
    if not 2 <= args.trials <= MAX_TRIALS:
        raise InputError(args.scenario, "--trials", f"needs 2 to {MAX_TRIALS:,} trials, got {args.trials}")
    workers = _workers(args, args.scenario)
    if scenario.measurement.ideal:
        raise InputError(scenario.source, "measurement", "the scenario measures ideally: there is nothing to sweep")
    out = args.out or args.reports / scenario.name
    try:  # the workers cannot be reached or started: the address, or dask not installed
        with workers.opened(), closing(Progress(scenario.name, after=0.0)) as progress:  # a bar ends its line
            results = sweep.run(scenario, args.trials, workers, progress)
    except WorkersError as exc:
        raise InputError(args.scenario, "--dask", str(exc)) from None
    results, not_finite = with_nulls(results)
    results.setdefault("run", {})["not_finite"] = not_finite
    text = sweep.render(results)
    try:
        _write_atomically(out, {"sweep.json": lambda p: p.write_text(json.dumps(results, indent=1,
                                                                                allow_nan=False) + "\n"),
                                "sweep.html": lambda p: p.write_text(text)})
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

    scenario = load_scenario(_resolve_scenario(args.scenario))
    if not isinstance(scenario, Scenario) or scenario.excitation is None:
        raise InputError(getattr(scenario, "source", args.scenario), "excitation",
                         "the scenario has no [excitation] to optimise")
    optimised, report = optimise(scenario, scenario.excitation, with_friction(scenario))
    t, q, qd, qdd = trajectory(optimised, scenario.excitation)
    cols = {"t": t}
    for k, j in enumerate(scenario.robot.joint_names):
        cols[f"q_{j}"], cols[f"qd_{j}"], cols[f"qdd_{j}"] = q[:, k], qd[:, k], qdd[:, k]
    import pandas as pd

    text = pd.DataFrame(cols).to_csv(index=False, float_format="%.17g")
    try:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        _write_file_atomically(args.out, text)
    except OSError as exc:
        raise InputError(args.out, "--out", f"cannot write ({exc.strerror or exc})") from None
    used = ", ".join(f"{k} {v:.3f}" for k, v in report["largest_fraction_of_limits"].items())
    print(f"{scenario.name}: wrote {args.out}: {len(t)} rows over {t[-1]:.3f} s at {scenario.excitation.rate:g} Hz, "
          f"at rest at both ends; condition number {report['initial_condition_number']:.3g} -> "
          f"{report['optimised_condition_number']:.3g}; largest fraction of each limit: {used}")
    return EXIT_OK


def cmd_audit(args: argparse.Namespace) -> int:
    import time

    from harness.base.progress import Progress
    from harness.report.audit import render_audit
    from harness.runner.audit import IDENTIFY_TOLERANCE, TOLERANCE, audit, resolve, totals

    robots = resolve(args.robots)
    out = args.out or args.reports / "audit"
    t0 = time.perf_counter()
    rows = []
    with closing(Progress("audit", args.quiet)) as progress, tempfile.TemporaryDirectory() as scratch:
        for k, (name, path) in enumerate(robots.items()):
            progress(f"robot {k + 1} of {len(robots)}: {name}", k / len(robots))
            rows.append(audit(name, path, Path(scratch) if args.identify else None))
    summary = {**totals(rows), "tolerance": TOLERANCE,
               "identify_tolerance": IDENTIFY_TOLERANCE if args.identify else None,
               "seconds": round(time.perf_counter() - t0, 3)}
    document = {"schema": {"name": "harness-audit", "version": 1}, "totals": summary,
                "robots": [r.as_dict() for r in rows]}
    from harness.runner.results import with_nulls

    document, _ = with_nulls(document)
    text = render_audit(document)
    try:
        _write_atomically(out, {"audit.json": lambda p: p.write_text(json.dumps(document, indent=1, allow_nan=False)
                                                                     + "\n"),
                                "audit.html": lambda p: p.write_text(text)})
    except OSError as exc:
        raise InputError(out, "--out", f"cannot write output ({exc.strerror or exc})") from None
    for r in rows:
        if r.verdict != "agrees":
            print(f"  {r.verdict:9s} {r.robot}: {r.reason}")
    print(f"audit: {summary['robots']} robots, {summary['read']} read, {summary['agree']} agree, "
          f"{summary['disagree']} disagree, {summary['refused']} refused; MuJoCo's MJCF conversion read back for "
          f"{summary['mjcf_read']} ({summary['seconds']:.1f} s)")
    print(f"  report: {out / 'audit.html'}")
    return EXIT_GATE_FAILED if summary["disagree"] else EXIT_OK


def cmd_list(args: argparse.Namespace) -> int:
    from harness.base.builtin import listing

    for kind, key in (("models", "model"), ("scenarios", "scenario")):
        for where, files in listing(kind):
            print(f"{where} ({len(files)})")
            for f in files:
                print(f"  {f.stem:<24} {_description(f, key)}")
    from importlib.metadata import entry_points

    from harness.base.plugins import METHOD_GROUP, MODEL_GROUP, STUDY_GROUP

    for title, group in (("model plugins", MODEL_GROUP), ("identification plugins", METHOD_GROUP),
                         ("studies", STUDY_GROUP)):
        found = sorted(entry_points(group=group), key=lambda ep: ep.name)
        print(f"{title} installed ({len(found)})")
        for ep in found:
            print(f"  {ep.name:<24} {ep.value}")
    return EXIT_OK


def cmd_init(args: argparse.Namespace) -> int:
    from harness.init import project

    out: Path = args.dir
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise InputError(out, "DIR", "exists and is not an empty folder: init writes a new project")
    files = project(args.urdf)
    try:
        _write_atomically(out, {name: (lambda p, text=text: p.write_text(text)) for name, text in files.items()})
    except OSError as exc:
        raise InputError(out, "DIR", f"cannot write ({exc.strerror or exc})") from None
    print(f"wrote {out}/: {', '.join(files)}")
    print(f"  cd {out} && harness run scenario.toml --out reports && python -m pytest")
    return EXIT_OK


def _description(path: Path, key: str) -> str:
    """The file's [key] description, or why it cannot be read (a listing never stops at one bad file)."""
    try:
        section = read_toml(path).get(key, {})
    except InputError as exc:
        return f"(unreadable: {exc.message})"
    if not isinstance(section, dict):
        return f"(unreadable: {key!r} is not a table)"
    text = section.get("description", "")
    return text if isinstance(text, str) else f"(unreadable: {key}.description is not a string)"


class _Stdout:
    """Standard output that goes quiet once its reader has gone (`harness list | head -1`): a
    broken pipe is not a verdict, so the command runs to its end and exits with its own status."""

    def __init__(self, stream):
        self.stream, self.gone = stream, False

    def write(self, text: str) -> int:
        if not self.gone:
            try:
                return self.stream.write(text)
            except BrokenPipeError:
                self._gone()
        return len(text)

    def flush(self) -> None:
        if not self.gone:
            try:
                self.stream.flush()
            except BrokenPipeError:
                self._gone()

    def _gone(self) -> None:
        self.gone = True
        try:  # what is still buffered goes nowhere, also when the interpreter flushes at exit
            os.dup2(os.open(os.devnull, os.O_WRONLY), self.stream.fileno())
        except (OSError, ValueError, AttributeError):
            pass

    def __getattr__(self, name: str):
        return getattr(self.stream, name)


def _no_verdict(args: argparse.Namespace, kind: str, message: str) -> None:
    """Bad input or an internal error: the CI files asked for still say so, as one test case with
    an error (harness/runner/ci.py). Nothing is written where the CI file itself is the fault."""
    given = next((v for v in (getattr(args, k, None) for k in ("scenarios", "results", "scenario")) if v),
                 [DEFAULT_SCENARIO] if args.command == "run" else [f"harness {args.command}"])
    name = " ".join(str(s) for s in (given if isinstance(given, list) else [given]))
    for attr, text in (("junit_xml", error_xml), ("summary", error_summary)):
        path = getattr(args, attr, None)
        if path is not None:
            try:
                _write_file_atomically(path, text(name, kind, message))
            except OSError:
                pass


def _origin(exc: BaseException) -> str:
    where = traceback.extract_tb(exc.__traceback__)
    return f" (at {Path(where[-1].filename).name}:{where[-1].lineno})" if where else ""


def main(argv: list[str] | None = None) -> int:
    """The command, in this process. Only the harness chooses the exit status: 0 every gate passed,
    1 a gate failed, 2 bad input (plugin code that raises anything, SystemExit and KeyboardInterrupt
    included, is bad input), 3 an internal error, 130 the user's Ctrl-C."""
    from harness.base.plugins import PluginError, interrupted_by_user, user_interrupts

    # the command draws nothing on screen: MuJoCo's OpenGL contexts (glfw, about 0.13 s of its import)
    # are not loaded unless the environment asks for them (MUJOCO_GL set beforehand is kept)
    os.environ.setdefault("MUJOCO_GL", "disable")
    args = _parser().parse_args(argv)
    for attr in ("out", "junit_xml", "summary"):  # where to write, fixed now: plugin code may change directory
        if getattr(args, attr, None) is not None:
            setattr(args, attr, Path(os.path.abspath(getattr(args, attr))))
    args.reports = Path(os.path.abspath("reports"))  # the default output folder's parent
    stdout, sys.stdout = sys.stdout, _Stdout(sys.stdout)
    status, kind, message = EXIT_INTERNAL, "internal error", ""
    try:
        with user_interrupts():
            status = {"run": cmd_run, "report": cmd_report, "gate": cmd_gate, "sweep": cmd_sweep,
                      "excite": cmd_excite, "list": cmd_list, "init": cmd_init,
                      "audit": cmd_audit}[args.command](args)
    except InputError as exc:
        status, kind, message = EXIT_BAD_INPUT, "bad input", exc.one_line()
    except PluginError as exc:
        status, kind, message = EXIT_BAD_INPUT, "bad input", f"plugin {exc}"
    except KeyboardInterrupt as exc:
        if interrupted_by_user():
            print("harness: interrupted", file=sys.stderr)
            status = 130
        else:  # raised by code, not by the user: a plugin's, reached outside its guard
            status, kind = EXIT_BAD_INPUT, "bad input"
            message = f"KeyboardInterrupt raised by code, not by the user{_origin(exc)}"
    except SystemExit as exc:  # the harness never calls sys.exit inside a command: plugin code did
        status, kind = EXIT_BAD_INPUT, "bad input"
        message = f"sys.exit({exc.code!r}) called by code the harness ran{_origin(exc)}: it does not end the run"
    except Exception as exc:
        if args.debug:
            traceback.print_exc()
        message = (f"internal error: {type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"
                   f"{_origin(exc)}{'' if args.debug else '; --debug shows the traceback'}")
    finally:
        sys.stdout.flush()
        sys.stdout = stdout
    if message:
        print(f"harness: {'error: ' if kind == 'bad input' else ''}{message}", file=sys.stderr)
        _no_verdict(args, kind, message)
    return status


def entry() -> None:
    """The `harness` command. The command runs in a child process and this one chooses the exit
    status: a child that ends without handing back its status (plugin code calling os._exit, or
    crashing the interpreter) is an internal error, exit 3, with the CI files still written.
    Where processes cannot be forked, it runs here."""
    argv = sys.argv[1:]
    if not hasattr(os, "fork"):
        sys.exit(main(argv))
    args = _parser().parse_args(argv)  # usage errors: exit 2 here, before anything is started
    sys.stdout.flush()
    sys.stderr.flush()
    global _BORN, _ENDS_WITH_COMMAND
    _BORN = time.perf_counter() - _process_age()  # the child's clock and this one are the same (monotonic)
    read_end, write_end = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child: the command
        os.close(read_end)
        status = EXIT_INTERNAL
        _ENDS_WITH_COMMAND = True
        try:
            status = main(argv)
        finally:
            for stream in (sys.stdout, sys.stderr):
                try:
                    stream.flush()
                except (OSError, ValueError):
                    pass
            os.write(write_end, bytes([status]))
            os._exit(status)
    os.close(write_end)
    # Ctrl-C and SIGTERM are passed on to the child, which unwinds and answers 130 (a second one,
    # from the terminal to the whole process group, finds it already unwinding)
    for s in (signal.SIGINT, signal.SIGTERM):
        signal.signal(s, lambda signum, frame: os.kill(pid, signum))
    _, wait_status = os.waitpid(pid, 0)
    os.set_blocking(read_end, False)  # processes the child started may hold the pipe open: read what is there
    try:
        handed = os.read(read_end, 1)
    except BlockingIOError:
        handed = b""
    os.close(read_end)
    if handed:
        _leave(handed[0])
    if os.WIFSIGNALED(wait_status) and os.WTERMSIG(wait_status) in (signal.SIGINT, signal.SIGTERM):
        print("harness: interrupted", file=sys.stderr)
        _leave(130)
    how = (f"killed by signal {signal.Signals(os.WTERMSIG(wait_status)).name}" if os.WIFSIGNALED(wait_status)
           else f"exit status {os.WEXITSTATUS(wait_status)}")
    message = (f"internal error: the command ended without a verdict ({how}): code it ran (a plugin?) ended the "
               "process or crashed it")
    print(f"harness: {message}", file=sys.stderr)
    _no_verdict(args, "internal error", message)
    _leave(EXIT_INTERNAL)


def _leave(status: int) -> None:
    """The waiting process ends with the child's verdict: its output flushed, and without the
    interpreter's teardown of the modules it imported (numpy's among them: 10 to 15 ms), since it
    holds nothing else to release."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    os._exit(status)


if __name__ == "__main__":  # pragma: no cover
    entry()
