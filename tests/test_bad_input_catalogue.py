"""A catalogue of bad inputs, each refused the same way: exit status 2, one line that starts with
`harness: error:`, no traceback, nothing written beside or into --out, no MUJOCO_LOG.TXT. Exit 3
(an internal error) is never seen here. Cases: model files, URDFs, scenarios, plugins, results
files and the command line; signals are in test_cli.py."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from harness.cli import main
from tests.conftest import MODELS, SCENARIOS, copy_gate_sets
from tests.test_cli import BAD_MODELS, BAD_SCENARIOS
from tests.test_urdf import BAD_URDFS, EXAMPLE_URDF


def _sub(old: str, new: str):
    def edit(text: str) -> str:
        assert old in text, old
        return text.replace(old, new, 1)
    return edit


def _append(extra: str):
    return lambda text: text + extra


MODEL_EDITS = {name: edit for name, (edit, _, _) in BAD_MODELS.items()} | {
    "400-digit integer": _sub("density = 7801.0", "density = " + "9" * 400),
    "mass as text": _sub('shape = "cylinder"\nlength = 0.3\nradius = 0.3\ndensity = 7801.0',
                         'shape = "explicit"\nmass = "heavy"\ninertia = [29.8, 19.9, 19.9]'),
    "no [model]": _sub("[model]", "[modelx]"),
    "gravity of two numbers": _sub("[model]", "[model]\ngravity = [0.0, -9.81]"),
    "huge length": _sub("length = 1.245", "length = 1e200"),
}

SCENARIO_EDITS = {name: edit for name, (edit, _) in BAD_SCENARIOS.items()} | {
    "no gates": lambda t: t[: t.index("\n[[gates]]")].replace(
        'gate_sets = ["gates/engines.toml", "gates/graph_theory_2021.toml"]\n', ""),
    "misspelt direction": _append('\n[[gates]]\nmetric = "recording.rows"\nlimit = 1\ndirection = "atmost"\n'),
    "gate limit as text": _append('\n[[gates]]\nmetric = "recording.rows"\nlimit = "small"\n'),
    "gate metric empty": _append('\n[[gates]]\nmetric = ""\nlimit = 1\n'),
    "gate set missing": _sub('"gates/engines.toml"', '"gates/nothing.toml"'),
    "built-in gate set unknown": _sub('"gates/engines.toml"', '"harness:nothing"'),
    "old model_under_test key": _sub('model = "../models/kr500.toml"',
                                     'model = "../models/kr500.toml"\nmodel_under_test = "../models/kr500.toml"'),
    "plugin module missing": _sub('plugin = "graph_theory_2021"', 'python = "no_such_module:make"'),
    "plugin entry point missing": _sub('plugin = "graph_theory_2021"', 'plugin = "no_such_plugin"'),
    "plugin named twice": _sub('plugin = "graph_theory_2021"', 'plugin = "graph_theory_2021"\npython = "m:f"'),
    "plugin name not an identifier": _sub('name = "graph"', 'name = "my model"'),
    "plugin named after an engine": _sub('name = "graph"', 'name = "mujoco"'),
    "unknown study": _append("\n[studies.no_such_study]\n"),
    "friction law without a log": _append("\n[friction_law]\nchoose = true\n"),
    "unknown study key": _sub("[studies.graph_theory_2021]\n", "[studies.graph_theory_2021]\ncolour = 1\n"),
    "paper table climbing out": _sub('"kr500_table3_identified_by_paper.csv"', '"../../../../etc/passwd"'),
    "paper table missing": _sub('"kr500_table3_identified_by_paper.csv"', '"table9.csv"'),
    "multiplier time off the grid": _sub("time = 1.5", "time = 1.505"),
    "validation scenario missing": _append('\n[torque_identification]\nvalidation = "nowhere.toml"\n'),
    "excitation and motion": _append('\n[excitation]\nbase_frequency = 1.0\n'),
    "unknown integrator": _sub('integrator = "RK4"', 'integrator = "RK45"'),
    "exponential overflow": _sub('[motion.O3]\ntype = "locked"',
                                 '[motion.O3]\ntype = "exponential"\namplitude = 1.0\nrate = 1000.0'),
    "unknown measurement key": _append("\n[measurement]\nprecision = 3\n"),
    "output steps beyond memory": _sub("output_steps = 100", "output_steps = 1000000000"),
    "timestep of 1e-300": _sub("timestep = 0.0005", "timestep = 1e-300"),
    "duration of 1e308": _sub("duration = 2.0", "duration = 1e308"),
    "too few sample times": _sub("sample_times = [0.3, 0.6, 0.9, 1.2, 1.5]", "sample_times = [0.3]"),
    "filter window beyond the recording": _append("\n[measurement]\ndifferentiate = true\nfilter_window = 301\n"),
    "relative noise on angles": _append("\n[measurement.noise.angles]\nrelative = 0.01\n"),
    "nested too deeply": _append("\nx = " + "[" * 3000 + "]" * 3000 + "\n"),
    "not UTF-8": lambda t: t + "\n# \udcff\n",
}


def _kr500_inputs(tmp_path: Path, model_edit=None, scenario_edit=None) -> list[str]:
    (tmp_path / "models").mkdir()
    (tmp_path / "scenarios").mkdir()
    copy_gate_sets(tmp_path / "scenarios")
    model = (MODELS / "kr500.toml").read_text()
    (tmp_path / "models" / "kr500.toml").write_text(model_edit(model) if model_edit else model)
    text = (SCENARIOS / "kr500_rail.toml").read_text()
    text = scenario_edit(text) if scenario_edit else text
    path = tmp_path / "scenarios" / "kr500_rail.toml"
    path.write_bytes(text.encode("utf-8", errors="surrogateescape"))
    return ["run", str(path), "--out", str(tmp_path / "out"), "--quiet"]


def _urdf_inputs(tmp_path: Path, case: str) -> list[str]:
    (old, new), _ = BAD_URDFS[case]
    (tmp_path / "arm.urdf").write_text(EXAMPLE_URDF.read_text().replace(old, new, 1))
    (tmp_path / "arm.toml").write_text('[urdf]\nfile = "arm.urdf"\n')
    (tmp_path / "s.toml").write_text('[scenario]\nmodel = "arm.toml"\nduration = 1.0\noutput_steps = 10\n'
                                     '[motion.shoulder]\ntype = "locked"\n[motion.elbow]\ntype = "locked"\n'
                                     '[[gates]]\nmetric = "torques.pinocchio_vs_mujoco.max_rel_error"\nlimit = 1e-9\n')
    return ["run", str(tmp_path / "s.toml"), "--out", str(tmp_path / "out")]


RESULT_EDITS = {
    "results not JSON": lambda r: "{not json",
    "results nested too deeply": lambda r: "[" * 100000 + "]" * 100000,
    "schema not an object": lambda r: {**r, "schema": [1]},
    "schema of another tool": lambda r: {**r, "schema": {"name": "other"}},
    "no gates": lambda r: {k: v for k, v in r.items() if k != "gates"},
    "gate direction misspelt": lambda r: {**r, "gates": [{**r["gates"][0], "direction": "atleast"}]},
    "gate limit null": lambda r: {**r, "gates": [{**r["gates"][0], "limit": None}]},
    "gate row a string": lambda r: {**r, "gates": ["a gate"]},
    "gate metric names nothing": lambda r: {**r, "gates": [{**r["gates"][0], "metric": "torques.none"}]},
    "recording section missing": lambda r: {k: v for k, v in r.items() if k != "recording"},
}


@pytest.fixture(scope="module")
def results_file(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("catalogue") / "run"
    assert main(["run", str(SCENARIOS / "kr500_rail_7digits.toml"), "--out", str(out), "--quiet"]) == 0
    return out / "results.json"


def _results_inputs(tmp_path: Path, case: str, results_file: Path) -> list[str]:
    edited = RESULT_EDITS[case](json.loads(results_file.read_text()))
    path = tmp_path / "results.json"
    path.write_text(edited if isinstance(edited, str) else json.dumps(edited))
    return ["gate", str(path)]


CLI_CASES = {
    "unknown command": ["fly"],
    "unknown flag": ["run", "--fast"],
    "trials as a float": ["sweep", "kr500_noise", "--trials", "1e12"],
    "trials beyond memory": ["sweep", str(SCENARIOS / "kr500_noise.toml"), "--trials", "1000000000000"],
    "one trial": ["sweep", str(SCENARIOS / "kr500_noise.toml"), "--trials", "1"],
    "no process": ["sweep", str(SCENARIOS / "kr500_noise.toml"), "--jobs", "0"],
    "jobs without bound": ["sweep", str(SCENARIOS / "kr500_noise.toml"), "--jobs", "100000"],
    "dask beside forked processes": ["sweep", str(SCENARIOS / "kr500_noise.toml"), "--dask", "--jobs", "2"],
    "dask address empty": ["sweep", str(SCENARIOS / "kr500_noise.toml"), "--dask", " "],
    "dask address without a port": ["sweep", str(SCENARIOS / "kr500_noise.toml"), "--trials", "2", "--dask", "nowhere"],
    "sweep of an ideal measurement": ["sweep", str(SCENARIOS / "kr500_rail.toml")],
    "run on no process": ["run", str(SCENARIOS / "kr500_rail.toml"), "--jobs", "0"],
    "run on dask beside forked processes": ["run", str(SCENARIOS / "kr500_rail.toml"), "--dask", "--jobs", "2"],
    "run on a dask address without a port": ["run", str(SCENARIOS / "kr500_rail.toml"), "--dask", "nowhere"],
    "scenario that does not exist": ["run", "no_such_scenario"],
    "results that do not exist": ["report", "no_such_results.json"],
}

CASES = ([("model", k) for k in MODEL_EDITS] + [("scenario", k) for k in SCENARIO_EDITS]
         + [("urdf", k) for k in BAD_URDFS] + [("results", k) for k in RESULT_EDITS]
         + [("cli", k) for k in CLI_CASES])


def test_the_catalogue_holds_at_least_60_bad_inputs():
    assert len(CASES) >= 60


@pytest.mark.parametrize(("kind", "case"), CASES, ids=[f"{k}: {c}" for k, c in CASES])
def test_bad_input_is_one_line_exit_2_and_nothing_written(tmp_path, monkeypatch, capsys, results_file, kind, case):
    monkeypatch.chdir(tmp_path)
    work = tmp_path / "work"
    work.mkdir()
    if kind == "model":
        argv = _kr500_inputs(work, model_edit=MODEL_EDITS[case])
    elif kind == "scenario":
        argv = _kr500_inputs(work, scenario_edit=SCENARIO_EDITS[case])
    elif kind == "urdf":
        argv = _urdf_inputs(work, case)
    elif kind == "results":
        argv = _results_inputs(work, case, results_file)
    else:
        argv = CLI_CASES[case]
    before = set(work.rglob("*"))
    try:
        code = main(argv)
    except SystemExit as exit_:  # argparse's refusals
        code = exit_.code
    err = capsys.readouterr().err
    assert code == 2, (code, err)
    assert err.count("\n") == 1 and err.startswith("harness: error: ") and "Traceback" not in err, err
    assert set(work.rglob("*")) == before  # nothing written, not even a temporary folder
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()
