"""A verdict CI can stake a release on: only the harness chooses its exit status, whatever plugin
code does; the CI files are written on every outcome; a failing gate says where; nothing is judged
by no gate; bad input of every kind ends in one line and exit 2. The hostile plugins here are
written by the tests into temporary folders."""

from __future__ import annotations

import json
import os
import re
import shlex
import shutil
import subprocess
import sys
import textwrap
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

import harness
from harness.base.builtin import DATA
from harness.cli import main
from harness.init import project
from harness.runner.gates import summary_line

HARNESS = Path(sys.executable).parent / "harness"  # the console script, as CI runs it


@pytest.fixture(scope="module")
def example(tmp_path_factory) -> Path:
    """The project `harness init` writes, in a folder of its own (read, never changed, by the tests)."""
    folder = tmp_path_factory.mktemp("example")
    for name, text in project().items():
        (folder / name).write_text(text)
    return folder


def _project(tmp_path: Path, plugin: str, extra: str = "", seconds: float = 0.5) -> Path:
    """The `harness init` project with its model under test replaced by `plugin` (module hostile.py), its
    two trajectories `seconds` long (what these tests judge is the verdict, not the motion's length)."""
    assert main(["init", str(tmp_path / "p")]) == 0
    folder = tmp_path / "p"
    for name in ("scenario.toml", "validation.toml"):
        text = (folder / name).read_text()
        assert "duration = 2.0\noutput_steps = 200\n" in text
        (folder / name).write_text(text.replace("duration = 2.0\noutput_steps = 200\n",
                                                f"duration = {seconds}\noutput_steps = {round(100 * seconds)}\n"))
    (folder / "hostile.py").write_text(textwrap.dedent(plugin))
    text = (folder / "scenario.toml").read_text().replace('python = "my_robot:make_model"',
                                                         'python = "hostile:make"')
    (folder / "scenario.toml").write_text(text + extra)
    return folder / "scenario.toml"


EXACT = """
import sys
sys.path.insert(0, __file__.rsplit("/", 1)[0])
from my_robot import TwoLinkArm
"""


@pytest.mark.parametrize("body", [
    EXACT + "sys.exit(0)\ndef make(robot, gravity_W, parameters): return TwoLinkArm(gravity_W)\n",
    EXACT + "class M(TwoLinkArm):\n    def inverse_dynamics(self, q, qd, qdd): raise SystemExit(0)\n"
            "def make(robot, gravity_W, parameters): return M(gravity_W)\n",
    EXACT + "class M(TwoLinkArm):\n    def inverse_dynamics(self, q, qd, qdd): raise KeyboardInterrupt\n"
            "def make(robot, gravity_W, parameters): return M(gravity_W)\n",
    EXACT + "class M(TwoLinkArm):\n    @property\n    def joint_names(self): sys.exit(0)\n"
            "def make(robot, gravity_W, parameters): return M(gravity_W)\n",
], ids=["sys.exit at import", "SystemExit in inverse_dynamics", "KeyboardInterrupt it raises",
        "sys.exit in a property"])
def test_a_plugin_that_exits_or_interrupts_is_bad_input_with_an_error_in_the_junit_file(tmp_path, capsys, body):
    path = _project(tmp_path, body)
    junit, summary = tmp_path / "junit.xml", tmp_path / "summary.md"
    status = main(["run", str(path), "--out", str(tmp_path / "out"), "--quiet", "--junit-xml", str(junit),
                   "--summary", str(summary)])
    err = capsys.readouterr().err
    assert status == 2 and err.count("\n") == 1 and "hostile:make" in err, err
    assert not (tmp_path / "out").exists()
    case = ET.parse(junit).getroot().find("./testsuite/testcase")
    assert case.find("error") is not None and "hostile:make" in case.find("error").get("message")
    assert "ERROR (bad input)" in summary.read_text()


def test_a_plugin_that_ends_the_process_is_an_internal_error_and_the_junit_file_says_so(tmp_path):
    """os._exit cannot be caught in the process that calls it: the command runs in a child and the
    `harness` process chooses the status."""
    path = _project(tmp_path, EXACT + "import os\nclass M(TwoLinkArm):\n"
                                      "    def inverse_dynamics(self, q, qd, qdd): os._exit(0)\n"
                                      "def make(robot, gravity_W, parameters): return M(gravity_W)\n")
    junit = tmp_path / "junit.xml"
    done = subprocess.run([str(HARNESS), "run", str(path), "--out", str(tmp_path / "out"), "--quiet",
                           "--junit-xml", str(junit)], capture_output=True, text=True, timeout=120)
    assert done.returncode == 3, done.stderr
    assert "ended without a verdict (exit status 0)" in done.stderr and done.stderr.count("\n") == 1
    assert ET.parse(junit).getroot().find("./testsuite/testcase/error") is not None


