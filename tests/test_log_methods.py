"""Identification methods on a measured log (harness/stages/log_methods.py): a method plugged in through
the door is given the training span as the harness's fit read it, judged on the validation span and,
on a bench log, against the robot that made the log; a method whose tool is absent is skipped and
said to be; the field's tools (harness/adapters/) compute what their own documentation says.

The bench log is the repository's (harness/data/logs/ur5_bench: the UR5 with drives, 1 % torque
noise), its scenario scenarios/ur5_bench_log.toml. The methods these tests plug in are written by the
tests into temporary folders."""

from __future__ import annotations

import json
import sys
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from harness.base.tomlio import InputError
from harness.cli import main
from harness.runner.gates import Gate, check, unknown_metrics
from harness.runner.scenario import load_scenario
from tests.conftest import ROOT

SCENARIO = ROOT / "harness" / "data" / "scenarios" / "ur5_bench_log.toml"
TRUTH = ROOT / "harness" / "data" / "models" / "ur5_friction.toml"

# The robot that made the log, as a method: what any method's figures are measured against, so its
# own must be exact.
ORACLE = f'''
import numpy as np
from harness.engines.pinocchio import build_model, rnea
from harness.identify.torque_id import true_parameters
from harness.model import friction
from harness.model.load import load_spec

SEEN = []


class Fitted:
    def __init__(self, spec, pm):
        self.spec, self.pm, self.joint_names = spec, pm, list(spec.joint_names)
        self.parameters = true_parameters(pm).reshape(-1, 10)
        self.friction = friction.values(spec.frictions)
        self.notes = ["the robot that made the log"]

    def inverse_dynamics(self, q, qd, qdd):
        return rnea(self.pm, q, qd, qdd).tau


class Oracle:
    def __init__(self, gravity_W):
        self.spec = load_spec({str(TRUTH)!r})
        self.pm = build_model(self.spec, gravity_W)
        self.joint_names = list(self.spec.joint_names)

    def fit(self, q, qd, qdd, tau, t):
        SEEN.append((len(q), len(t), float(t[0]), float(t[-1])))
        return Fitted(self.spec, self.pm)


def make(robot, gravity_W):
    return Oracle(gravity_W)
'''

ABSENT = '''
from harness.base.plugins import ToolUnavailable


def make(robot):
    raise ToolUnavailable("absent", "the tool it wraps is not installed; pip install absent-tool")
'''


@pytest.fixture(scope="module")
def bench_run(tmp_path_factory):
    """The repository's bench-log scenario with two more methods: the oracle, and one whose tool is absent."""
    folder = tmp_path_factory.mktemp("bench_methods")
    (folder / "oracle.py").write_text(ORACLE)
    (folder / "absent.py").write_text(ABSENT)
    text = SCENARIO.read_text().replace('"../', f'"{SCENARIO.parent.parent}/')
    text += ('\n[[identification]]\nname = "oracle"\npython = "oracle:make"\n'
             '[[identification]]\nname = "absent"\npython = "absent:make"\n'
             '[[gates]]\nmetric = "identification_methods.oracle.truth.validation_rel_error"\nlimit = 1e-12\n'
             '[[gates]]\nmetric = "identification_methods.absent.validation_rel_error"\nlimit = 0.01\n')
    (folder / "s.toml").write_text(text)
    status = main(["run", str(folder / "s.toml"), "--out", str(folder / "out"), "--quiet",
                   "--junit-xml", str(folder / "junit.xml")])
    oracle = sys.modules["oracle"]
    return status, json.loads((folder / "out" / "results.json").read_text()), oracle.SEEN, folder


