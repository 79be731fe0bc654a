"""Inputs nobody chose: an arm at rest, no forces at all, too few samples, files nested too deeply
or cut short, a wrong D. Each ends in a verdict (exit 0 or 1) or in one line and exit 2, never in
a traceback."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from harness.cli import main
from tests.conftest import MODELS, SCENARIOS, copy_gate_sets


def _kr500(tmp_path: Path, edit) -> Path:
    (tmp_path / "models").mkdir(exist_ok=True)
    (tmp_path / "scenarios").mkdir(exist_ok=True)
    copy_gate_sets(tmp_path / "scenarios")
    shutil.copy(MODELS / "kr500.toml", tmp_path / "models" / "kr500.toml")
    path = tmp_path / "scenarios" / "s.toml"
    path.write_text(edit((SCENARIOS / "kr500_rail.toml").read_text()))
    return path


def _at_rest(text: str) -> str:
    return (text.replace('type = "constant_acceleration"\nacceleration = 2.0', 'type = "locked"')
            .replace('type = "constant_acceleration"\nacceleration = 9.5493', 'type = "locked"'))


def test_kr500_at_rest_is_judged_not_crashed(tmp_path, capsys):
    """At rest B1's Cardano angles sit in gimbal lock on every row (beta = -pi/2): Eq. 111 has no
    row to solve and nothing is identifiable. Those gates fail with no value; everything that can
    be evaluated agrees at round-off."""
    out = tmp_path / "out"
    assert main(["run", str(_kr500(tmp_path, _at_rest)), "--out", str(out), "--quiet"]) == 1
    gates = {g["metric"]: g for g in json.loads((out / "results.json").read_text())["gates"]}
    failing = {m for m, g in gates.items() if not g["passed"]}
    assert failing == {"lagrange.formulations.normal.acceleration_check_max_rel_error",
                       "lagrange.formulations.normal.reaction_check_max_rel_error",
                       "identification.not_identifiable_count"}
    assert gates["lagrange.formulations.normal.acceleration_check_max_rel_error"]["value"] is None
    assert gates["graph.unconstrained_residual.max_rotational"]["value"] < 1e-12


def test_a_metric_that_is_not_a_number_is_written_as_null_and_its_gate_fails(tmp_path, capsys):
    """No gravity and no motion: every torque and every joint load is zero, so their relative
    errors are 0/0. results.json stays valid JSON, says where, and the gates fail closed."""
    def still(text):
        return _at_rest(text).replace("gravity = [0.0, 0.0, -9.80665]", "gravity = [0.0, 0.0, 0.0]")

    out = tmp_path / "out"
    assert main(["run", str(_kr500(tmp_path, still)), "--out", str(out), "--quiet"]) == 1
    results = json.loads((out / "results.json").read_text())
    assert "torques.pinocchio_vs_mujoco.max_rel_error" in results["run"]["not_finite"]
    row = next(g for g in results["gates"] if g["metric"] == "torques.pinocchio_vs_mujoco.max_rel_error")
    assert row["value"] is None and not row["passed"]


@pytest.mark.parametrize("times", ["[]", "[0.3]"])
def test_too_few_sample_times_for_the_identification_are_bad_input(tmp_path, capsys, times):
    path = _kr500(tmp_path, lambda t: t.replace("sample_times = [0.3, 0.6, 0.9, 1.2, 1.5]", f"sample_times = {times}"))
    assert main(["run", str(path), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "scenario.sample_times" in err and "at least 2" in err
    assert not (tmp_path / "out").exists()


def test_a_sign_flipped_in_D_fails_a_gate(tmp_path, monkeypatch, capsys):
    """D cancels from Eq. 36 and Eq. 111; the check against a rotation library sees it."""
    import harness.papers.graph_theory_2021.dynamics as dynamics

    original = dynamics.D

    def flipped(theta):
        out = original(theta).copy()
        out[..., 0, 1] *= -1
        return out

    monkeypatch.setattr(dynamics, "D", flipped)
    assert main(["run", str(SCENARIOS / "kr500_rail.toml"), "--out", str(tmp_path / "out"), "--quiet"]) == 1
    assert "FAIL  Cardano D (Eq. 33) agrees with a rotation library" in capsys.readouterr().out


def test_files_nested_too_deeply_are_bad_input(tmp_path, capsys):
    deep_toml = tmp_path / "deep.toml"
    deep_toml.write_text("a = " + "[" * 5000 + "]" * 5000 + "\n")
    deep_json = tmp_path / "deep.json"
    deep_json.write_text("[" * 100000 + "]" * 100000)
    assert main(["run", str(deep_toml)]) == 2
    assert main(["gate", str(deep_json)]) == 2
    err = capsys.readouterr().err.splitlines()
    assert err == [f"harness: error: {deep_toml}: invalid TOML: nested too deeply",
                   f"harness: error: {deep_json}: invalid JSON: nested too deeply"]


@pytest.fixture(scope="module")
def written(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("written") / "run"
    assert main(["run", str(SCENARIOS / "kr500_rail_7digits.toml"), "--out", str(out), "--quiet"]) == 0
    return out


@pytest.mark.parametrize(("damage", "phrase"), [
    (lambda text: text[: len(text) // 2], "truncated or edited recording"),
    (lambda text: "\n".join(text.splitlines()[:40]) + "\n", "rows of joints"),
    (lambda text: text.replace("B1_az", "B1_zz", 1), "column missing"),
    # no body's orientation at all (another layout, as an earlier version wrote it): refused, not a crash
    (lambda text: text.replace("_R11,", "_alpha,"), "column missing"),
])
def test_report_refuses_a_recording_that_is_cut_short_or_edited(written, tmp_path, capsys, damage, phrase):
    for f in ("results.json", "recording.csv"):
        shutil.copy(written / f, tmp_path / f)
    (tmp_path / "recording.csv").write_text(damage((written / "recording.csv").read_text()))
    assert main(["report", str(tmp_path / "results.json")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and phrase in err, err
    assert not (tmp_path / "report.html").exists()


def test_report_reads_its_recording_only_beside_results_json(written, tmp_path, capsys):
    results = json.loads((written / "results.json").read_text())
    results["recording"]["file"] = "../../etc/passwd"
    (tmp_path / "results.json").write_text(json.dumps(results))
    assert main(["report", str(tmp_path / "results.json")]) == 2
    assert "recording.file: must name a file beside results.json" in capsys.readouterr().err


@pytest.mark.parametrize(("edit", "key"), [
    (lambda t: t.replace("output_steps = 100", "output_steps = 1000000000"), "scenario.output_steps"),
    (lambda t: t.replace("output_steps = 100", "output_steps = " + "9" * 400), "scenario.output_steps"),
    (lambda t: t.replace("timestep = 0.0005", "timestep = 1e-300"), "simulation.timestep"),
    (lambda t: t.replace("duration = 2.0", "duration = 1e12"), "simulation.timestep"),
    (lambda t: t.replace("duration = 2.0", "duration = 1e308"), "scenario.duration"),
])
def test_what_cannot_fit_is_refused_before_anything_is_allocated(tmp_path, capsys, edit, key):
    assert main(["run", str(_kr500(tmp_path, edit)), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and key in err and ("at most" in err or "beyond" in err), err


@pytest.mark.parametrize("argv", [["sweep", "kr500_noise", "--trials", "1e12"],
                                  ["sweep", str(SCENARIOS / "kr500_noise.toml"), "--trials", "1000000000000"],
                                  ["sweep", str(SCENARIOS / "kr500_noise.toml"), "--jobs", "100000"],
                                  ["run", "--no-such-flag"], ["no-such-command"]])
def test_command_line_mistakes_are_one_line_and_exit_2(capsys, argv):
    try:
        code = main(argv)
    except SystemExit as exit_:  # argparse's own refusals
        code = exit_.code
    assert code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("harness: error: "), err


@pytest.mark.slow  # four robots, 3 to 10 s each
@pytest.mark.parametrize("robot", ["kinova", "solo12", "bolt", "double_pendulum"])
def test_robots_of_example_robot_data_run_from_two_line_model_files(tmp_path, capsys, robot):
    """No crash: a verdict. Kinova keeps its models in */robots/, as Solo12 and Bolt do; Bolt's feet
    are massless links with inertia. The double pendulum's links sit in Cardano gimbal lock, so
    there Eq. 111's gates fail with no value; everything else passes."""
    from harness.model.load import load_spec

    (tmp_path / f"{robot}.toml").write_text(f'[urdf]\nrobot = "{robot}"\n')
    copy_gate_sets(tmp_path)
    spec = load_spec(tmp_path / f"{robot}.toml")
    motion = "".join(f'\n[motion.{j}]\ntype = "sinusoids"\nsin = [[0.3, {1.1 + 0.3 * k}]]\n'
                     for k, j in enumerate(spec.joint_names))
    (tmp_path / "s.toml").write_text(
        f'[scenario]\nmodel = "{robot}.toml"\nduration = 0.4\noutput_steps = 20\nsample_times = "all"\n'
        'gate_sets = ["gates/engines.toml", "gates/graph_theory_2021.toml"]\n\n'
        '[model_under_test]\nname = "graph"\nplugin = "graph_theory_2021"\n\n[studies.graph_theory_2021]\n' + motion)
    out = tmp_path / "out"
    code = main(["run", str(tmp_path / "s.toml"), "--out", str(out), "--quiet"])
    gates = json.loads((out / "results.json").read_text())["gates"]
    failing = {g["metric"] for g in gates if not g["passed"]}
    if robot == "double_pendulum":
        assert code == 1 and failing == {"lagrange.formulations.normal.acceleration_check_max_rel_error",
                                         "lagrange.formulations.normal.reaction_check_max_rel_error"}
    else:
        assert code == 0 and not failing