def test_an_internal_error_writes_an_error_case_too(example, tmp_path, capsys, monkeypatch):
    import harness.stages.torques

    def broken(*args, **kwargs):
        raise ZeroDivisionError("a bug")

    monkeypatch.setattr(harness.stages.torques, "joint_load_scale", broken)
    junit = tmp_path / "junit.xml"
    assert main(["run", str(example / "scenario.toml"), "--out", str(tmp_path / "o"), "--quiet",
                 "--junit-xml", str(junit)]) == 3
    error = ET.parse(junit).getroot().find("./testsuite/testcase/error")
    assert error.get("type") == "InternalError" and "ZeroDivisionError: a bug" in error.get("message")


def test_the_summary_line_counts_the_failing_gates_in_the_same_words_everywhere(tmp_path, capsys):
    rows = [{"passed": False}] * 5 + [{"passed": True}]
    assert summary_line("arm", rows) == "arm: FAILED (5 of 6 gates fail)"
    assert summary_line("arm", [{"passed": True}] * 2) == "arm: PASSED (2 gates)"
    path = _project(tmp_path, EXACT + "def make(robot, gravity_W, parameters): return TwoLinkArm(gravity_W, m2=1.26)\n")
    summary = tmp_path / "s.md"
    capsys.readouterr()
    assert main(["run", str(path), "--out", str(tmp_path / "out"), "--quiet", "--summary", str(summary)]) == 1
    out = capsys.readouterr().out
    line = "scenario: FAILED (4 of 6 gates fail)"  # the model's four gates; the method's two pass
    assert out.splitlines()[0] == line and f"### {line}" in summary.read_text()
    assert line in (tmp_path / "out" / "report.html").read_text()


def test_a_failing_gate_names_the_worst_joint_and_time_or_parameter(example, tmp_path, capsys):
    path = _project(tmp_path, EXACT + "def make(robot, gravity_W, parameters): return TwoLinkArm(gravity_W, m2=1.26)\n")
    capsys.readouterr()
    assert main(["run", str(path), "--out", str(tmp_path / "out"), "--quiet"]) == 1
    out = capsys.readouterr().out
    results = json.loads((tmp_path / "out" / "results.json").read_text())
    worst = results["torques"]["mine_vs_mujoco"]
    assert (f"FAIL  torques.mine_vs_mujoco.max_rel_error = {worst['max_rel_error']:.3g} > 1e-09 (worst: "
            f"{worst['max_rel_joint']} at t = {worst['max_rel_t']:.4g} s)") in out
    assert "(worst: elbow at random state" in out
    # an identification gate names the base parameter: the method is judged against a 5 % lighter truth
    (path.parent / "robot.urdf").write_text((path.parent / "robot.urdf").read_text().replace(
        '<mass value="1.2"/>', '<mass value="1.14"/>'))
    (path.parent / "my_robot.py").write_text((path.parent / "my_robot.py").read_text().replace(
        'return LeastSquares(Path(__file__).parent / parameters.get("urdf", "robot.urdf"), gravity_W)',
        'return LeastSquares(Path(__file__).parent / "true.urdf", gravity_W)'))
    (path.parent / "true.urdf").write_text((example / "robot.urdf").read_text())
    capsys.readouterr()
    main(["run", str(path), "--out", str(tmp_path / "out2"), "--quiet"])
    gate = next(r for r in json.loads((tmp_path / "out2" / "results.json").read_text())["gates"]
                if r["metric"] == "identification_methods.ls.validation.max_rel_error")
    assert gate["where"].startswith(("shoulder at t =", "elbow at t ="))