@pytest.mark.slow  # a few seconds: a whole pipeline or a subprocess
def test_the_robot_that_made_the_log_is_judged_exact_against_itself(bench_run):
    """The truth's own model as a method: its torques are the truth's at every conditioned state (0, to
    round-off), its parameters reduce to the truth's base parameters with friction (0), every link is
    physical and no drive term negative; its held-out error against the measured torques is then the
    noise of the log alone, close to the 1 % the bench added."""
    status, results, _, _ = bench_run
    oracle = results["identification_methods"]["oracle"]
    assert status == 0
    assert oracle["truth"]["validation_rel_error"] <= 1e-12
    assert oracle["base_parameters"]["with_friction"] and oracle["base_parameters"]["max_rel_error"] <= 1e-9
    assert oracle["physical"] == {"inconsistent_links": 0, "links": [], "negative_count": 0, "negative": []}
    # the torques were read with 1 % noise relative to each joint's scale: their error is of that size
    assert 0.005 <= oracle["validation_rel_error"] <= 0.02
    assert oracle["notes"] == ["the robot that made the log"] and oracle["seconds"] >= 0.0


@pytest.mark.slow  # a few seconds: a whole pipeline or a subprocess
def test_the_model_class_floor_is_the_noise_less_what_its_parameters_absorb(bench_run):
    """The least-squares columns fitted on the validation span itself (log_identification.validation_floor):
    on a log made by a robot within the class, with white torque noise of relative size nu on that span
    (the measured torques' error against the truth's), the residual is the noise less its projection on
    the p columns, of expected squared size nu^2 (1 - p / (N n)) where every joint's rows share the
    noise's scale alike. The joints' noise scales differ (1 % of each joint's RMS torque), so the p
    dimensions may fall on the noisier joints' rows: a bound of 4 p / (N n) below, and above it no fit of
    the class can be worse than the truth's own torques, nu (measured 0.00968 for nu = 0.00975, p = 58,
    N n = 4302)."""
    _, results, _, _ = bench_run
    li = results["log_identification"]
    nu = li["truth"]["validation_rel_error"]["measured"]
    p = li["least_squares"]["base_parameters"]  # the columns: the base parameters and the families' terms
    rows = li["spans"]["validation"]["samples"] * li["joints"]
    floor = li["validation_floor"]["rel_error"]
    assert nu * np.sqrt(1 - 4 * p / rows) <= floor <= nu
    assert floor <= li["validation_rel_error"]["least squares"]


@pytest.mark.slow  # a few seconds: a whole pipeline or a subprocess
def test_a_method_is_fitted_on_the_training_span_only_and_sits_in_one_table_with_the_harness(bench_run):
    """The fit receives exactly the training span's samples and, since it names a parameter `t`, their
    times (the validation span starts after they end); the harness's own rows are the log stage's
    figures, the same numbers in both places."""
    _, results, seen, _ = bench_run
    spans = results["log_identification"]["spans"]
    training = spans["training"]
    assert seen == [(training["samples"], training["samples"], training["t_start"], training["t_end"])]
    assert training["t_end"] < spans["validation"]["t_start"]
    table, li = results["identification_methods"], results["log_identification"]
    for row, model in (("harness_least_squares", "least squares"), ("harness_consistent", "consistent")):
        assert table[row]["validation_rel_error"] == li["validation_rel_error"][model]
        assert table[row]["truth"]["validation_rel_error"] == li["truth"]["validation_rel_error"][model]
    assert table["harness_consistent"]["physical"]["inconsistent_links"] == li["consistent"]["inconsistent_links"]


@pytest.mark.slow  # a few seconds: a whole pipeline or a subprocess
def test_a_method_whose_tool_is_absent_is_skipped_and_its_gates_say_so(bench_run):
    """Skipped, with the factory's reason, in results.json, on its gate (neither passed nor failed:
    counted apart) and in the JUnit XML; the rest of the run is judged as usual."""
    status, results, _, folder = bench_run
    assert results["identification_methods"]["absent"] == {
        "plugin": "absent:make", "skipped": "the tool it wraps is not installed; pip install absent-tool"}
    row = next(g for g in results["gates"] if g["metric"].startswith("identification_methods.absent."))
    assert row["skipped"] and row["passed"] and row["value"] is None and "pip install absent-tool" in row["reason"]
    suite = ET.parse(folder / "junit.xml").getroot().find("testsuite")
    assert suite.get("skipped") == "1" and suite.get("failures") == "0"
    assert status == 0 and results["passed"]


