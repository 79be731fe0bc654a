"""`harness audit` (harness/runner/audit.py): robots read as the harness reads them and checked against
Pinocchio's own parsers and MuJoCo, which share none of the harness's reading code. A read robot
agrees within 1e-9 (the engines agree to about 1e-13); the audit can fail (a planted reading error
is caught), refuses in a row rather than a crash, and says why MuJoCo's conversion of a URDF differs
where it does."""

from __future__ import annotations

import json

import numpy as np
import pytest

from harness.base.tomlio import InputError
from harness.cli import main
from harness.runner.audit import TOLERANCE, audit, resolve
from tests.conftest import ROOT
from tests.test_mjcf import ARM

FIGURES = ("torques_vs_pinocchio", "mass_matrix_vs_pinocchio", "torques_vs_mujoco", "torques_urdf_vs_mjcf")


def test_robots_of_the_collection_agree_with_pinocchio_and_mujoco_and_are_written_out(tmp_path, capsys):
    names = ["panda", "kinova", "double_pendulum_continuous", "solo12"]
    assert main(["audit", *names, "--out", str(tmp_path / "a"), "--quiet"]) == 0
    doc = json.loads((tmp_path / "a" / "audit.json").read_text())
    assert [r["robot"] for r in doc["robots"]] == names
    for r in doc["robots"]:
        assert r["verdict"] == "agrees", r
        assert all(r[f] <= TOLERANCE for f in FIGURES), r
        assert r["base_parameters"] == r["pinocchio_regressor_rank"] > 0
        assert r["mjcf"] == "read" and r["root"] == "fixed"
    assert doc["totals"]["agree"] == 4
    html = (tmp_path / "a" / "audit.html").read_text()
    assert all(n in html for n in names)
    assert "4 agree" in capsys.readouterr().out


def test_a_reading_error_is_caught_and_fails_the_audit(tmp_path, monkeypatch, capsys):
    """Every moving body's principal moments 0.1 % larger as the harness reads them: Pinocchio's own
    parser disagrees."""
    import harness.model.urdf as urdf

    union = urdf.union
    monkeypatch.setattr(urdf, "union", lambda parts: (lambda m, c, p, a: (m, c, p * 1.001, a))(*union(parts)))
    assert main(["audit", "ur5_robot", "--out", str(tmp_path / "a"), "--quiet"]) == 1
    row = json.loads((tmp_path / "a" / "audit.json").read_text())["robots"][0]
    assert row["verdict"] == "disagrees" and "torques against Pinocchio" in row["reason"]
    assert "1 disagree" in capsys.readouterr().out


def test_a_robot_the_harness_refuses_is_a_row_with_the_reason():
    name, path = next(iter(resolve(["ur3"]).items()))
    row = audit(name, path)
    assert (row.verdict, row.reason) == ("refused", "expected one root link, found 0")


def test_mujocos_conversion_of_a_urdf_is_compared_and_a_difference_explained():
    """Bolt's feet have no mass but an inertia: the harness and Pinocchio's parser keep it, MuJoCo's
    URDF import drops it, and the torques of the two readings differ by 2e-4 of the largest."""
    name, path = next(iter(resolve(["bolt"]).items()))
    row = audit(name, path)
    assert row.torques_vs_pinocchio <= TOLERANCE and row.torques_vs_mujoco <= TOLERANCE
    assert row.torques_urdf_vs_mjcf > 1e-6  # a limit of MuJoCo's import, said: not a disagreement of the harness's
    assert row.verdict == "not compared" and "FL_FOOT" in row.reason and "zero mass" in row.reason


def test_an_mjcf_file_is_audited_against_pinocchios_mjcf_parser(tmp_path):
    (tmp_path / "arm.xml").write_text(ARM.replace('<option gravity="0.3 -0.2 -9.7"/>', ""))
    row = audit("arm", tmp_path / "arm.xml")
    assert row.verdict == "agrees", row.reason
    assert row.mjcf == "the file itself" and row.dof == 3
    assert row.torques_vs_pinocchio <= TOLERANCE and row.mass_matrix_vs_pinocchio <= TOLERANCE