def test_a_model_or_method_that_no_gate_judges_is_refused(example, tmp_path, capsys):
    path = example / "scenario.toml"
    text = path.read_text()
    for metric, kind in (("mine_", "mine"), ("identification_methods.ls.", "ls")):
        blocks = text.split("[[gates]]")
        kept = "[[gates]]".join(b for b in blocks if metric not in b)
        (tmp_path / "robot.toml").write_text((example / "robot.toml").read_text())
        for f in ("robot.urdf", "my_robot.py", "validation.toml"):
            (tmp_path / f).write_text((example / f).read_text())
        (tmp_path / "s.toml").write_text(kept)
        assert main(["run", str(tmp_path / "s.toml"), "--out", str(tmp_path / "out"), "--quiet"]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and f"{kind!r} is judged by no gate" in err and metric in err


def test_a_broken_pipe_is_not_a_verdict():
    done = subprocess.run(f"'{HARNESS}' list | head -1; exit ${{PIPESTATUS[0]}}", shell=True, executable="/bin/bash",
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and done.stdout.count("\n") == 1, (done.returncode, done.stderr)


def test_a_motion_that_diverges_is_bad_input_in_one_line(tmp_path, capsys, caplog):
    path = _project(tmp_path, EXACT + "def make(robot, gravity_W, parameters): return TwoLinkArm(gravity_W)\n")
    path.write_text(path.read_text().replace("sin = [[0.9, 2.1]]", "sin = [[1e4, 400.0]]"))
    assert main(["run", str(path), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "motion." in err and "non-finite values at t = " in err
    assert len([r for r in caplog.records if r.name == "harness.mujoco"]) <= 1


def test_a_motion_beyond_the_limits_warns_and_is_gateable(tmp_path, capsys, caplog):
    path = _project(tmp_path, EXACT + "def make(robot, gravity_W, parameters): return TwoLinkArm(gravity_W)\n",
                    '\n[[gates]]\nmetric = "motion.largest.position"\nlimit = 1.0\n', seconds=2.0)
    path.write_text(path.read_text().replace("sin = [[0.9, 2.1]]", "sin = [[60.0, 2.1]]"))
    assert main(["run", str(path), "--out", str(tmp_path / "out"), "--quiet"]) == 1
    warned = [r.getMessage() for r in caplog.records if "beyond the model's limits" in r.getMessage()]
    assert len(warned) == 1 and "shoulder position" in warned[0]
    limits = json.loads((tmp_path / "out" / "results.json").read_text())["motion"]["limits"]
    # the URDF's shoulder range is +-3.1 rad about 0; q = -0.3 + 60 sin(2.1 t) on the 201 recorded rows (the
    # drive tracks it within 1e-9 rad)
    t = np.linspace(0.0, 2.0, 201)
    assert limits["shoulder"]["position"] == pytest.approx(np.max(np.abs(-0.3 + 60 * np.sin(2.1 * t))) / 3.1, rel=1e-9)


def test_the_built_in_scenario_passes_within_its_limits(example, tmp_path):
    assert main(["run", str(example / "scenario.toml"), "--out", str(tmp_path / "o"), "--quiet"]) == 0
    motion = json.loads((tmp_path / "o" / "results.json").read_text())["motion"]
    assert motion["beyond"] == [] and max(motion["largest"].values()) <= 1.0


@pytest.mark.skipif(not Path("/dev/zero").exists(), reason="no /dev/zero")
def test_inputs_that_were_internal_errors_are_refused_in_one_line(example, tmp_path, capsys):
    assert main(["run", "/dev/zero"]) == 2
    assert "larger than 16 MiB" in capsys.readouterr().err
    blocker = tmp_path / "file"
    blocker.write_text("")
    assert main(["run", str(example / "scenario.toml"), "--out", str(tmp_path / "o"), "--quiet"]) == 0
    capsys.readouterr()
    assert main(["report", str(tmp_path / "o" / "results.json"), "--out", str(blocker / "report.html")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--out" in err
    (tmp_path / "models").mkdir()
    (tmp_path / "models" / "odd.toml").write_text('model = "a string"\n')
    cwd = os.getcwd()
    try:
        os.chdir(tmp_path)
        assert main(["list"]) == 0
    finally:
        os.chdir(cwd)
    assert "odd" in capsys.readouterr().out


@pytest.mark.slow  # a few seconds: a whole pipeline or a subprocess
def test_built_in_scenarios_run_from_any_folder(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["list"]) == 0
    assert "kr500_rail" in capsys.readouterr().out
    assert main(["run", "planar6_case1_proposed", "--out", "o", "--quiet"]) == 0
    assert json.loads((tmp_path / "o" / "results.json").read_text())["passed"]
    # a file of the same name in the current folder comes first
    (tmp_path / "planar6_case1_proposed.toml").write_text("not toml [")
    assert main(["run", "planar6_case1_proposed", "--out", "o2", "--quiet"]) == 2


@pytest.mark.slow  # a few seconds: a whole pipeline or a subprocess
def test_init_writes_a_project_that_passes_out_of_the_box(tmp_path, capsys):
    assert main(["init", str(tmp_path / "p")]) == 0
    assert main(["init", str(tmp_path / "p")]) == 2  # never over an existing project
    names = sorted(p.name for p in (tmp_path / "p").iterdir())
    assert names == ["README.md", "ci-job.yml", "my_robot.py", "robot.toml", "robot.urdf", "scenario.toml",
                     "test_my_robot.py", "validation.toml"]
    assert harness.DISTRIBUTION in (tmp_path / "p" / "ci-job.yml").read_text()
    done = subprocess.run([str(HARNESS), "run", "scenario.toml", "--out", "reports", "--quiet"],
                          cwd=tmp_path / "p", capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    # the CI job's comparison, its command as written, with this run as its own baseline: nothing worse
    shutil.copytree(tmp_path / "p" / "reports", tmp_path / "p" / "baseline")
    command = re.search(r"harness compare [^|\n]*", (tmp_path / "p" / "ci-job.yml").read_text()).group(0)
    done = subprocess.run([str(HARNESS), *shlex.split(command)[1:]], cwd=tmp_path / "p", capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 0 and "NOT WORSE" in done.stdout, done.stdout + done.stderr
    assert "NOT WORSE" in (tmp_path / "p" / "reports" / "compare.md").read_text()
    done = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider"], cwd=tmp_path / "p",
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0 and "1 passed" in done.stdout, done.stdout + done.stderr


def test_the_api_judges_a_model_object_and_a_scenario_given_as_a_dict(example, tmp_path):
    sys.path.insert(0, str(example))
    try:
        from my_robot import TwoLinkArm
    finally:
        sys.path.remove(str(example))
    g = np.array([0.0, 0.0, -9.80665])
    scenario = {"scenario": {"model": "robot.toml", "duration": 1.0, "output_steps": 50},
                "motion": {"shoulder": {"type": "sinusoids", "sin": [[0.5, 2.0]]}, "elbow": {"type": "locked"}},
                "gates": [{"metric": "torques.pinocchio_vs_mujoco.max_rel_error", "limit": 1e-9}]}
    good = harness.run(scenario, folder=example, models={"exact": TwoLinkArm(g)})
    assert good.passed and {g.metric for g in good.gates} >= {"torques.exact_random_vs_pinocchio.max_rel_error"}
    bad = harness.run(scenario, folder=example, model=TwoLinkArm(g, m2=1.26))
    assert {g.metric for g in bad.failed} == {f"torques.model_{k}.max_rel_error"
                                              for k in ("vs_mujoco", "vs_pinocchio", "random_vs_pinocchio")}
    with pytest.raises(harness.InputError, match=r"motion\.elbow: missing"):
        harness.load_scenario({**scenario, "motion": {"shoulder": {"type": "locked"}}}, folder=example)


def test_random_states_find_an_error_the_scripted_motion_hides(tmp_path, capsys):
    """A model wrong only where the elbow bends beyond 2 rad, which the scripted motion never reaches."""
    path = _project(tmp_path, EXACT + textwrap.dedent("""
        import numpy as np
        class M(TwoLinkArm):
            def inverse_dynamics(self, q, qd, qdd):
                tau = super().inverse_dynamics(q, qd, qdd)
                return tau + np.where(q[:, 1:2] > 2.0, 0.01, 0.0)
        def make(robot, gravity_W, parameters): return M(gravity_W)
        """))
    assert main(["run", str(path), "--out", str(tmp_path / "out"), "--quiet"]) == 1
    gates = {g["metric"]: g for g in json.loads((tmp_path / "out" / "results.json").read_text())["gates"]}
    assert gates["torques.mine_vs_mujoco.max_rel_error"]["passed"]
    random = gates["torques.mine_random_vs_pinocchio.max_rel_error"]
    assert not random["passed"] and random["where"].startswith("elbow at random state")


def test_a_methods_parameters_come_back_as_a_base_parameter_table_with_intervals(example):
    result = harness.run(example / "scenario.toml")
    table = result.results["identification_methods"]["ls"]["base_parameters"]
    # the planar 2R arm has 6 base parameters; each names the standard parameters it combines
    assert table["count"] == 6 and len(table["base"]) == 6
    assert all(p["expression"].startswith(("shoulder.", "elbow.")) for p in table["base"])
    assert all(abs(p["identified"] - p["true"]) <= 1e-9 * max(abs(p["true"]), 1.0) for p in table["base"])
    assert all(p["std"] is not None and p["ci95"][0] <= p["identified"] <= p["ci95"][1] for p in table["base"])


NOISY = "\n[measurement]\nseed = 3\n[measurement.noise.joint_torques]\nrelative = 0.01\n"


def _sweep_json(folder: Path) -> dict:
    out = json.loads((folder / "sweep.json").read_text())
    out.pop("run")
    return out


@pytest.mark.slow  # a sweep run three ways (1.7 s)
def test_sweep_monte_carlos_a_users_method_the_same_wherever_the_trials_run(tmp_path, capsys):
    """The example method (least squares, 1 % torque noise, 100 trials): unbiased (every |bias| within 3
    standard errors of the mean over the trials, as least squares on a regressor of noise-free states
    must be), with intervals from its covariance; forked processes give the same file."""
    assert main(["init", str(tmp_path / "p")]) == 0
    path = tmp_path / "p" / "scenario.toml"
    path.write_text(path.read_text() + NOISY)
    assert main(["sweep", str(path), "--trials", "100", "--out", str(tmp_path / "one")]) == 0
    assert main(["sweep", str(path), "--trials", "100", "--out", str(tmp_path / "two"), "--jobs", "2"]) == 0
    one = _sweep_json(tmp_path / "one")
    assert one == _sweep_json(tmp_path / "two")
    b = one["identification_methods"]["ls"]["base_parameters"]
    assert b["count"] == 6 and b["significant_biases"] == 0 and len(b["base"]) == 6
    assert 0.0 < b["coverage_min"] <= b["coverage_max"] <= 1.0
    assert "ls" in capsys.readouterr().out and "Identification methods under measurement noise" in (
        tmp_path / "one" / "sweep.html").read_text()


def test_a_method_that_exits_in_a_worker_process_is_bad_input(tmp_path, capsys):
    assert main(["init", str(tmp_path / "p")]) == 0
    folder = tmp_path / "p"
    (folder / "my_robot.py").write_text((folder / "my_robot.py").read_text().replace(
        "        W, y = self.regressor(q, qd, qdd), tau.reshape(-1)",
        "        if tau[0, 0] != tau[0, 0] + 0.0 or tau[3, 1] > 0 or tau[3, 1] <= 0:\n"
        "            raise SystemExit(0)\n"
        "        W, y = self.regressor(q, qd, qdd), tau.reshape(-1)"))
    (folder / "scenario.toml").write_text((folder / "scenario.toml").read_text() + NOISY)
    capsys.readouterr()
    assert main(["sweep", str(folder / "scenario.toml"), "--trials", "8", "--jobs", "2", "--out",
                 str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "my_robot:make_method" in err and "SystemExit" in err and not (tmp_path / "o").exists()


@pytest.mark.slow  # the run must last long enough to be interrupted
def test_ctrl_c_is_130_and_leaves_nothing_behind(tmp_path):
    import signal
    import time

    proc = subprocess.Popen([str(HARNESS), "run", "kr500_rail_forward", "--out", str(tmp_path / "o"), "--quiet",
                             "--junit-xml", str(tmp_path / "j.xml")], stderr=subprocess.PIPE, text=True)
    time.sleep(8)
    proc.send_signal(signal.SIGINT)  # to the harness process alone: it passes it on
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130 and "interrupted" in err
    assert list(tmp_path.iterdir()) == []  # no output folder, no temporary one


def test_the_readme_is_a_short_front_door_under_the_distributions_own_name():
    """The README stays under 300 lines, names the distribution of pyproject.toml (not `harness`,
    which an unrelated project holds on the package index), and every page it links exists."""
    import re
    import tomllib

    root = DATA.parents[1]
    readme = (root / "README.md").read_text()
    name = tomllib.loads((root / "pyproject.toml").read_text())["project"]["name"]
    assert readme.count("\n") < 300 and name != "harness" and name == harness.DISTRIBUTION
    assert f"pip install {name}" in readme
    links = re.findall(r"\]\(([^)#]+)\)", readme)
    assert links and all((root / link).is_file() for link in links)
    first = [line for line in readme.splitlines() if line.startswith("## ")][:2]
    assert first == ["## Set-up on a fresh machine (Python 3.11+)", "## Your own robot in five minutes"]


def test_a_plugin_that_changes_directory_does_not_move_the_output(tmp_path, monkeypatch):
    path = _project(tmp_path, EXACT + "import os\nos.chdir('/')\n"
                                      "def make(robot, gravity_W, parameters): return TwoLinkArm(gravity_W)\n")
    monkeypatch.chdir(tmp_path)
    assert main(["run", str(path), "--out", "out", "--quiet", "--junit-xml", "j.xml"]) == 0
    assert (tmp_path / "out" / "results.json").is_file() and (tmp_path / "j.xml").is_file()


@pytest.mark.slow  # starts a local Dask cluster
def test_a_users_method_swept_on_dask_gives_the_same_file(tmp_path):
    """On Dask the method is built again on each worker from the scenario (its module by path)."""
    assert main(["init", str(tmp_path / "p")]) == 0
    path = tmp_path / "p" / "scenario.toml"
    path.write_text(path.read_text() + NOISY)
    assert main(["sweep", str(path), "--trials", "24", "--out", str(tmp_path / "here")]) == 0
    assert main(["sweep", str(path), "--trials", "24", "--out", str(tmp_path / "dask"), "--dask"]) == 0
    assert _sweep_json(tmp_path / "here") == _sweep_json(tmp_path / "dask")


@pytest.mark.slow  # harness init and its project's run (1.8 s)
def test_init_from_a_urdf_whose_model_file_states_coupled_drives_passes_with_them(tmp_path):
    """`harness init --urdf` with the TX40's URDF, then its coupled drives and every motor's law written
    into the project's model file (harness/data/models/tx40.toml's transmission): the bench carries
    them (MuJoCo's tendons, Pinocchio's law), the placeholder model takes them as the harness reads
    them and its method fits what they leave, so every gate of the project passes: the torques at the
    motion's and at random states, the mass matrix, the base parameters and the validation."""
    import tomllib

    models = DATA / "models"
    urdf = models / tomllib.loads((models / "tx40.toml").read_text())["urdf"]["file"]
    assert main(["init", str(tmp_path / "p"), "--urdf", str(urdf.resolve())]) == 0
    folder = tmp_path / "p"
    drives = (models / "tx40.toml").read_text().split("[drives]", 1)[1]
    drives = drives.replace("coulomb_velocity = 0.64", "armature = 3.5e-4\nviscous = 7.9e-3\ncoulomb = 0.22\n"
                            "offset = 0.012\ncoulomb_velocity = 0.64")
    (folder / "robot.toml").write_text((folder / "robot.toml").read_text() + "\n[drives]" + drives)
    assert main(["run", str(folder / "scenario.toml"), "--out", str(tmp_path / "o"), "--quiet"]) == 0
    results = json.loads((tmp_path / "o" / "results.json").read_text())
    assert results["model"]["transmission"]["coupled"] == {"motor_6": ["joint_5", "joint_6"]}
    assert len(results["gates"]) == 6 and all(g["passed"] for g in results["gates"])


def test_init_from_a_urdf_moves_every_joint_within_its_limits_and_passes(tmp_path, capsys):
    """A robot nobody here wrote a scenario for (UR5 of example-robot-data, as shipped): every joint moves
    within its position and velocity limits, and the placeholder model and the method pass out of the box."""
    from harness.model.urdf import example_robot_data_path

    urdf = example_robot_data_path("ur5")
    assert main(["init", str(tmp_path / "p"), "--urdf", str(urdf)]) == 0
    folder = tmp_path / "p"
    assert main(["run", str(folder / "scenario.toml"), "--out", str(tmp_path / "o"), "--quiet"]) == 0
    results = json.loads((tmp_path / "o" / "results.json").read_text())
    assert set(results["scenario"]["motion"]) == {"shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint",
                                                 "wrist_1_joint", "wrist_2_joint", "wrist_3_joint"}
    largest = results["motion"]["largest"]
    assert largest["position"] <= 1 / 3 + 1e-9 and largest["velocity"] <= 0.5 + 1e-9
    assert main(["init", str(tmp_path / "q"), "--urdf", str(tmp_path / "nothing.urdf")]) == 2
    assert "nothing.urdf" in capsys.readouterr().err and not (tmp_path / "q").exists()


def test_init_reads_a_urdfs_mimic_joints_as_its_own_and_refuses_other_couplings(tmp_path, capsys):
    """The project moves every joint and runs a tree's model and method: a URDF's <mimic> joints are read
    as joints of their own there (`mimic = "independent"` in robot.toml, said at its head) and the project
    passes; an MJCF file's joint equalities (a closed chain of couplings) are refused in one line."""
    import tomllib

    from tests.conftest import MODELS, ROOT

    arm = ROOT / "examples" / "two_link_arm" / "two_link_arm.urdf"
    (tmp_path / "arm.urdf").write_text(arm.read_text().replace('<child link="fore"/>',
                                                               '<child link="fore"/><mimic joint="shoulder"/>'))
    assert main(["init", str(tmp_path / "p"), "--urdf", str(tmp_path / "arm.urdf")]) == 0
    robot = tomllib.loads((tmp_path / "p" / "robot.toml").read_text())
    assert robot["urdf"]["mimic"] == "independent"
    assert main(["run", str(tmp_path / "p" / "scenario.toml"), "--out", str(tmp_path / "o"), "--quiet"]) == 0
    assert set(json.loads((tmp_path / "o" / "results.json").read_text())["scenario"]["motion"]) == {"shoulder", "elbow"}
    capsys.readouterr()
    assert main(["init", str(tmp_path / "q"), "--mjcf", str(MODELS / "gripper.xml")]) == 2
    assert "a closed chain (loop 'fingers')" in capsys.readouterr().err and not (tmp_path / "q").exists()


@pytest.mark.parametrize("flag", ["--mjcf", pytest.param("--urdf", marks=pytest.mark.slow),
                                  pytest.param("--robot", marks=pytest.mark.slow)])  # each an init and a run: 1 s
def test_init_from_an_mjcf_file_passes_with_its_armature_damping_and_frictionloss(tmp_path, capsys, flag):
    """An MJCF arm written as MJCF files are (tests/test_mjcf.py's: defaults, degrees, a joint `ref`, a
    slide, armature, damping, frictionloss, a geared motor, gravity of its own), started with any of the
    three flags (the format told by the root element): the project's model file reads the MJCF, the
    placeholder model is Pinocchio's MJCF parser, the method takes the armature as known, and all six
    gates pass. A file that is neither is refused in one line naming it and the flag."""
    from tests.test_mjcf import ARM

    (tmp_path / "arm.xml").write_text(ARM)
    assert main(["init", str(tmp_path / "p"), flag, str(tmp_path / "arm.xml")]) == 0
    folder = tmp_path / "p"
    assert (folder / "robot.xml").read_text() == ARM and "[mjcf]" in (folder / "robot.toml").read_text()
    assert main(["run", str(folder / "scenario.toml"), "--out", str(tmp_path / "o"), "--quiet"]) == 0
    results = json.loads((tmp_path / "o" / "results.json").read_text())
    assert len(results["gates"]) == 6 and all(g["passed"] for g in results["gates"])
    (tmp_path / "other.xml").write_text("<sdf version='1.6'/>")
    assert main(["init", str(tmp_path / "q"), flag, str(tmp_path / "other.xml")]) == 2
    err = capsys.readouterr().err.strip()
    assert "other.xml" in err and flag in err and "<sdf>" in err and "\n" not in err and not (tmp_path / "q").exists()


@pytest.mark.slow  # harness init and its project's run (1.3 s)
def test_init_from_an_mjcf_file_with_a_floating_base_fixes_it_where_the_harness_does(tmp_path):
    """The same arm on a free joint: the harness fixes the base where the file puts it, and so does the
    placeholder (Pinocchio's MJCF parser builds the free joint; it is locked at MuJoCo's qpos0, the
    file's pose), so the project passes all six gates, and the two that judge the base free; its
    floating.toml, where the bench moves the base, passes too, and its CI job runs both."""
    from tests.test_mjcf import ARM

    base = '<body name="base" pos="0 0 0.1">'
    (tmp_path / "arm.xml").write_text(ARM.replace(base, base + '<freejoint name="float"/>'))
    assert main(["init", str(tmp_path / "p"), "--mjcf", str(tmp_path / "arm.xml")]) == 0
    assert main(["run", str(tmp_path / "p" / "scenario.toml"), "--out", str(tmp_path / "o"), "--quiet"]) == 0
    results = json.loads((tmp_path / "o" / "results.json").read_text())
    assert len(results["gates"]) == 8 and all(g["passed"] for g in results["gates"])
    assert sum(g["metric"].startswith("torques.floating.") for g in results["gates"]) == 2
    # floating.toml: the bench moves the base, and the placeholder (Pinocchio's parser with its free-flyer)
    # finds the world's wrench on it (round-off, gated at 1e-9)
    assert main(["run", str(tmp_path / "p" / "floating.toml"), "--out", str(tmp_path / "f"), "--quiet"]) == 0
    moved = json.loads((tmp_path / "f" / "results.json").read_text())
    assert "torques.floating.base_wrench_mine_vs_mujoco_max_rel_error" in [g["metric"] for g in moved["gates"]]
    assert "floating.toml" in (tmp_path / "p" / "ci-job.yml").read_text()


def test_init_floating_reads_a_urdfs_root_link_as_its_floating_base_and_refuses_where_it_cannot(tmp_path, capsys):
    """`--floating`: a URDF whose root link is the base (no `floating` joint, as published legged robots
    are) is written `floating = true`, its base read as a free body named on the root link, and the
    project gets floating.toml, whose bench moves the base, in its pytest and CI job. Without the flag
    the same file is a fixed-base arm with no floating.toml. Refused in one line, nothing written: the
    flag without a robot file, with an MJCF file (which states its own free joint), and on a URDF whose
    root link has no mass (no body to float)."""
    import tomllib

    from harness.runner.scenario import load_scenario
    from tests.conftest import ROOT
    from tests.test_mjcf import ARM

    arm = tmp_path / "arm.urdf"  # the two-link arm on a trunk of 5 kg, its root link
    arm.write_text((ROOT / "examples" / "two_link_arm" / "two_link_arm.urdf").read_text().replace(
        '<link name="base"/>', '<link name="base"><inertial><mass value="5.0"/>'
                               '<inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial></link>'))
    assert main(["init", str(tmp_path / "p"), "--urdf", str(arm), "--floating"]) == 0
    folder = tmp_path / "p"
    assert tomllib.loads((folder / "robot.toml").read_text())["urdf"] == {"file": "robot.urdf", "floating": True}
    moved = load_scenario(folder / "floating.toml")
    assert moved.robot.floating.body.name == "base" and moved.base_motion is not None
    assert "floating.toml" in (folder / "ci-job.yml").read_text()
    assert "floating.toml" in (folder / "test_my_robot.py").read_text()
    assert load_scenario(folder / "scenario.toml").robot.floating is not None  # fixed on this bench, judged free
    assert main(["init", str(tmp_path / "fixed"), "--urdf", str(arm)]) == 0
    assert not (tmp_path / "fixed" / "floating.toml").exists()
    assert load_scenario(tmp_path / "fixed" / "scenario.toml").robot.floating is None
    capsys.readouterr()
    (tmp_path / "arm.xml").write_text(ARM)
    massless = ROOT / "examples" / "two_link_arm" / "two_link_arm.urdf"  # its root link has no mass: no base
    for args in ([], ["--mjcf", str(tmp_path / "arm.xml")], ["--urdf", str(massless)]):
        assert main(["init", str(tmp_path / "q"), *args, "--floating"]) == 2
        err = capsys.readouterr().err.strip()
        assert err.count("\n") == 0 and ("--floating" in err or "no mass" in err) and not (tmp_path / "q").exists()


@pytest.mark.slow  # a few seconds: two whole pipelines and a pytest
def test_init_floating_on_a_published_quadruped_passes_both_its_scenarios_out_of_the_box(tmp_path):
    """example-robot-data's Go1 (its URDF's root link the trunk, no floating joint), `harness init
    --floating`: scenario.toml (the base held, every gate passed, the two that judge it free among them)
    and floating.toml (the bench moving the base, the world's wrench on it found by the placeholder model
    to 1e-9) pass, and so does the project's own pytest."""
    from harness.model.urdf import example_robot_data_path

    folder = tmp_path / "p"
    assert main(["init", str(folder), "--robot", str(example_robot_data_path("go1")), "--floating"]) == 0
    for name in ("scenario", "floating"):
        assert main(["run", str(folder / f"{name}.toml"), "--out", str(tmp_path / name), "--quiet"]) == 0
        gates = json.loads((tmp_path / name / "results.json").read_text())["gates"]
        assert all(g["passed"] for g in gates) and any(g["metric"].startswith("torques.floating.") for g in gates)
    done = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider"], cwd=folder,
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stdout[-2000:]


@pytest.mark.slow  # a few seconds: a whole pipeline or a subprocess
@pytest.mark.parametrize("robot", ["talos_reduced", "humanoid MJCF"])
def test_init_at_humanoid_scale_passes_its_run_and_its_pytest_out_of_the_box(tmp_path, robot):
    """TALOS (example-robot-data's talos_reduced.urdf, 32 joints: the template method's pinv(W^T W) was
    6.6e-8 of its largest entry off symmetric, refused) and a humanoid MJCF with meshes in a folder of
    their own, a keyframe, a free joint and a second root body on a hinge (its meshes were not copied,
    Pinocchio's parser stopped at the keyframe and read the first root body alone): `harness init`, then
    `harness run scenario.toml` passes, every joint judged, its report saying the humanoid's floating base
    was fixed on the bench (and two gates judging it free), and the project's own pytest (the same run
    through the harness_run fixture: run for the MJCF project, whose run is the shorter)."""
    from harness.model.urdf import example_robot_data_path
    from tests.conftest import humanoid_mjcf

    source = (example_robot_data_path("talos_reduced") if robot == "talos_reduced"
              else humanoid_mjcf(tmp_path / "maker"))
    folder = tmp_path / "p"
    assert main(["init", str(folder), "--robot", str(source)]) == 0
    if robot != "talos_reduced":
        assert sorted(p.name for p in (folder / "assets").iterdir()) == ["arm.STL", "pelvis.STL", "shin.STL",
                                                                         "thigh.STL", "torso.STL"]
    assert main(["run", str(folder / "scenario.toml"), "--out", str(tmp_path / "o"), "--quiet"]) == 0
    results = json.loads((tmp_path / "o" / "results.json").read_text())
    assert len(results["scenario"]["motion"]) == (32 if robot == "talos_reduced" else 10)
    floating = robot != "talos_reduced"  # the humanoid's base: fixed on the bench, judged free by two more gates
    assert len(results["gates"]) == 6 + 2 * floating and all(g["passed"] for g in results["gates"])
    if floating:  # its floating base, fixed where the file puts it, said in the report too
        assert "the floating base is taken as fixed to the world" in (tmp_path / "o" / "report.html").read_text()
        assert {g["metric"] for g in results["gates"]} >= {"torques.floating.engines_max_rel_error",
                                                           "torques.floating.mass_matrix_max_rel_error"}
        done = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider"],
                              cwd=folder, capture_output=True, text=True, timeout=300)
        assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]


def test_the_plugin_file_init_writes_passes_the_linter(tmp_path):
    """my_robot.py is composed of pieces (harness/data/init/): the whole, for every kind of project."""
    from harness.model.urdf import example_robot_data_path
    from tests.test_mjcf import ARM

    (tmp_path / "arm.xml").write_text(ARM)
    for name, robot in (("arm", None), ("ur5", example_robot_data_path("ur5")), ("mjcf", tmp_path / "arm.xml")):
        folder = tmp_path / name
        folder.mkdir()
        (folder / "my_robot.py").write_text(project(robot)["my_robot.py"])
    done = subprocess.run([str(Path(sys.executable).parent / "ruff"), "check", "--no-cache", "--isolated",
                           "--select", "E,F,W,B", "--line-length", "120", str(tmp_path)],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stdout
