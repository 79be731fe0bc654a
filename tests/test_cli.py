"""`harness run`: what it writes, and how it refuses bad input (exit 2, one line naming the file
and the key, no traceback, nothing left in the output folder)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from harness.cli import main
from tests.conftest import MODELS, SCENARIOS, copy_gate_sets


def test_run_writes_recording_results_and_report(kr500_run):
    """The recording, results.json, the report, and the graph-theory study's Cardano angles beside the
    recording (its stage's file), listed in the run's manifest."""
    assert sorted(p.name for p in kr500_run.iterdir()) == ["cardano.csv", "manifest.json", "recording.csv",
                                                           "report.html", "results.json"]
    results = json.loads((kr500_run / "results.json").read_text())
    assert list(results)[:4] == ["schema", "passed", "gates", "run"]
    assert results["passed"] is True and all(g["passed"] for g in results["gates"])
    assert results["scenario"]["name"] == "kr500_rail"
    assert results["scenario"]["sample_times"] == [0.3, 0.6, 0.9, 1.2, 1.5]
    assert results["model"]["name"] == "kr500"
    assert results["recording"]["rows"] == 101
    assert results["graph"]["gimbal_lock_rows"]["B1"][0] == 0.0  # the graph-theory study's
    worst = max(v["q_max_abs_error"] for v in results["recording"]["tracking_error"].values())
    assert worst <= 1e-9


def _copy_inputs(tmp_path: Path, model_edit=None, scenario_edit=None) -> Path:
    """A model and scenario pair in tmp_path, each optionally edited as text."""
    (tmp_path / "models").mkdir()
    (tmp_path / "scenarios").mkdir()
    copy_gate_sets(tmp_path / "scenarios")
    model = (MODELS / "kr500.toml").read_text()
    scenario = (SCENARIOS / "kr500_rail.toml").read_text()
    (tmp_path / "models" / "kr500.toml").write_text(model_edit(model) if model_edit else model)
    path = tmp_path / "scenarios" / "kr500_rail.toml"
    path.write_text(scenario_edit(scenario) if scenario_edit else scenario)
    return path


def _replace_in_body(body: str, old: str, new: str):
    """Edit one line inside the [[bodies]] entry named `body`."""
    def edit(text: str) -> str:
        start = text.index(f'name = "{body}"')
        end = text.index(old, start) + len(old)
        return text[:end - len(old)] + new + text[end:]
    return edit


def _replace_in_joint(joint: str, old: str, new: str):
    return _replace_in_body(joint, old, new)


BAD_MODELS = {
    "invalid TOML": (lambda t: t.replace("[model]", "[model"), "models/kr500.toml", "invalid TOML"),
    "unknown key": (_replace_in_body("B3", "radius = 0.2", "radius = 0.2\ncolour = 1"),
                    "models/kr500.toml", "bodies.B3.colour"),
    "missing key": (_replace_in_body("B3", "radius = 0.2\n", ""), "models/kr500.toml",
                    "bodies.B3.radius"),
    "negative length": (_replace_in_body("B2", "length = 1.245", "length = -1.245"),
                        "models/kr500.toml", "bodies.B2.length"),
    "zero radius": (_replace_in_body("B4", "radius = 0.2", "radius = 0.0"),
                    "models/kr500.toml", "bodies.B4.radius"),
    "zero density": (_replace_in_body("B5", "density = 7801.0", "density = 0"),
                     "models/kr500.toml", "bodies.B5.density"),
    "negative mass": (_replace_in_body("B6", 'shape = "cylinder"\nlength = 0.3\nradius = 0.3\n'
                                             "density = 7801.0",
                                       'shape = "explicit"\nmass = -661.7\ninertia = [29.8, 19.9, 19.9]'),
                      "models/kr500.toml", "bodies.B6.mass"),
    "zero axis": (_replace_in_joint("O3", "axis = [0.0, 1.0, 0.0]", "axis = [0.0, 0.0, 0.0]"),
                  "models/kr500.toml", "joints.O3.axis"),
    "unknown joint type": (_replace_in_joint("O4", 'type = "revolute"', 'type = "spherical"'),
                           "models/kr500.toml", "joints.O4.type"),
    "missing parent": (_replace_in_joint("O5", 'parent = "B4"', 'parent = "B44"'),
                       "models/kr500.toml", "joints.O5.parent"),
    "loop": (lambda t: _replace_in_joint("O1", 'parent = "carriage"', 'parent = "B2"')(t),
             "models/kr500.toml", "joints.O1.parent"),
    "duplicate name": (_replace_in_body("B5", 'name = "B5"', 'name = "B4"'),
                       "models/kr500.toml", "bodies.B4.name"),
    "non-finite number": (_replace_in_body("B2", "length = 1.245", "length = inf"),
                          "models/kr500.toml", "bodies.B2.length"),
}

BAD_SCENARIOS = {
    "joint the model lacks": (lambda t: t + '\n[motion.O7]\ntype = "locked"\n', "motion.O7"),
    "joint without motion": (lambda t: t.replace('[motion.O6]\ntype = "locked"\n', ""), "motion.O6"),
    "sample time outside the run": (lambda t: t.replace("1.5]", "2.5]"), "scenario.sample_times"),
    "non-finite acceleration": (lambda t: t.replace("acceleration = 2.0", "acceleration = nan"),
                                "motion.rail.acceleration"),
    "unknown motion type": (lambda t: t.replace('[motion.O3]\ntype = "locked"',
                                                '[motion.O3]\ntype = "jerk"'), "motion.O3.type"),
    "model file missing": (lambda t: t.replace("../models/kr500.toml", "../models/kr5000.toml"),
                           "scenario.model"),
    "non-positive duration": (lambda t: t.replace("duration = 2.0", "duration = 0.0"),
                              "scenario.duration"),
    "timestep not dividing the output interval": (
        lambda t: t.replace("timestep = 0.0005", "timestep = 0.0007"), "simulation.timestep"),
}


def _assert_refused(capsys, argv: list[str], file_part: str, key: str, out: Path) -> None:
    assert main(argv) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1, captured.err
    assert lines[0].startswith("harness: error: ")
    assert file_part in lines[0] and key in lines[0], lines[0]
    assert "Traceback" not in captured.err and captured.out == ""
    assert not out.exists()
    assert not [p for p in out.parent.iterdir() if p.name.startswith(f".{out.name}")]


@pytest.mark.parametrize("case", list(BAD_MODELS))
def test_bad_model_is_refused(tmp_path, capsys, case):
    edit, file_part, key = BAD_MODELS[case]
    scenario = _copy_inputs(tmp_path, model_edit=edit)
    out = tmp_path / "out"
    _assert_refused(capsys, ["run", str(scenario), "--out", str(out)], file_part, key, out)


@pytest.mark.parametrize("case", list(BAD_SCENARIOS))
def test_bad_scenario_is_refused(tmp_path, capsys, case):
    edit, key = BAD_SCENARIOS[case]
    scenario = _copy_inputs(tmp_path, scenario_edit=edit)
    out = tmp_path / "out"
    _assert_refused(capsys, ["run", str(scenario), "--out", str(out)], "scenarios/kr500_rail.toml",
                    key, out)


def test_missing_and_unreadable_files_are_refused(tmp_path, capsys):
    out = tmp_path / "out"
    _assert_refused(capsys, ["run", str(tmp_path / "nope.toml"), "--out", str(out)], "nope.toml",
                    "file not found", out)
    (tmp_path / "dir.toml").mkdir()
    _assert_refused(capsys, ["run", str(tmp_path / "dir.toml"), "--out", str(out)], "dir.toml",
                    "cannot read", out)
    (tmp_path / "binary.toml").write_bytes(b"\xff\xfe\x00")
    _assert_refused(capsys, ["run", str(tmp_path / "binary.toml"), "--out", str(out)], "binary.toml",
                    "cannot read", out)


def test_console_script_refuses_bad_input_without_traceback(tmp_path):
    """The installed `harness` command, as a user runs it."""
    scenario = _copy_inputs(tmp_path, scenario_edit=BAD_SCENARIOS["joint the model lacks"][0])
    out = tmp_path / "out"
    exe = Path(sys.executable).with_name("harness")
    cmd = [str(exe)] if exe.exists() else [sys.executable, "-m", "harness.cli"]
    proc = subprocess.run([*cmd, "run", str(scenario), "--out", str(out)], capture_output=True,
                          text=True, env={**os.environ, "PYTHONWARNINGS": "error"}, check=False)
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "motion.O7" in proc.stderr
    assert "Traceback" not in proc.stderr
    assert not out.exists()


@pytest.mark.slow  # a second or more: a whole pipeline, or processes
def test_sigterm_stops_a_run_in_one_line_and_leaves_nothing_behind(tmp_path):
    """Terminated while it works (after its first progress line, inside the constrained model's
    forward simulation): one line, exit status 130, no output folder and no temporary one."""
    import signal
    import subprocess
    import sys

    proc = subprocess.Popen([sys.executable, "-m", "harness.cli", "run", str(SCENARIOS / "kr500_rail_forward.toml"),
                             "--out", str(tmp_path / "out")], cwd=tmp_path, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    first = proc.stderr.readline()  # the handler is installed before any progress is printed
    proc.send_signal(signal.SIGTERM)
    _, rest = proc.communicate(timeout=120)
    assert "[kr500_rail_forward" in first
    assert proc.returncode == 130 and rest.splitlines()[-1] == "harness: interrupted"
    assert not list(tmp_path.iterdir())


def test_scenarios_that_name_each_other_are_refused_as_a_cycle(tmp_path, capsys):
    scenario = _copy_inputs(tmp_path)
    copy_gate_sets(tmp_path / "scenarios")
    text = scenario.read_text()
    scenario.write_text(text + '\n[torque_identification]\nvalidation = "other.toml"\n')
    back = text + '\n[torque_identification]\nvalidation = "kr500_rail.toml"\n'
    (tmp_path / "scenarios" / "other.toml").write_text(back)
    out = tmp_path / "out"
    _assert_refused(capsys, ["run", str(scenario), "--out", str(out)], "other.toml", "torque_identification.validation",
                    out)


@pytest.mark.slow  # three processes started and timed (3.5 s)
def test_the_start_up_is_counted_from_the_harnesss_own_start_not_its_processs(tmp_path):
    """A process that waits 2 s before it starts the harness (a shell that had just run pip read 54 s):
    run.timings' first entry is the harness's imports alone (about 0.3 s here), not the process's age."""
    code = ("import sys, time\ntime.sleep(2.0)\n"
            f"sys.argv = ['harness', 'run', 'kr500_rail', '--out', {str(tmp_path / 'o')!r}, '--quiet']\n"
            "from harness.cli import entry\nentry()\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    timings = json.loads((tmp_path / "o" / "results.json").read_text())["run"]["timings"]
    first, seconds = next(iter(timings.items()))
    assert first == "starting the harness and importing the engines and libraries" and seconds < 2.0
