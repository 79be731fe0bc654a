"""The `harness` command line: its commands and options (argparse), usage errors in one line."""

from __future__ import annotations

import argparse
from pathlib import Path

from harness.cli.common import DEFAULT_SCENARIO


class _Parser(argparse.ArgumentParser):
    """Usage errors in one line, exit status 2, like every other bad input."""

    def error(self, message: str):
        self.exit(2, f"harness: error: {message} (see harness --help)\n")

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


def parser() -> argparse.ArgumentParser:
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
    _replace_option(run)
    _worker_options(run, "the estimators' Monte Carlo trials ([estimators])")
    _ci_options(run)
    _results_commands(sub)
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
    sweep.add_argument("--out", metavar="DIR", type=Path, default=None,
                       help="default: reports/<scenario name>.sweep (beside the run's folder, not in it)")
    _replace_option(sweep)
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
                    "DIR/audit.json (a row per robot) and DIR/audit.html. Verdicts: agrees, disagrees (the dynamics "
                    "differ beyond 1e-9), not compared (a reference parser cannot represent the file: said which and "
                    "why), refused. Exit status 1 when a robot that was read disagrees, 2 when a robot named here is "
                    "refused; in the whole collection a refused robot is a row, not a failure.")
    audit.add_argument("robots", metavar="ROBOT|FILE", nargs="*",
                       help="a URDF or MJCF file, a model file (.toml: with its drives or friction, also checked "
                            "with them), or a robot of example-robot-data by name (default: every robot of the "
                            "installed example-robot-data)")
    audit.add_argument("--out", metavar="DIR", type=Path, default=None, help="default: reports/audit")
    audit.add_argument("--identify", action="store_true",
                       help="also identify each robot from a log of its own bench recording (4 s at 250 Hz, the "
                            "last 30 %% held out) through [data] (minutes for a collection)")
    audit.add_argument("--quiet", action="store_true", help="no progress messages")
    _replace_option(audit)
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
                    "`python -m pytest` pass in DIR; with --urdf or --mjcf, for your robot.")
    init.add_argument("dir", metavar="DIR", type=Path)
    robot = init.add_mutually_exclusive_group()
    for flag, kind in (("--urdf", "URDF"), ("--mjcf", "MJCF file"), ("--robot", "URDF or MJCF file")):
        robot.add_argument(flag, metavar="FILE", type=Path, default=None, dest=flag.removeprefix("--"),
                           help=f"your robot's {kind}: copied in, every joint given a motion within its limits, and a "
                                "placeholder model (Pinocchio on the file) to replace with yours (default: a two-link "
                                "arm with a closed-form model); any of --urdf, --mjcf and --robot takes either format, "
                                "told by its root element")
    init.add_argument("--floating", action="store_true",
                      help="the URDF's root link is a floating base (a legged robot or humanoid whose file, as most "
                           "published ones, has no `floating` joint): robot.toml says `floating = true`, the bench "
                           "holds the base where the file draws it while the joints move, and floating.toml judges "
                           "the robot with its base moving (docs/floating_base.md)")
    return parser


def _results_commands(sub) -> None:
    """`report`, `gate` and `compare`: what reads results.json files without simulating again."""
    report = sub.add_parser("report", help="re-render report.html from a results.json",
                            description="Re-render the HTML report from a results.json and the recording.csv "
                                        "beside it, without simulating again.")
    report.add_argument("results", metavar="RESULTS.json", type=Path)
    report.add_argument("--out", metavar="FILE", type=Path, default=None,
                        help="where to write the report (default: report.html beside RESULTS.json)")
    report.add_argument("--figures", metavar="DIR", type=Path, default=None,
                        help="also write each chart of the report as PNG and PDF into DIR, drawn with matplotlib "
                             "from the same data (pip install 'robot-dynamics-harness[figures]')")
    gate = sub.add_parser("gate", help="re-check the gates of one or more results.json",
                          description="Check gates against existing results without simulating again. The gates "
                                      "are the ones stored in each results.json, or those of --scenario FILE (for "
                                      "example after changing a limit). Exit status 1 if any gate fails.")
    gate.add_argument("results", metavar="RESULTS.json", type=Path, nargs="+")
    gate.add_argument("--scenario", metavar="FILE", type=Path, default=None,
                      help="take the gates from this scenario file instead")
    _ci_options(gate)
    comp = sub.add_parser(
        "compare", help="compare two runs' gated metrics: is the candidate worse than the baseline?",
        description="Read each gated metric of the candidate in both runs and say, per metric, whether the "
                    "candidate is worse beyond its tolerance: the gate's own (tolerance = ... in [[gates]]), "
                    "else an order of magnitude for a round-off gate (limit at most 1e-6) and a 1 % change "
                    "its wrong way for any other. Exit status 1 naming each worse metric, 2 when the runs are "
                    "of another scenario or one is missing.")
    comp.add_argument("baseline", metavar="BASELINE", type=Path,
                      help="a results.json, or a folder of runs (DIR/results.json or DIR/*/results.json)")
    comp.add_argument("candidate", metavar="CANDIDATE", type=Path, help="the same, of the run to judge")
    _ci_options(comp)


def _replace_option(p: argparse.ArgumentParser) -> None:
    p.add_argument("--replace", action="store_true",
                   help="replace what an output folder holds of another run (of another scenario or command); "
                        "without it such a folder is refused, and a run of the same scenario is replaced whole. A "
                        "folder holding files no run wrote is never replaced")


def _ci_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--junit-xml", metavar="FILE", type=Path, default=None,
                   help="also write the verdict as JUnit XML: one test case per gate, a failure for each failing gate")
    p.add_argument("--summary", metavar="FILE", type=Path, default=None,
                   help="also write a Markdown table of the gates (for a CI job summary)")