def test_a_gate_under_a_skipped_result_is_skipped_and_any_other_missing_metric_is_still_bad_input():
    results = {"identification_methods": {"m": {"plugin": "p", "skipped": "not installed"}, "n": {"x": 1.0}}}
    gates = (Gate("a", "identification_methods.m.truth.validation_rel_error", 0.1),
             Gate("b", "identification_methods.n.x", 0.5), Gate("c", "identification_methods.n.y", 0.5))
    assert unknown_metrics(gates, results) == [2]
    rows, passed = check(gates[:2], results)
    assert rows[0]["skipped"] and rows[0]["passed"] and rows[0]["reason"] == "skipped: not installed"
    assert not rows[1]["passed"] and not passed  # a gate that is not skipped still judges


def test_a_gate_under_a_failed_result_fails_with_what_the_method_raised():
    results = {"identification_methods": {"m": {"plugin": "p", "failed": "fit raised RuntimeError: singular"}}}
    gate = Gate("a", "identification_methods.m.validation_rel_error", 0.5)
    assert unknown_metrics([gate], results) == []  # known: the method ran and failed
    rows, passed = check([gate], results)
    assert not passed and not rows[0]["passed"] and rows[0]["value"] is None
    assert rows[0]["reason"] == "failed: fit raised RuntimeError: singular"


RAISES = """
def make(robot):
    return Raises(list(robot.joint_names))


class Raises:
    def __init__(self, joint_names):
        self.joint_names = joint_names

    def fit(self, q, qd, qdd, tau, t):
        raise RuntimeError("the normal equations are singular")
"""


@pytest.mark.slow  # a few seconds: a whole pipeline
def test_a_method_whose_fit_raises_is_its_row_failed_and_the_run_is_still_judged_and_written(tmp_path, capsys):
    """An exception inside a method's fit is that method's result, not the run's end: its row says
    what it raised, its gate fails (exit 1, not 3), the harness's own fit is judged and exported, and
    the terminal says it once."""
    (tmp_path / "raises.py").write_text(RAISES)
    scenario = _scenario_with(tmp_path, '[[identification]]\nname = "raises"\npython = "raises:make"\n'
                                        '[[gates]]\nmetric = "identification_methods.raises.validation_rel_error"\n'
                                        'limit = 1\n[[gates]]\nmetric = "log_identification.validation_rel_error.'
                                        'consistent"\nlimit = 0.05\n')
    status = main(["run", str(scenario), "--out", str(tmp_path / "out"), "--quiet"])
    results = json.loads((tmp_path / "out" / "results.json").read_text())
    row = results["identification_methods"]["raises"]
    assert status == 1 and row["plugin"] == "raises:make" and row["seconds"] >= 0
    assert row["failed"] == "fit raised RuntimeError: the normal equations are singular"
    failing = [g for g in results["gates"] if not g["passed"]]
    assert [g["metric"] for g in failing] == ["identification_methods.raises.validation_rel_error"]
    assert (tmp_path / "out" / "identified" / "robot.toml").is_file()
    assert "the normal equations are singular" in (tmp_path / "out" / "report.html").read_text()
    assert capsys.readouterr().err.count("identification method raises failed") == 1


def _scenario_with(tmp_path, extra: str):
    text = SCENARIO.read_text().replace('"../', f'"{SCENARIO.parent.parent}/')
    text = text[: text.index("[[identification]]")] + extra
    (tmp_path / "s.toml").write_text(text)
    return tmp_path / "s.toml"


