"""The doors of harness/base/plugins.py, tried as a user outside the project would: a model written as
Python code, an identification method, the public API, the pytest fixture, CI artefacts and exit
statuses. The user's code here is written by these tests into temporary folders: no file of the
project contains it."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import textwrap
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

import harness
from harness.cli import main
from tests.conftest import ROOT

EXAMPLE = ROOT / "examples" / "two_link_arm"

# The two-link arm by Newton's and Euler's laws through the Jacobians of each centre of mass,
# tau = sum_i J_i^T m_i (a_i - g) + J_w,i^T I_i alpha_i with a_i = J_i q'' + J_i' q': another
# formulation than the example's closed-form Lagrange equations.
USER_MODEL = '''
import numpy as np


class Arm:
    joint_names = ["elbow", "shoulder"]  # deliberately not the robot's order

    def __init__(self, g, m1=2.0, m2=1.2, l1=0.5, r1=0.25, r2=0.2, I1=0.04206667, I2=0.01615):
        self.g, self.m, self.I, self.l1, self.r = g, (m1, m2), (I1, I2), l1, (r1, r2)

    def inverse_dynamics(self, q, qd, qdd):
        e, s = q[:, 0], q[:, 1]            # my columns: elbow, shoulder
        ed, sd, edd, sdd = qd[:, 0], qd[:, 1], qdd[:, 0], qdd[:, 1]
        (r1, r2), l1 = self.r, self.l1
        a1, a12 = s, s + e
        # centre-of-mass positions (x, z) = r (cos a, -sin a); Jacobians w.r.t. (shoulder, elbow)
        J1 = np.stack([np.stack([-r1 * np.sin(a1), 0 * a1], -1), np.stack([-r1 * np.cos(a1), 0 * a1], -1)], -2)
        J2 = np.stack([np.stack([-l1 * np.sin(a1) - r2 * np.sin(a12), -r2 * np.sin(a12)], -1),
                       np.stack([-l1 * np.cos(a1) - r2 * np.cos(a12), -r2 * np.cos(a12)], -1)], -2)
        w1, w12 = sd, sd + ed
        Jd1 = np.stack([np.stack([-r1 * np.cos(a1) * w1, 0 * a1], -1),
                        np.stack([r1 * np.sin(a1) * w1, 0 * a1], -1)], -2)
        Jd2 = np.stack([np.stack([-l1 * np.cos(a1) * w1 - r2 * np.cos(a12) * w12, -r2 * np.cos(a12) * w12], -1),
                        np.stack([l1 * np.sin(a1) * w1 + r2 * np.sin(a12) * w12, r2 * np.sin(a12) * w12], -1)], -2)
        v, vd = np.stack([sd, ed], -1), np.stack([sdd, edd], -1)
        g = np.array([0.0, -self.g])
        tau = np.zeros_like(v)
        for m, J, Jd in ((self.m[0], J1, Jd1), (self.m[1], J2, Jd2)):
            a = np.einsum("nij,nj->ni", J, vd) + np.einsum("nij,nj->ni", Jd, v)
            tau += np.einsum("nij,ni->nj", J, m * (a - g))
        tau[:, 0] += self.I[0] * sdd + self.I[1] * (sdd + edd)
        tau[:, 1] += self.I[1] * (sdd + edd)
        return tau[:, ::-1]                # back to my column order: elbow, shoulder


def make(robot, gravity_W, parameters):
    return Arm(-gravity_W[2], **parameters)
'''

SCENARIO = '''
[scenario]
model = "two_link_arm.toml"
duration = 1.5
output_steps = 150
{extra_scenario}

[model_under_test]
name = "mine"
python = "{python}"
{parameters}

[motion.shoulder]
type = "sinusoids"
offset = -0.3
sin = [[0.9, 2.1]]

[motion.elbow]
type = "sinusoids"
sin = [[1.2, 3.3], [0.3, 7.0]]

[[gates]]
metric = "torques.mine_vs_mujoco.max_rel_error"
limit = 1e-9

[[gates]]
metric = "torques.mine_vs_pinocchio.max_rel_error"
limit = 1e-9
'''


def _project(tmp_path: Path, parameters: str = "", python: str = "user_arm:make", model: str = USER_MODEL,
             extra: str = "") -> Path:
    """A user's project: the robot description, their model module and a scenario."""
    for f in ("two_link_arm.urdf", "two_link_arm.toml"):
        shutil.copy(EXAMPLE / f, tmp_path / f)
    (tmp_path / "user_arm.py").write_text(model)
    path = tmp_path / "arm.toml"
    path.write_text(SCENARIO.format(python=python, parameters=parameters, extra_scenario=extra))
    return path