def test_a_file_pinocchios_parser_cannot_read_is_not_compared_with_it_but_still_with_mujocos_reading(tmp_path):
    """MJCF's <frame> (MuJoCo compiles it; Pinocchio's MJCF parser does not know it): `not compared`, with
    Pinocchio's reason whole on one line, and the harness's torques against MuJoCo's own model of the file.
    An engine's message of many lines (Pinocchio's "From file: ... in function: ... reason: ...") is kept
    whole, its lines joined on one line."""
    from harness.base.tomlio import in_one_line

    (tmp_path / "framed.xml").write_text('<mujoco><worldbody><frame pos="0 0 1"><body name="a"><joint type="hinge"/>'
                                         '<geom size=".1"/></body></frame></worldbody></mujoco>')
    row = audit("framed", tmp_path / "framed.xml")
    assert row.verdict == "not compared"
    assert row.reason == "Pinocchio's MJCF parser cannot read it: No such node (body)"
    assert row.torques_vs_pinocchio is None and row.torques_vs_mujoco_file <= TOLERANCE
    pretty = "From file: /src/parsers/mjcf/mjcf-graph.cpp\nin function: parseJoint\nat line: 312\nreason: no range\n"
    assert in_one_line(pretty) == ("From file: /src/parsers/mjcf/mjcf-graph.cpp; in function: parseJoint; "
                                   "at line: 312; reason: no range")


@pytest.mark.parametrize("argument, message", [("no_such_robot", "no robot of that name"),
                                               ("README.md", "neither a URDF")])
