"""Torque channels a log does not have (harness/sources/log/channels.py, harness/stages/log_model.py):
`[data] unmeasured` names the joints without one. Their motion stays in every other joint's row; their
own rows are neither fitted nor judged. Checked against Pinocchio's own inverse dynamics at random
states, against the structure of an open tree's dynamics (a joint's drive terms reach its own row
alone), and on a bench log whose truth is known."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from harness.api import load_scenario
from harness.cli import main
from harness.identify.torque_id import drive_columns
from harness.model.friction import IDENTIFIED_KEYS
from harness.stages.log_model import log_model
from tests.conftest import SCENARIOS, bench_log, pinocchio_rnea, viscous_coulomb, write_frame

MODEL = SCENARIOS.parent / "models" / "ur5_friction.toml"
UNMEASURED = ("wrist_2_joint", "wrist_3_joint")
GRAVITY_W = np.array([0.0, 0.0, -9.81])


def _states(n: int, count: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    return rng.uniform(-np.pi, np.pi, (count, n)), rng.standard_normal((count, n)), rng.standard_normal((count, n))


def test_the_rows_of_the_measured_joints_are_pinocchios_torques_of_those_joints():
    """At 30 random states of the UR5 with drives, the regressor's rows of the measured joints times the
    model's own parameters are pinocchio.rnea's torques of those joints plus their drive terms
    (computed here from the model file, not by the harness), to 1e-12 of the largest torque: the
    difference is the order of summation. The unmeasured joints' rows are absent, not zero."""
    robot = load_scenario(SCENARIOS / "ur5_friction.toml").robot
    model = log_model(robot, GRAVITY_W, UNMEASURED)
    q, qd, qdd = _states(6, 30, 1)
    measured = [k for k, j in enumerate(robot.joint_names) if j not in UNMEASURED]
    assert model.torque_joints == [robot.joint_names[k] for k in measured]
    W = model.rows(model.pm, q, qd, qdd)
    assert W.shape == (30 * len(measured), 14 * 6)
    pm = model.pm
    expected = (pinocchio_rnea(pm, q, qd, qdd) + viscous_coulomb(robot.frictions, qd, qdd))[:, measured]
    got = (W @ model.x_model).reshape(30, len(measured))
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12 * np.abs(expected).max())
    np.testing.assert_allclose(model.torques(pm, q, qd, qdd), expected, rtol=0, atol=1e-12 * np.abs(expected).max())


def test_an_unmeasured_joints_drive_terms_leave_the_base_and_its_motion_stays_in_the_others_rows():
    """Of an open tree, joint j's friction and rotor inertia act on its own row alone: with the two wrists
    unmeasured, none of their eight drive terms is a base parameter, every measured joint's viscous and
    Coulomb terms are;
    the base's columns span the measured rows (their rank at other random states is the base's size) and
    reproduce the model's torques of those joints. The wrists' velocities still move the others' rows:
    the rows at a state differ when only an unmeasured joint's q' changes."""
    robot = load_scenario(SCENARIOS / "ur5_friction.toml").robot
    model = log_model(robot, GRAVITY_W, UNMEASURED)
    independent = set(model.base.independent.tolist())
    for k, j in enumerate(robot.joint_names):
        columns = set(range(*drive_columns(6, k).indices(14 * 6)))
        if j in UNMEASURED:
            assert not columns & independent, j
        else:
            start = drive_columns(6, k).start  # viscous and Coulomb (a rotor inertia may regroup with its link's)
            own = {start + IDENTIFIED_KEYS.index("viscous"), start + IDENTIFIED_KEYS.index("coulomb")}
            assert own <= independent, j
    q, qd, qdd = _states(6, 200, 7)
    W = model.rows(model.pm, q, qd, qdd)
    base = W[:, model.base.independent]
    assert np.linalg.matrix_rank(base) == len(model.base.independent) == np.linalg.matrix_rank(W)
    tau = model.torques(model.pm, q, qd, qdd)
    np.testing.assert_allclose(base @ model.base.of(model.x_model), tau.ravel(), rtol=0,
                               atol=1e-10 * np.abs(tau).max())
    moved = qd.copy()
    moved[:, 5] += 1.0  # the unmeasured wrist 3 turning faster
    assert not np.allclose(model.torques(model.pm, q, moved, qdd), tau, rtol=0, atol=1e-9)


def test_the_measured_columns_are_read_into_their_joints_places_an_unmeasured_joints_zero():
    """The elbow (the third of six joints) unmeasured: the log's five torque columns go to joints 1, 2, 4,
    5 and 6, in that order, each with its column's name; the elbow's column is zero and named as
    unmeasured."""
    from types import SimpleNamespace

    from harness.sources.log.channels import every_joint

    robot = load_scenario(SCENARIOS / "ur5_friction.toml").robot
    source = SimpleNamespace(unmeasured=("elbow_joint",), unmeasured_motors=())
    tau = np.arange(1.0, 11.0).reshape(2, 5)
    out, names = every_joint(source, robot, tau, [f"c{k}" for k in range(5)])
    np.testing.assert_array_equal(out, [[1, 2, 0, 3, 4, 5], [6, 7, 0, 8, 9, 10]])
    assert names == ["c0", "c1", "(unmeasured: elbow_joint)", "c2", "c3", "c4"]


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    """ur5_friction's bench log (2 s, 400 rows, noise free): as recorded; with the wrists' channels reading
    0 (a mobile manipulator's dead wrist channels); and without their columns."""
    folder = tmp_path_factory.mktemp("unmeasured")
    bench_log(load_scenario(SCENARIOS / "ur5_friction.toml"), folder, 2.0, 400)
    df = pd.read_csv(folder / "log.csv")
    dead = df.assign(tau5=0.0, tau6=0.0)
    write_frame(dead, folder / "dead.csv")
    write_frame(dead.drop(columns=["tau5", "tau6"]), folder / "absent.csv")
    return folder