def test_a_users_model_in_code_passes_at_round_off(tmp_path, capsys):
    result = harness.run(_project(tmp_path))
    assert result.passed, result.failed
    tq = result.results["torques"]
    assert tq["mine_vs_mujoco"]["max_rel_error"] < 1e-12 and tq["mine_vs_pinocchio"]["max_rel_error"] < 1e-12
    assert [g.metric for g in result.gates] == ["torques.mine_vs_mujoco.max_rel_error",
                                                "torques.mine_vs_pinocchio.max_rel_error"]


@pytest.mark.parametrize(("mass", "loaded"), [("m1", {"shoulder"}), ("m2", {"shoulder", "elbow"})])
def test_one_mass_five_percent_off_fails_at_the_joints_it_loads(tmp_path, capsys, mass, loaded):
    """The forearm's mass loads both joints; the upper arm's only the shoulder (the elbow carries
    the forearm alone). The run exits 1 and says where."""
    value = {"m1": 2.0, "m2": 1.2}[mass] * 1.05
    out = tmp_path / "out"
    assert main(["run", str(_project(tmp_path, f"{mass} = {value}")), "--out", str(out), "--quiet"]) == 1
    assert "FAIL  torques.mine_vs_mujoco.max_rel_error" in capsys.readouterr().out
    results = json.loads((out / "results.json").read_text())
    per_joint = results["torques"]["mine_vs_mujoco"]["max_rel_error_per_joint"]
    assert {j for j, e in per_joint.items() if e > 1e-9} == loaded
    assert all(e < 1e-12 for j, e in per_joint.items() if j not in loaded)
    assert results["torques"]["mine_vs_mujoco"]["max_rel_joint"] in loaded
    report = (out / "report.html").read_text()
    assert "FAILED" in report and "Largest relative error per joint" in report


PLUGIN_FAULTS = {
    "no such module": ({"python": "not_there:make"}, "cannot import module 'not_there'"),
    "import raises": ({"model": "raise RuntimeError('boom')\n"}, "RuntimeError: boom"),
    "no attribute": ({"python": "user_arm:nope"}, "has no attribute 'nope'"),
    "not module:attribute": ({"python": "user_arm"}, "expected 'module:attribute'"),
    "factory raises": ({"model": "def make(robot):\n    raise ValueError('bad arm')\n"}, "ValueError: bad arm"),
    "wrong joints": ({"model": USER_MODEL.replace('["elbow", "shoulder"]', '["elbow", "wrist"]')}, "joint_names"),
    "no inverse_dynamics": ({"model": "class A:\n    joint_names = ['shoulder', 'elbow']\n"
                                      "def make(robot):\n    return A()\n"}, "no inverse_dynamics"),
    "raises while running": ({"model": USER_MODEL.replace("e, s = q[:, 0], q[:, 1]", "e, s = q[:, 7], q[:, 1]")},
                             "inverse_dynamics raised IndexError"),
    "wrong shape": ({"model": USER_MODEL.replace("return tau[:, ::-1]", "return tau[:, :1]")},
                    "returned shape"),
    "complex torques": ({"model": USER_MODEL.replace("return tau[:, ::-1]", "return tau[:, ::-1] + 0j")},
                        "returned complex numbers (complex128)"),  # not cut to their real part
    "a torque not finite": ({"model": USER_MODEL.replace("return tau[:, ::-1]",  # inf in the first row alone
                                                         "return tau[:, ::-1] / (s != s[0])[:, None]")},
                            "returned values that are not finite"),
}