def test_an_unknown_robot_is_refused_in_one_line(tmp_path, capsys, argument, message):
    assert main(["audit", argument, "--out", str(tmp_path / "a")]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "\n" not in err and not (tmp_path / "a").exists()


def test_the_states_fill_a_range_written_as_lower_equal_upper():
    from harness.model.states import position_bounds

    lo, hi = position_bounds(["a", "b"], [True, False], {"a": (0.0, 0.0), "b": (-0.1, 0.2)})
    np.testing.assert_array_equal(lo, [-np.pi, -0.1])
    np.testing.assert_array_equal(hi, [np.pi, 0.2])


def _identifiable() -> list[str]:
    """The robots of example-robot-data the harness reads and that have a joint to move."""
    from harness.model.load import spec_from_data

    out = []
    for name, path in resolve([]).items():
        try:
            if spec_from_data({"urdf": {"file": str(path)}}, path).joints:
                out.append(name)
        except InputError:
            pass
    return out


def _selects_slow(config: pytest.Config) -> bool:
    """Whether the run's mark expression (-m) selects a test marked slow (the fast suite's does not)."""
    expression = config.getoption("markexpr")
    if not expression:
        return True
    try:
        from _pytest.mark.expression import Expression
    except ImportError:  # pytest's own parser moved: read the robots anyway
        return True
    return Expression.compile(expression).evaluate(lambda name, **_: name == "slow")


def pytest_generate_tests(metafunc: pytest.Metafunc) -> None:
    """The robots of the collection are read (a second) only where the slow checks run: the fast suite's
    two workers each collect every test, the deselected ones too."""
    if metafunc.definition.name == "test_every_robot_read_is_identified_from_its_own_bench_log":
        metafunc.parametrize("name", _identifiable() if _selects_slow(metafunc.config) else [])


@pytest.mark.slow  # the whole collection: about 4 minutes on 2 cores (tiago_dual, 101 joints, 75 s)
def test_every_robot_read_is_identified_from_its_own_bench_log(tmp_path, name):
    """A log of the robot's own bench recording (every joint on two sinusoids, 4 s at 250 Hz) read
    back through [data]: least squares and the consistent fit predict the held-out 30 % within
    IDENTIFY_TOLERANCE (1e-4; the exact model scores 1e-7 to 1.3e-5 on the same data, the floor of
    the log's differentiated accelerations)."""
    from harness.runner.audit import IDENTIFY_TOLERANCE, identify_from_bench

    got = identify_from_bench(name, resolve([name])[name], tmp_path)
    e = got["validation_rel_error"]
    assert max(e["least squares"], e["consistent"]) <= IDENTIFY_TOLERANCE, got


def test_a_model_file_with_coupled_drives_is_audited_with_them_and_a_misapplied_law_is_caught(tmp_path,
                                                                                             monkeypatch):
    """A model file around a URDF with a coupled transmission and every motor's law (tests/test_drives.py's
    arm): its rigid bodies against Pinocchio's parser and MuJoCo, and its torques with the drives,
    MuJoCo's bench (the motors' tendons, the dry terms through N) against Pinocchio's RNEA with the law,
    all within 1e-9. The dry terms applied 1 % too strong on MuJoCo's side are caught."""
    from harness.model import drives
    from tests.test_drives import _drives_model

    path = tmp_path / _drives_model(tmp_path)
    assert resolve([str(path)]) == {"coupled": path}
    row = audit("coupled", path)
    assert row.verdict == "agrees", row.reason
    assert row.drives_vs_pinocchio <= TOLERANCE and row.torques_vs_pinocchio <= TOLERANCE
    dry = drives.Dry.__call__
    monkeypatch.setattr(drives.Dry, "__call__", lambda self, *a, **k: 1.01 * dry(self, *a, **k))
    row = audit("coupled", path)
    assert row.verdict == "disagrees" and "torques with the drives" in row.reason
    assert row.torques_vs_pinocchio <= TOLERANCE  # the rigid bodies still agree


def test_a_model_file_that_fixes_joints_of_its_urdf_is_not_compared_with_the_urdfs_parse():
    from harness.runner.audit import _read

    path = next(iter(resolve([str(ROOT / "harness" / "data" / "models" / "panda_arm.toml")]).values()))
    spec, described, _ = _read(path)
    assert spec.urdf_fixed and described == spec.urdf
    row = audit("panda_arm", path)
    assert row.verdict == "agrees" and row.torques_vs_pinocchio is None
    assert any("fixes joints its URDF moves" in note for note in row.notes)
    assert row.drives_vs_pinocchio <= TOLERANCE  # its joints' damping, MuJoCo against Pinocchio


def test_a_closed_chain_and_a_humanoid_with_a_free_joint_agree_with_both_readers(tmp_path, capsys):
    """The shipped fourbar.xml (two subtrees from the ground, closed by a connect) and a humanoid MJCF (a
    free joint, a keyframe, meshes, a second root body on a hinge: what Pinocchio's MJCF parser reads
    only when given the file with its keyframe left out and its root bodies under one, its free joint
    held at the file's pose as the harness holds it): each agrees with Pinocchio's parser and with
    MuJoCo's own model of the file (loops off, the free joint at rest), exit 0. Before, each was
    'disagrees' through Pinocchio's parser (other joints; 'Keyframe size does not match model size')."""
    from tests.conftest import MODELS, humanoid_mjcf

    biped = humanoid_mjcf(tmp_path / "biped")
    assert main(["audit", str(MODELS / "fourbar.xml"), str(biped), "--out", str(tmp_path / "a"), "--quiet"]) == 0
    rows = json.loads((tmp_path / "a" / "audit.json").read_text())["robots"]
    for r in rows:
        assert r["verdict"] == "agrees", r
        assert max(r["torques_vs_pinocchio"], r["mass_matrix_vs_pinocchio"], r["torques_vs_mujoco_file"]) <= TOLERANCE
        assert r["base_parameters"] == r["pinocchio_regressor_rank"]
    assert rows[1]["dof"] == 10 and rows[1]["root"] == "floating (judged free, and fixed at the file's pose)"
    assert max(rows[1]["floating"].values()) <= TOLERANCE  # free: tests/test_floating.py
    assert any("keyframe" in n for n in rows[1]["notes"]) and any("root bodies" in n for n in rows[0]["notes"])


def test_a_misread_mjcf_disagrees_with_mujocos_own_reading_of_the_file(tmp_path, monkeypatch):
    """Every body's mass 0.1 % larger as the harness reads an MJCF file: MuJoCo's own model of the file
    and Pinocchio's parser both disagree, exit 1 (a 'not compared' never hides what was compared)."""
    import dataclasses

    import harness.model.load as load

    read = load.spec_from_data

    def heavier(*args, **kwargs):
        spec = read(*args, **kwargs)
        return dataclasses.replace(spec, bodies=tuple(dataclasses.replace(b, mass=b.mass * 1.001) for b in spec.bodies))

    monkeypatch.setattr(load, "spec_from_data", heavier)
    (tmp_path / "framed.xml").write_text('<mujoco><worldbody><frame pos="0 0 1"><body name="a"><joint type="hinge" '
                                         'axis="0 1 0"/><geom size=".1" pos="0.3 0 0"/></body></frame></worldbody>'
                                         '</mujoco>')  # its joint unnamed: the harness's '#0' is MuJoCo's joint 0
    assert main(["audit", str(tmp_path / "framed.xml"), "--out", str(tmp_path / "a"), "--quiet"]) == 1
    row = json.loads((tmp_path / "a" / "audit.json").read_text())["robots"][0]
    assert row["verdict"] == "disagrees" and row["reason"].startswith("torques against MuJoCo's own model of the file")
    assert "not compared: Pinocchio's MJCF parser cannot read it" in row["reason"]


REFUSED = {
    "ball.xml": ('<mujoco><worldbody><body name="a"><joint name="j" type="hinge"/><geom size=".1"/><body name="b" '
                 'pos="0 0 -.3"><joint name="elbow0" type="ball" damping="1"/><geom size=".1"/></body></body>'
                 '</worldbody></mujoco>', "ball joint 'elbow0' has damping"),
    "coupled.xml": ('<mujoco><worldbody><body name="a"><joint name="l" type="slide"/><geom size=".1"/></body><body '
                    'name="b" pos="0 1 0"><joint name="r" type="slide"/><geom size=".1"/></body></worldbody><equality>'
                    '<joint joint1="r" joint2="l" polycoef="0 1 1 0 0"/></equality></mujoco>',
                    "by a polynomial of degree above 1"),
    "included.xml": ('<mujoco><include file="missing.xml"/><worldbody><body name="a"><joint name="l" type="hinge"/>'
                     '<geom size=".1"/></body></worldbody></mujoco>', "Error opening file 'missing.xml'"),
    # a floating joint from the root link is a floating base (tests/test_floating.py); below it, refused
    "floating.urdf": ('<robot name="f"><link name="world"/><link name="mount"/><link name="base"><inertial><mass '
                      'value="1"/><inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial></link><joint '
                      'name="bolt" type="fixed"><parent link="world"/><child link="mount"/></joint><joint '
                      'name="floating_base" type="floating"><parent link="mount"/><child link="base"/></joint></robot>',
                      "joint 'floating_base' has type 'floating' below the root link"),
}


@pytest.mark.parametrize("name", list(REFUSED))
def test_a_single_file_the_harness_refuses_is_bad_input(tmp_path, capsys, name):
    """A file named on the command line that the harness's reader refuses: exit 2, one line naming it,
    nothing written (it was exit 0, with a row saying 'refused')."""
    text, words = REFUSED[name]
    (tmp_path / name).write_text(text)
    assert main(["audit", str(tmp_path / name), "--out", str(tmp_path / "a"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"harness: error: {tmp_path / name}: ") and words in err and "\n" not in err
    assert not (tmp_path / "a").exists()