@pytest.mark.parametrize(("extra", "key", "words"), [
    ('[[identification]]\nname = "m"\nplugin = "figaroh"\nvalidation = "other.toml"\n'
     '[[gates]]\nmetric = "identification_methods.m.validation_rel_error"\nlimit = 1\n',
     "identification[0].validation", "validation span"),
    ('[[identification]]\nname = "harness_consistent"\nplugin = "figaroh"\n'
     '[[gates]]\nmetric = "identification_methods.harness_consistent.validation_rel_error"\nlimit = 1\n',
     "identification.name", "harness's own fit"),
    ('[[identification]]\nname = "m"\nplugin = "figaroh"\n'
     '[[gates]]\nmetric = "log_identification.validation_rel_error.consistent"\nlimit = 1\n',
     "identification.name", "judged by no gate, so it would pass whatever it computes: add [[gates]] on "
                            "identification_methods.m.validation_rel_error"),
])
def test_a_method_on_a_log_is_refused_in_one_line_naming_the_key(tmp_path, extra, key, words):
    with pytest.raises(InputError) as err:
        load_scenario(_scenario_with(tmp_path, extra))
    assert key in str(err.value) and words in str(err.value) and "\n" not in str(err.value)


# --- FIGAROH (harness/adapters/figaroh.py) --------------------------------------------------------------


def test_figaroh_absent_is_a_tool_unavailable_naming_the_extra(monkeypatch):
    from harness.adapters import figaroh
    from harness.base.plugins import ToolUnavailable

    for name in [m for m in sys.modules if m == "figaroh" or m.startswith("figaroh.")] + ["figaroh"]:
        monkeypatch.setitem(sys.modules, name, None)  # an import of it raises ImportError
    with pytest.raises(ToolUnavailable, match=r"pip install 'harness\[figaroh\]'"):
        figaroh._figaroh()


@pytest.mark.slow  # a few seconds: a whole pipeline or a subprocess
def test_figaroh_least_squares_is_the_least_squares_of_its_own_model(bench_run):
    """FIGAROH's model of the torques is the rigid-body regressor with, per joint, rotor inertia q'',
    viscous q', a sharp Coulomb sign(q') and an offset. Fitted by numpy's least squares on the harness's
    regressor and those columns (an independent computation of the same model), the held-out and
    training errors are FIGAROH's to 1e-6 (its elimination of columns whose squared norm is under
    1e-3 may leave out a direction that numpy fits, of that order)."""
    pytest.importorskip("figaroh", reason="FIGAROH is not installed (pip install 'harness[figaroh]')")
    from harness.engines.pinocchio import build_model
    from harness.identify.torque_id import regressor
    from harness.sources.log import load

    _, results, _, _ = bench_run
    sc = load_scenario(SCENARIO)
    split = load(sc.data, sc.robot)
    train, validation = split.training, split.validation
    pm = build_model(sc.robot, sc.gravity_W)
    joints = sc.robot.joint_names
    n = len(joints)

    def columns(q, qd, qdd):
        W = regressor(pm, q, qd, qdd).reshape(len(q), n, -1)
        drive = np.zeros((len(q), n, 4 * n))
        for j in range(n):
            drive[:, j, 4 * j: 4 * j + 4] = np.stack([qdd[:, j], qd[:, j], np.sign(qd[:, j]), np.ones(len(q))], -1)
        return np.concatenate([W, drive], axis=2).reshape(len(q) * n, -1)

    q, qd, qdd, tau = train.joint_data(joints)
    x = np.linalg.lstsq(columns(q, qd, qdd), tau.ravel(), rcond=None)[0]
    row = results["identification_methods"]["figaroh"]
    for span, log in (("training", train), ("validation", validation)):
        qs, qds, qdds, taus = log.joint_data(joints)
        pred = (columns(qs, qds, qdds) @ x).reshape(taus.shape)
        assert row[f"{span}_rel_error"] == pytest.approx(np.linalg.norm(pred - taus) / np.linalg.norm(taus), rel=1e-6)