@pytest.mark.parametrize("case", list(PLUGIN_FAULTS))
def test_a_broken_plugin_is_bad_input_in_one_line_and_nothing_is_written(tmp_path, capsys, case):
    edit, phrase = PLUGIN_FAULTS[case]
    path = _project(tmp_path, python=edit.get("python", "user_arm:make"), model=edit.get("model", USER_MODEL))
    out = tmp_path / "out"
    assert main(["run", str(path), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("harness: error: ") and phrase in err, err
    assert not out.exists() and not [p for p in tmp_path.iterdir() if p.name.startswith(".out")]


def test_an_empty_gate_list_and_a_misspelt_direction_are_bad_input(tmp_path, capsys):
    path = _project(tmp_path)
    text = path.read_text()
    path.write_text(text[: text.index("[[gates]]")])
    assert main(["run", str(path), "--quiet"]) == 2
    assert "declares no gates" in capsys.readouterr().err
    path.write_text(text + 'direction = "at_lest"\n')
    assert main(["run", str(path), "--quiet"]) == 2
    assert "'at_lest' is not one of" in capsys.readouterr().err


def test_an_internal_error_exits_3_in_one_line_and_debug_shows_the_traceback(tmp_path, capsys, monkeypatch):
    import harness.stages.torques

    def broken(*args, **kwargs):
        raise ZeroDivisionError("a bug")

    monkeypatch.setattr(harness.stages.torques, "joint_load_scale", broken)
    path = _project(tmp_path)
    assert main(["run", str(path), "--out", str(tmp_path / "out"), "--quiet"]) == 3
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "internal error: ZeroDivisionError: a bug" in err
    # --debug adds the traceback and changes nothing else: the same exit status
    assert main(["--debug", "run", str(path), "--out", str(tmp_path / "out"), "--quiet"]) == 3
    err = capsys.readouterr().err
    assert "Traceback (most recent call last)" in err and "ZeroDivisionError: a bug" in err


def test_junit_xml_and_summary_count_the_failing_gates(tmp_path, capsys):
    junit, summary = tmp_path / "gates.xml", tmp_path / "summary.md"
    path = _project(tmp_path, "m2 = 1.26")
    assert main(["run", str(path), "--out", str(tmp_path / "out"), "--quiet", "--junit-xml", str(junit),
                 "--summary", str(summary)]) == 1
    root = ET.parse(junit).getroot()
    cases = root.findall("./testsuite/testcase")
    assert root.get("tests") == "2" and root.get("failures") == "2" and len(cases) == 2
    assert all(c.find("failure") is not None for c in cases)
    text = summary.read_text()
    assert "arm: FAILED (2 of 2 gates fail)" in text and text.count("**FAIL**") == 2
    # the same verdict again from results.json, without simulating
    assert main(["gate", str(tmp_path / "out" / "results.json"), "--junit-xml", str(junit)]) == 1
    assert ET.parse(junit).getroot().get("failures") == "2"


def test_a_user_identification_method_is_fitted_and_judged_on_a_validation_trajectory(tmp_path):
    """A least-squares fit of the arm's five base parameters written by the user, with no
    parameters reported: judged by the torques it predicts on a trajectory it never saw."""
    method = USER_MODEL + textwrap.dedent('''
        class Fitted:
            joint_names = ["shoulder", "elbow"]

            def __init__(self, theta, g):
                self.theta, self.g = theta, g

            def inverse_dynamics(self, q, qd, qdd):
                return np.einsum("nij,j->ni", regressor(q, qd, qdd, self.g), self.theta)


        def regressor(q, qd, qdd, g):
            """tau = Y theta, theta = (I1 + m1 r1^2 + m2 l1^2, I2 + m2 r2^2, m2 l1 r2, m1 r1 + m2 l1, m2 r2)."""
            c1, c12, s2, c2 = np.cos(q[:, 0]), np.cos(q[:, 0] + q[:, 1]), np.sin(q[:, 1]), np.cos(q[:, 1])
            z = 0 * c1
            row1 = [qdd[:, 0], qdd[:, 0] + qdd[:, 1], (2 * qdd[:, 0] + qdd[:, 1]) * c2
                    - s2 * (2 * qd[:, 0] * qd[:, 1] + qd[:, 1] ** 2), -g * c1, -g * c12]
            row2 = [z, qdd[:, 0] + qdd[:, 1], qdd[:, 0] * c2 + s2 * qd[:, 0] ** 2, z, -g * c12]
            return np.stack([np.stack(row1, -1), np.stack(row2, -1)], -2)


        class LeastSquares:
            joint_names = ["shoulder", "elbow"]

            def __init__(self, g):
                self.g = g

            def fit(self, q, qd, qdd, tau):
                Y = regressor(q, qd, qdd, self.g)
                theta = np.linalg.lstsq(Y.reshape(-1, 5), tau.reshape(-1), rcond=None)[0]
                return Fitted(theta, self.g)


        def method(robot, gravity_W):
            return LeastSquares(-gravity_W[2])
    ''')
    path = _project(tmp_path, model=method)
    validation = tmp_path / "validation.toml"
    other_motion = path.read_text().replace("[[0.9, 2.1]]", "[[0.5, 1.3]]").replace("[[1.2, 3.3]", "[[0.7, 2.9]")
    validation.write_text(other_motion)
    path.write_text(path.read_text() + textwrap.dedent('''
        [identification]
        name = "my_fit"
        python = "user_arm:method"
        validation = "validation.toml"

        [[gates]]
        metric = "identification_methods.my_fit.validation.max_rel_error"
        limit = 1e-9
    '''))
    result = harness.run(path)
    assert result.passed, result.failed
    judged = result.results["identification_methods"]["my_fit"]
    assert judged["validation"]["scenario"] == "validation" and judged["validation"]["max_rel_error"] < 1e-10
    assert judged["base_parameters"] is None  # it reports no parameters: only its torques are judged


DATA_SHEET_METHOD = USER_MODEL + textwrap.dedent('''
    def inertial(m, c, I_c):
        """Pinocchio's dynamic parameters about a frame at the joint point, world axes at q = 0."""
        c = np.asarray(c, float)
        I_o = np.diag(I_c) + m * (c @ c * np.eye(3) - np.outer(c, c))
        return [m, *(m * c), I_o[0, 0], I_o[0, 1], I_o[1, 1], I_o[0, 2], I_o[1, 2], I_o[2, 2]]


    class FromDataSheet:
        """Not a fit at all: the parameters a data sheet gives, with the forearm's mass scaled."""

        joint_names = ["shoulder", "elbow"]

        def __init__(self, g, scale):
            self.g, self.scale = g, scale

        def fit(self, q, qd, qdd, tau):
            m2 = 1.2 * self.scale
            model = Arm(self.g, m2=m2)
            model.joint_names = ["elbow", "shoulder"]
            model.parameters = np.array([inertial(m2, [0.2, 0, 0], [0.0003, 0.01615, 0.01615]),
                                         inertial(2.0, [0.25, 0, 0], [0.0008, 0.04206667, 0.04206667])])
            return model


    def method(robot, gravity_W, parameters):
        return FromDataSheet(-gravity_W[2], **parameters)
''')


@pytest.mark.parametrize(("scale", "worst"), [(1.0, 1e-12), (1.05, None)])
def test_the_parameters_a_method_reports_are_judged_by_the_base_parameters_the_data_determine(tmp_path, scale,
                                                                                              worst):
    """Its (n, 10) parameters, in its own joint order, reduced to the base parameters of the
    training data's regressor and compared with the robot's. A 5 % heavier forearm is seen."""
    path = _project(tmp_path, model=DATA_SHEET_METHOD)
    path.write_text(path.read_text() + f'''
[identification]
name = "sheet"
python = "user_arm:method"
scale = {scale}

[[gates]]
metric = "identification_methods.sheet.base_parameters.max_rel_error"
limit = 1e-9
''')
    judged = harness.run(path).results["identification_methods"]["sheet"]
    # a planar 2R arm has 6 base parameters: per link the moment of inertia about its joint axis and the two
    # first moments in the plane, link 1's absorbing link 2's mass (m2 l1^2, m2 l1)
    assert judged["validation"] is None and judged["base_parameters"]["count"] == 6
    error = judged["base_parameters"]["max_rel_error"]
    assert error < worst if worst else error > 1e-2


class _Fitted:
    """What a method's fit returns, reduced to what the base-parameter table reads of it."""

    joint_names = ("elbow", "shoulder")

    def __init__(self, covariance):
        self.parameters, self.covariance = np.zeros((2, 10)), covariance


def _spd(seed: int) -> np.ndarray:
    """A symmetric positive definite (20, 20) matrix, products of round-off and all (A A^T / 20)."""
    A = np.random.default_rng(seed).standard_normal((20, 20))
    return A @ A.T / 20


@pytest.mark.parametrize("case", ["positive definite", "not symmetric", "indefinite, positive diagonal"])
def test_a_methods_covariance_must_be_one_on_the_base_parameters(case):
    """A method's `covariance` gives the intervals of the base parameters beta = T theta: the standard
    deviations are the square roots of diag(T C T^T). A matrix that is no covariance is refused: not
    symmetric beyond round-off, or with a negative eigenvalue on the base parameters even where every
    variance is positive (which the diagonal alone does not show)."""
    from harness.base.plugins import PluginError
    from harness.stages.plugin_fits import BaseMap, base_table

    T = np.random.default_rng(1).standard_normal((6, 20))  # 6 base parameters of 2 links, as a planar 2R arm
    bm = BaseMap([f"beta{k}" for k in range(6)], T, np.zeros(6))
    C = _spd(0)  # in the robot's joint order (shoulder, elbow)
    if case == "not symmetric":
        C[0, 5] += 1e-3 * np.abs(C).max()
    elif case == "indefinite, positive diagonal":
        w, V = np.linalg.eigh(T @ C @ T.T)
        v = T.T @ np.linalg.solve(T @ T.T, V[:, 0])  # C moved along the base direction of least variance
        C = C - 2.0 * w[0] * np.outer(v, v)
        assert np.all(np.diag(T @ C @ T.T) > 0) and np.linalg.eigvalsh(T @ C @ T.T)[0] < 0
    order = np.r_[10:20, 0:10]  # the method's joint order is (elbow, shoulder): its covariance
    fitted = _Fitted(C[np.ix_(order, order)])
    if case == "positive definite":
        table = base_table("m", fitted, ["shoulder", "elbow"], bm)
        np.testing.assert_allclose(table.std, np.sqrt(np.diag(T @ C @ T.T)), rtol=1e-12)
    else:
        refusal = "not symmetric" if case == "not symmetric" else "positive semidefinite"
        with pytest.raises(PluginError, match=refusal):
            base_table("m", fitted, ["shoulder", "elbow"], bm)


def _pytest_in(folder: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", str(folder)],
                          capture_output=True, text=True, cwd=folder, timeout=300)


@pytest.mark.slow  # a few seconds: a whole pipeline or a subprocess
def test_the_harness_run_fixture_in_a_users_own_suite_passes_and_fails(tmp_path):
    good, bad = tmp_path / "good", tmp_path / "bad"
    shutil.copytree(EXAMPLE, good)
    shutil.copytree(EXAMPLE, bad)
    (bad / "my_arm.py").write_text((good / "my_arm.py").read_text().replace('"m2": 1.2', '"m2": 1.3'))
    passed, failed = _pytest_in(good), _pytest_in(bad)
    assert passed.returncode == 0 and "1 passed" in passed.stdout, passed.stdout + passed.stderr
    assert failed.returncode == 1 and "1 failed" in failed.stdout
    assert "my torques vs MuJoCo" in failed.stdout  # the failing gate is named


def test_mujoco_warnings_go_to_the_log_not_to_a_file_in_the_working_directory(tmp_path, monkeypatch, caplog):
    import mujoco

    import harness.engines.mujoco  # noqa: F401  (installs the handler)

    monkeypatch.chdir(tmp_path)
    model = mujoco.MjModel.from_xml_string("<mujoco><worldbody><body><joint/><geom size='0.1'/></body>"
                                           "</worldbody></mujoco>")
    data = mujoco.MjData(model)
    data.qvel[0] = float("nan")
    mujoco.mj_step(model, data)
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()
    assert any("QVEL" in r.getMessage() for r in caplog.records)


def test_importing_harness_loads_no_engine_and_no_paper():
    code = ("import sys, harness; harness.load_scenario; "
            "print(sorted(m for m in sys.modules if m.startswith(('harness.papers', 'mujoco', 'pinocchio'))))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, check=True)
    assert out.stdout.strip() == "[]", out.stdout


def test_a_simulated_scenario_loads_no_convex_solver_and_no_optimiser():
    """Reading a simulated scenario knows the log stages' tables (stages.LOG_TABLES) without importing
    their modules, which import cvxpy and scipy.optimize (about 2 s together on a 2-core machine)."""
    from harness.stages import LOG_TABLES, log_stages

    assert set(LOG_TABLES) == {s.table for s in log_stages() if s.table is not None}
    code = ("import sys, harness; harness.load_scenario('kr500_rail'); "
            "print(sorted(m for m in ('cvxpy', 'scipy.optimize') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, check=True)
    assert out.stdout.strip() == "[]", out.stdout


@pytest.mark.slow  # a few seconds: two processes, each loading a scenario and its libraries
def test_a_log_scenario_imports_the_tools_it_names_and_no_other():
    """The field's tools are imported when a scenario names them (FIGAROH's import alone takes about
    1 s): tx40_motion names none, tx40 names FIGAROH; neither MuJoCo's sysid nor Dask nor rosbags."""
    pytest.importorskip("figaroh")
    tools = ("figaroh", "mujoco.sysid", "distributed", "rosbags")
    code = ("import sys, harness; harness.load_scenario({!r}); "
            f"print(sorted(m for m in {tools!r} if m in sys.modules))")
    for scenario, expected in (("tx40_motion", "[]"), ("tx40", "['figaroh']")):
        out = subprocess.run([sys.executable, "-c", code.format(scenario)], capture_output=True, text=True, cwd=ROOT,
                             check=True)
        assert out.stdout.strip() == expected, (scenario, out.stdout)


def test_the_version_is_read_from_the_installed_metadata_only_when_asked_for():
    """`import harness` leaves importlib.metadata (about 40 ms) unloaded unless something before it
    loaded it; `harness.__version__` then reads the installed distribution's version."""
    from importlib.metadata import version

    code = ("import sys; before = 'importlib.metadata' in sys.modules; import harness; "
            "print(before or 'importlib.metadata' not in sys.modules); print(harness.__version__)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, check=True)
    lazy, reported = out.stdout.split()
    assert lazy == "True" and reported == version(harness.DISTRIBUTION)


def test_no_core_module_imports_a_paper_package():
    core = [p for p in (ROOT / "harness").rglob("*.py") if "papers" not in p.parts]
    offenders = [str(p.relative_to(ROOT)) for p in core if "harness.papers" in p.read_text()]
    assert not offenders