def _run(folder, name: str, file: str, extra: str, tau: str = '"tau{j}"') -> tuple[int, dict]:
    (folder / f"{name}.toml").write_text(
        f'[scenario]\nmodel = "{MODEL}"\n[data]\nfile = "{file}"\n'
        f'columns = {{ t = "t", q = "q{{j}}", qd = "qd{{j}}", tau = {tau} }}\n'
        f'units = {{ q = "rad", qd = "rad/s", tau = "N m" }}\ntruth = "{MODEL}"\nvalidation = {{ from = 0.7 }}\n'
        f'{extra}[[gates]]\nmetric = "log_identification.validation_rel_error.consistent"\nlimit = 1e-2\n')
    status = main(["run", str(folder / f"{name}.toml"), "--out", str(folder / name), "--quiet"])
    return status, json.loads((folder / name / "results.json").read_text())


@pytest.mark.slow  # two log runs (5 s); a dead channel's count and message: tests/test_log_channels.py
def test_dead_channels_declared_unmeasured_identify_the_robot_and_read_as_measured_do_not(logs, capsys):
    """The wrists' channels 0 on every row. Declared unmeasured (columns there or absent: the same fit, to
    the bit), the consistent fit predicts the truth's torques of the other four joints on the held-out
    span within 1e-3 (a noise-free log whose model class holds the truth: what is left is the
    accelerations' differences, 8e-5 with every channel read; the wrists' links are seen through fewer
    rows); the identified wrists keep the model's friction exactly, no law searched for them; no forward
    prediction, said.
    Read as measured, the same log makes every joint's fit wrong (0.1 or more against the truth), and
    the checks name both channels and the key that leaves them out."""
    declared = 'unmeasured = ["wrist_2_joint", "wrist_3_joint"]\n'
    status, dead = _run(logs, "dead", "dead.csv", declared)
    assert status == 0
    status, absent = _run(logs, "absent", "absent.csv", declared, tau='["tau1", "tau2", "tau3", "tau4"]')
    assert status == 0
    li, other = dead["log_identification"], absent["log_identification"]
    assert li["least_squares"]["base"] == other["least_squares"]["base"]
    assert li["consistent"]["friction"] == other["consistent"]["friction"]
    assert li["torque_joints"] == ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint"]
    assert li["unmeasured"]["joints"] == list(UNMEASURED)
    assert li["truth"]["validation_rel_error"]["consistent"] <= 1e-3
    assert li["truth"]["validation_rel_error"]["least squares"] <= 1e-3
    robot = load_scenario(SCENARIOS / "ur5_friction.toml").robot
    for j in UNMEASURED:
        f = robot.joint(j).friction
        got = li["consistent"]["friction"][j]
        assert (got["armature"], got["viscous"], got["coulomb"], got["offset"]) == (
            f.armature, f.viscous, f.coulomb, f.offset)
        assert li["friction_law"]["per_joint"][j] == {}  # no law searched: nothing of it is in the data
    assert "wrist_2_joint" in li["prediction"]["note"] and not li["prediction"]["models"]
    assert any("unmeasured" in w for w in li["warnings"])
    report = (logs / "dead" / "report.html").read_text()
    assert "Unmeasured joints wrist_2_joint, wrist_3_joint" in report and li["prediction"]["note"] in report
    capsys.readouterr()
    # (the model's own law and no forward simulation: what is checked is the fit's error)
    status, read = _run(logs, "read", "dead.csv", "prediction = { starts = 0 }\n[friction_law]\nchoose = false\n")
    err = capsys.readouterr().err
    assert status == 1 and read["log_identification"]["truth"]["validation_rel_error"]["consistent"] > 0.1
    assert "wrist_2_joint 100 %, wrist_3_joint 100 %" in err and "[data] unmeasured" in err


@pytest.mark.parametrize(("extra", "tau", "key", "said"), [
    ('unmeasured = ["wrist_3_joint", "wrist_3_joint"]\n', '"tau{j}"', "data.unmeasured", "named twice"),
    ('unmeasured = ["wrist_9_joint"]\n', '"tau{j}"', "data.unmeasured", "wrist_9_joint"),
    ('unmeasured = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint", '
     '"wrist_3_joint"]\n', '"tau{j}"', "data.unmeasured", "every joint named"),
    ('unmeasured = ["wrist_3_joint"]\ncounterbalanced = ["wrist_3_joint"]\n', '"tau{j}"', "data.counterbalanced",
     "is unmeasured"),
    ('unmeasured = ["wrist_3_joint"]\n', '["tau1", "tau2", "tau3"]', "data.columns.tau", "5, one per measured joint"),
    ('unmeasured = ["wrist_3_joint"]\n[refinement]\nadjust = ["delay"]\n', '"tau{j}"', "refinement",
     "every joint's torque"),
])
def test_unmeasured_channels_badly_declared_are_refused_in_one_line(logs, capsys, extra, tau, key, said):
    (logs / "bad.toml").write_text(
        f'[scenario]\nmodel = "{MODEL}"\n[data]\nfile = "dead.csv"\n'
        f'columns = {{ t = "t", q = "q{{j}}", qd = "qd{{j}}", tau = {tau} }}\n{extra}'
        '[[gates]]\nmetric = "log_identification.validation_rel_error.consistent"\nlimit = 1e-2\n')
    assert main(["run", str(logs / "bad.toml"), "--out", str(logs / "bad"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and key in err[0] and said in err[0], err
    assert not (logs / "bad").exists()