def test_figaroh_runs_at_its_own_tolerances_unless_told_otherwise():
    """Where the scenario gives none, the QR's rank threshold is FIGAROH's own (its QRDecomposer's
    TOL_QR, read from the installed FIGAROH) and the physical fit is left at build_problem's default;
    a tolerance given is used for both."""
    pytest.importorskip("figaroh", reason="FIGAROH is not installed (pip install 'harness[figaroh]')")
    from figaroh.tools.qrdecomposition import TOL_QR

    from harness.adapters.figaroh import Figaroh

    sc = load_scenario(SCENARIO)
    own = Figaroh(sc.robot, sc.gravity_W, {})
    assert own.qr_tolerance == TOL_QR and own.physical_qr == {}
    told = Figaroh(sc.robot, sc.gravity_W, {"qr_tolerance": 1e-5})
    assert told.qr_tolerance == 1e-5 and told.physical_qr == {"qr_tol": 1e-5}


@pytest.mark.slow  # a few seconds: a whole pipeline or a subprocess
def test_figaroh_rows_state_what_figaroh_cannot_do(bench_run):
    """The table does not hide a tool's limits: the sharp Coulomb law and, for the least squares, that
    its parameters are a minimum-norm split (not a physical claim, and judged all the same)."""
    pytest.importorskip("figaroh", reason="FIGAROH is not installed (pip install 'harness[figaroh]')")
    _, results, _, _ = bench_run
    ls, phys = results["identification_methods"]["figaroh"], results["identification_methods"]["figaroh_physical"]
    assert any("sign(q')" in note for note in ls["notes"]) and any("minimum-norm" in note for note in ls["notes"])
    assert phys["physical"]["inconsistent_links"] == 0 and set(ls["friction"]) == set(phys["friction"])


@pytest.mark.slow  # a few seconds: a whole pipeline or a subprocess
def test_the_bench_log_is_what_its_recipe_makes(tmp_path):
    """harness/data/logs/ur5_bench/log.csv is the bench of its bench.toml, measured: remade here, the
    same numbers (to 1e-9: another CPU may round MuJoCo's last bits otherwise; the noise is seeded)."""
    import pandas as pd

    from harness.sources.bench import record, write_log
    from harness.sources.measurement import measure

    folder = ROOT / "harness" / "data" / "logs" / "ur5_bench"
    sc = load_scenario(folder / "bench.toml")
    write_log(measure(record(sc), sc.measurement), sc.robot.joint_names, tmp_path / "log.csv")
    made, shipped = pd.read_csv(tmp_path / "log.csv"), pd.read_csv(folder / "log.csv")
    assert list(made.columns) == list(shipped.columns) and made.shape == shipped.shape == (2401, 19)
    np.testing.assert_allclose(made.to_numpy(), shipped.to_numpy(), rtol=1e-9, atol=1e-12)


# --- MuJoCo's sysid (harness/adapters/mujoco_sysid.py) -------------------------------------------------


def test_mujoco_sysid_absent_is_a_tool_unavailable_naming_the_extra(monkeypatch):
    from harness.adapters import mujoco_sysid
    from harness.base.plugins import ToolUnavailable

    for name in [m for m in sys.modules if m.startswith("mujoco.sysid")] + ["mujoco.sysid"]:
        monkeypatch.setitem(sys.modules, name, None)
    with pytest.raises(ToolUnavailable, match=r"pip install 'harness\[sysid\]'"):
        mujoco_sysid._sysid()


@pytest.mark.slow  # a few seconds: a whole pipeline or a subprocess
def test_mujoco_sysid_is_judged_against_the_truth_and_states_its_limits(bench_run):
    """MuJoCo's sysid from the model as given (the URDF without drives: 22 % off the truth's torques): its
    row holds its error against the truth's torques, its links are physical by construction (the
    pseudo-inertia's Cholesky factor), and it says what it cannot do and what it cost. Whether it comes
    closer to the robot than the model as given is not the harness's to claim: its rollouts' residual
    falls from 1.5e4 to 40 on every machine, but the torques it leaves are where round-off steered it
    (mujoco 4.0.0, same log, its default 84 chunks: 15.4 % on an Intel Xeon, 150 % on an AMD EPYC with
    two rotor inertias at their bound, 131 % there after 60 iterations; docs/plugins.md)."""
    pytest.importorskip("mujoco.sysid", reason="MuJoCo's sysid is not installed (pip install 'harness[sysid]')")
    _, results, _, _ = bench_run
    row = results["identification_methods"]["sysid"]
    assert np.isfinite(row["truth"]["validation_rel_error"]) and row["truth"]["span"] == "validation"
    assert row["physical"]["inconsistent_links"] == 0
    assert any("sharp sign" in note for note in row["notes"])
    assert any("rolled out in" in note for note in row["notes"]) and row["seconds"] > 0
    # by default the rollouts tile the training span: its length over chunk_seconds (0.1 s), rounded up
    span = results["log_identification"]["spans"]["training"]
    seconds = span["t_end"] - span["t_start"]
    shooting = next(note for note in row["notes"] if note.startswith("multiple shooting"))
    assert shooting.startswith(f"multiple shooting: {int(np.ceil(seconds / 0.1 - 1e-9))} rollouts of ")
    assert "(100 % covered, the default: the chunks tile it)" in shooting


@pytest.mark.slow  # a few seconds: a whole pipeline or a subprocess
def test_a_simulated_scenario_with_a_skipped_method_beside_a_real_one_reports_both(tmp_path):
    """On the bench too: the project `harness init` writes, its least-squares method kept and one whose
    tool is absent added. The run passes with the skipped gate counted apart, and the report's
    method table has both rows (a skipped row once sent the whole table to the log's layout)."""
    assert main(["init", str(tmp_path / "p")]) == 0
    folder = tmp_path / "p"
    (folder / "absent.py").write_text(ABSENT)
    text = (folder / "scenario.toml").read_text().replace("[identification]\n", "[[identification]]\n", 1)
    (folder / "scenario.toml").write_text(
        text + '\n[[identification]]\nname = "absent"\npython = "absent:make"\n'
        '[[gates]]\nmetric = "identification_methods.absent.validation.max_rel_error"\nlimit = 0.01\n')
    assert main(["run", str(folder / "scenario.toml"), "--out", str(folder / "o"), "--quiet"]) == 0
    results = json.loads((folder / "o" / "results.json").read_text())
    assert results["identification_methods"]["absent"]["skipped"]
    assert results["identification_methods"]["ls"]["base_parameters"]["max_rel_error"] < 1e-6
    page = (folder / "o" / "report.html").read_text()
    assert "Identification methods under test" in page and "absent:make" in page and "my_robot:make_method" in page


@pytest.mark.slow  # a few seconds: a whole pipeline or a subprocess
def test_the_refinement_reports_its_rollouts_and_seconds_beside_sysids(bench_run):
    """The scenario's refinement by simulation stands beside MuJoCo's sysid on the same log: its rollouts
    and seconds, and those sysid reports, in one place; it never worsens the held-out torque error
    (on this log, whose law the search already finds, it changes it by a few parts in 1e5)."""
    _, results, _, folder = bench_run
    rf = results["refinement"]
    assert rf["rollouts"] > 0 and rf["steps"] == rf["rollouts"] * round(rf["horizon_s"] / 1e-3) and rf["seconds"] > 0
    assert rf["validation"]["torque_rel_error_change"] <= 0
    assert set(rf["candidates"]) >= {"consistent", "pass 1: links held", "pass 1: refitted"}
    report = (folder / "out" / "report.html").read_text()
    assert 'id="refinement"' in report and "What it cost" in report
    if not results["identification_methods"]["sysid"].get("skipped"):
        beside = rf["beside"]["sysid"]
        assert beside["plugin"] == "mujoco_sysid" and beside["rollouts"] > 0 and beside["seconds"] > 0
