"""Any robot from a URDF: the reader against Pinocchio's own URDF parser, the 10-parameter and the
joint-torque identifications, the optimised excitation, and an arm the project has never seen."""

from __future__ import annotations

import json

import numpy as np
import pinocchio as pin
import pytest

from harness.cli import main
from harness.engines.pinocchio import build_model, crba
from harness.model.load import load_spec
from harness.model.urdf import example_robot_data_path
from tests.conftest import MODELS, ROOT, SCENARIOS, copy_gate_sets, results_of

ARMS = ("panda", "ur5")


@pytest.mark.parametrize("robot", (*ARMS, "bolt", "solo12"))
def test_urdf_reader_matches_pinocchios_own_parser(robot, tmp_path):
    """Pinocchio parses the same URDF itself (merging fixed joints too): the joint-space inertia
    matrix and the gravity torques of our RobotSpec agree with its model at random
    configurations to 1e-12 relative. Bolt and Solo12 branch at the base (two and four legs): our
    joints come root first, breadth first, Pinocchio's depth first, so the columns are matched by
    name; Bolt's feet are links of zero mass with rotational inertia, fixed to the lower legs."""
    model_file = tmp_path / f"{robot}.toml"
    model_file.write_text(f'[urdf]\nrobot = "{robot}"\n')  # the two-line model file
    spec = load_spec(model_file)
    ours = build_model(spec, np.array([0, 0, -9.81]))
    theirs = pin.buildModelFromUrdf(str(example_robot_data_path(robot)))
    assert sorted(theirs.names[i] for i in range(1, theirs.njoints)) == sorted(spec.joint_names)
    cols = [theirs.joints[theirs.getJointId(j)].idx_q for j in spec.joint_names]
    rng = np.random.default_rng(0)
    q = rng.uniform(-1.5, 1.5, size=(20, len(spec.joints)))
    M_ours = crba(ours, q)
    data = theirs.createData()
    for k in range(len(q)):
        q_theirs = np.zeros(theirs.nq)
        q_theirs[cols] = q[k]
        M = pin.crba(theirs, data, q_theirs)
        M = (np.triu(M) + np.triu(M, 1).T)[np.ix_(cols, cols)]
        np.testing.assert_allclose(M_ours[k], M, rtol=0, atol=1e-12 * np.abs(M).max())
        g_theirs = pin.computeGeneralizedGravity(theirs, data, q_theirs)[cols]
        q_ours = np.zeros(ours.model.nq)
        q_ours[ours.q_index] = q[k]
        g_ours = pin.computeGeneralizedGravity(ours.model, ours.model.createData(), q_ours)[ours.q_index]
        np.testing.assert_allclose(g_ours, g_theirs, rtol=0, atol=1e-12 * np.abs(g_theirs).max())


@pytest.mark.slow  # a few seconds: a whole pipeline or a subprocess
@pytest.mark.parametrize("robot", ARMS)
def test_ten_parameters_per_body_are_recovered(run_scenario, robot):
    """Ideal measurements: every identifiable parameter within 1e-8 of the truth (measured ~1e-12).
    The first link only spins about the vertical axis through its joint, so its m c_z, Ixx, Ixy,
    Iyy leave no trace in its forces and moments: exactly those are not identifiable."""
    results = results_of(run_scenario(SCENARIOS / f"{robot}_sines.toml"))
    full = results["identification_full"]
    assert full["max_abs_rel_error"] <= 1e-8
    first = load_spec(MODELS / f"{robot}.toml").bodies[0].name
    assert full["not_identifiable"] == [f"{first}.{p}" for p in ("mcz", "Ixx", "Ixy", "Iyy")]


@pytest.mark.slow  # a few seconds: a whole pipeline or a subprocess
@pytest.mark.parametrize("robot", ARMS)
def test_joint_torque_identification_recovers_base_parameters_and_predicts_validation(run_scenario, robot):
    out = run_scenario(SCENARIOS / f"{robot}_sines.toml")
    ti = results_of(out)["torque_identification"]
    assert ti["max_rel_error"] <= 1e-8
    assert ti["validation"]["max_rel_error"] <= 1e-8
    # the base parameters reproduce the full model's torques: W theta = W_1 beta on the validation data
    assert ti["base_parameters"] < ti["parameters"]


@pytest.mark.slow  # the optimisation: about 6 s
def test_optimised_excitation_is_better_conditioned(run_scenario):
    ex = results_of(run_scenario(SCENARIOS / "ur5_excitation.toml"))["excitation"]
    assert ex["optimised_condition_number"] < ex["initial_condition_number"]


@pytest.mark.parametrize("robot", ["z1", "xarm"])
def test_an_arm_never_seen_goes_through_harness_run(tmp_path, capsys, robot):
    """A URDF of example-robot-data that no file of the project names: a model file of two lines
    and a scenario moving every joint; no code changes. The three torque sources agree."""
    spec_text = f'[model]\nname = "{robot}"\n\n[urdf]\nrobot = "{robot}"\n'
    (tmp_path / "models").mkdir()
    (tmp_path / "scenarios").mkdir()
    copy_gate_sets(tmp_path / "scenarios")
    (tmp_path / "models" / f"{robot}.toml").write_text(spec_text)
    spec = load_spec(tmp_path / "models" / f"{robot}.toml")
    motion = "".join(f'\n[motion.{j}]\ntype = "sinusoids"\nsin = [[0.3, {1.1 + 0.3 * k}]]\n'
                     for k, j in enumerate(spec.joint_names))
    (tmp_path / "scenarios" / "s.toml").write_text(
        f'[scenario]\nmodel = "../models/{robot}.toml"\nduration = 1.0\noutput_steps = 50\nsample_times = "all"\n'
        + '\n[model_under_test]\nname = "graph"\nplugin = "graph_theory_2021"\n'
        + motion + '\n[[gates]]\nmetric = "torques.graph_vs_pinocchio.max_rel_error"\nlimit = 1e-9\n'
        + '\n[[gates]]\nmetric = "torques.pinocchio_vs_mujoco.max_rel_error"\nlimit = 1e-9\n')
    assert main(["run", str(tmp_path / "scenarios" / "s.toml"), "--out", str(tmp_path / "out"), "--quiet"]) == 0
    assert "PASSED (2 gates)" in capsys.readouterr().out


EXAMPLE_URDF = ROOT / "examples" / "two_link_arm" / "two_link_arm.urdf"

BAD_URDFS = {
    "NaN mass": (('<mass value="2.0"/>', '<mass value="nan"/>'), "mass = 'nan' is not finite"),
    "text mass": (('<mass value="2.0"/>', '<mass value="heavy"/>'), "is not a list of numbers"),
    "negative mass": (('<mass value="2.0"/>', '<mass value="-2.0"/>'), "mass -2 is negative"),
    "inf origin": (('<origin xyz="0.5 0 0"', '<origin xyz="inf 0 0"'), "origin xyz"),
    "joint without child": (('<child link="fore"/>', ""), "has no <child link=...>"),
    "undefined child": (('<child link="fore"/>', '<child link="hand"/>'), "child link 'hand' is not defined"),
    "zero axis": (('<axis xyz="0 1 0"/>\n    <limit lower="-3.1" upper="3.1" effort="100" velocity="5"/>\n  '
                   '</joint>\n  <link name="fore">', '<axis xyz="0 0 0"/>\n  </joint>\n  <link name="fore">'),
                  "axis is the zero vector"),
    "duplicate link": (('<link name="fore">', '<link name="upper">'), "link 'upper' is defined twice"),
    "loop": (('<parent link="upper"/>\n    <child link="fore"/>', '<parent link="fore"/>\n    <child link="upper"/>'),
             "the child of two joints"),
    "inertia without mass": (('<mass value="1.2"/>', '<mass value="0"/>'), "rotational inertia but no mass"),
    "limits the wrong way round": (('lower="-3.1" upper="3.1"', 'lower="3.1" upper="-3.1"'),
                                   "joint 'shoulder': limit lower='3.1' upper='-3.1' is no range"),
    "a NaN limit": (('lower="-3.1" upper="3.1"', 'lower="-3.1" upper="nan"'), "is no range"),
    "a moving link without mass": (('<mass value="1.2"/>\n      <inertia ixx="0.0003" ixy="0" ixz="0" iyy="0.01615" '
                                    'iyz="0" izz="0.01615"/>', ""),
                                   "link 'fore' moves (joint 'elbow') and has no mass"),
}


@pytest.mark.parametrize("case", list(BAD_URDFS))
def test_a_urdf_that_no_rigid_body_could_have_is_refused_in_one_line(tmp_path, capsys, case):
    (old, new), phrase = BAD_URDFS[case]
    text = EXAMPLE_URDF.read_text()
    assert old in text, case
    (tmp_path / "arm.urdf").write_text(text.replace(old, new, 1))
    (tmp_path / "arm.toml").write_text('[urdf]\nfile = "arm.urdf"\n')
    (tmp_path / "s.toml").write_text('[scenario]\nmodel = "arm.toml"\nduration = 1.0\noutput_steps = 10\n'
                                     '[motion.shoulder]\ntype = "locked"\n[motion.elbow]\ntype = "locked"\n'
                                     '[[gates]]\nmetric = "torques.pinocchio_vs_mujoco.max_rel_error"\nlimit = 1e-9\n')
    assert main(["run", str(tmp_path / "s.toml"), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "arm.urdf" in err and phrase in err, err
    assert not (tmp_path / "out").exists()


def _is_the_nearest_rigid_moments(x: np.ndarray, p: np.ndarray, tol: float) -> bool:
    """The independent check: x is the projection of p onto the cone of a rigid body's principal moments
    (each at most the sum of the other two: x = B y, y >= 0, B's columns (0, 1, 1), (1, 0, 1), (1, 1, 0)),
    by Moreau's decomposition: x in the cone, p - x in its polar cone (B^T (p - x) <= 0) and the two
    orthogonal, each to `tol`."""
    B = np.ones((3, 3)) - np.eye(3)
    r = p - x
    return bool(np.all(np.linalg.solve(B, x) >= -tol) and np.all(B.T @ r <= tol)
                and abs(r @ x) <= tol * np.abs(x).max())


@pytest.mark.parametrize(("tensor", "why"), [
    ('ixx="0.001557" ixy="0" ixz="0" iyy="0.005976" iyz="0" izz="0.007774"', "triangle inequality"),
    ('ixx="-0.001" ixy="0" ixz="0" iyy="0.01615" iyz="0" izz="0.01615"', "a negative principal moment"),
    ('ixx="0.0003" ixy="0.0001" ixz="0" iyy="0.0002" iyz="0" izz="0.01615"', "triangle inequality")])
def test_a_urdf_inertia_no_rigid_body_has_is_read_as_the_nearest_that_is_with_one_warning(tmp_path, capsys, tensor,
                                                                                         why):
    """A maker's URDF whose link breaks the triangle inequality (a mobile manipulator's arm_1_link: 0.001557,
    0.005976, 0.007774) or has a negative moment is read, not refused: the forearm's moments become the
    nearest a rigid body has (to 1e-9 of its largest moment: the boundary, INERTIA_TOL inside), its
    principal axes kept, said once on the terminal and in results.json, and both engines agree on it."""
    from harness.model.urdf import INERTIA_TOL

    old = 'ixx="0.0003" ixy="0" ixz="0" iyy="0.01615" iyz="0" izz="0.01615"'
    (tmp_path / "arm.urdf").write_text(EXAMPLE_URDF.read_text().replace(old, tensor))
    (tmp_path / "arm.toml").write_text('[urdf]\nfile = "arm.urdf"\n')
    motion = "".join(f'[motion.{j}]\ntype = "sinusoids"\nsin = [[0.8, {w}]]\n' for j, w in (("shoulder", 3.1),
                                                                                           ("elbow", 4.3)))
    gate = '[[gates]]\nmetric = "torques.pinocchio_vs_mujoco.max_rel_error"\nlimit = 1e-9\n'
    head = '[scenario]\nmodel = "arm.toml"\nduration = 1.0\noutput_steps = 10\n'
    (tmp_path / "s.toml").write_text(head + motion + gate)
    assert main(["run", str(tmp_path / "s.toml"), "--out", str(tmp_path / "out"), "--quiet"]) == 0
    err = capsys.readouterr().err
    assert err.count("link 'fore': principal moments") == 1 and why in err, err
    notes = json.loads((tmp_path / "out" / "results.json").read_text())["scenario"]["model_notes"]
    assert len(notes) == 1 and notes[0].startswith("link 'fore'")
    values = dict(kv.split("=") for kv in tensor.split())
    v = {k: float(x.strip('"')) for k, x in values.items()}
    I = np.array([[v["ixx"], v["ixy"], v["ixz"]], [v["ixy"], v["iyy"], v["iyz"]], [v["ixz"], v["iyz"], v["izz"]]])
    p = np.linalg.eigvalsh(I)
    fore = next(b for b in load_spec(tmp_path / "arm.toml").bodies if b.name == "fore")
    I_read = fore.R_WB0 @ fore.I_B @ fore.R_WB0.T
    read = np.linalg.eigvalsh(I_read)
    inside = INERTIA_TOL * np.max(np.abs(p))  # each moment raised by it off the cone's boundary
    assert _is_the_nearest_rigid_moments(read - inside, p, 4 * inside)
    # the slack an engine's check sees: that rise, less the round-off of the body's eigendecomposition
    assert read[2] - read[0] - read[1] <= -inside / 2 and read[0] >= inside / 2
    # the same principal axes as written: the two tensors commute (to round-off of their size)
    assert np.abs(I_read @ I - I @ I_read).max() <= 1e-12 * np.max(np.abs(p)) ** 2


def test_a_mimic_joint_follows_its_leader_on_the_bench(tmp_path, capsys):
    """A URDF's <mimic> is a coupling (tests/test_couplings.py): the bench moves the shoulder alone,
    MuJoCo's joint equality moves the elbow, and the engines agree on the shoulder's torque through G
    and on the coupling's generalised force (MuJoCo's qfrc_constraint), nothing said on the terminal.
    Read as a joint of its own ([urdf] mimic = "independent") it is moved on its own, said once."""
    mimic = '<child link="fore"/>\n    <mimic joint="shoulder" multiplier="-0.7" offset="0.2"/>'
    (tmp_path / "arm.urdf").write_text(EXAMPLE_URDF.read_text().replace('<child link="fore"/>', mimic))
    (tmp_path / "arm.toml").write_text('[urdf]\nfile = "arm.urdf"\n')
    gates = "".join(f'[[gates]]\nmetric = "{m}"\nlimit = 1e-9\n' for m in (
        "torques.pinocchio_vs_mujoco.max_rel_error", "torques.closed_chain.loop_forces_vs_mujoco_max_rel_error"))
    (tmp_path / "s.toml").write_text('[scenario]\nmodel = "arm.toml"\nduration = 0.5\noutput_steps = 10\n'
                                     '[motion.shoulder]\ntype = "sinusoids"\noffset = 0.1\nsin = [[0.5, 3.0]]\n'
                                     + gates)
    assert main(["run", str(tmp_path / "s.toml"), "--out", str(tmp_path / "out"), "--quiet"]) == 0
    assert "mimics" not in capsys.readouterr().err
    results = json.loads((tmp_path / "out" / "results.json").read_text())
    assert results["torques"]["closed_chain"]["loops"] == {"mimic_elbow": {
        "type": "joint", "follower": "elbow", "leader": "shoulder", "ratio": -0.7, "offset": 0.2}}
    assert results["torques"]["closed_chain"]["loop_gap_max"] <= 1e-7  # MuJoCo's soft coupling's gap, rad
    (tmp_path / "arm.toml").write_text('[urdf]\nfile = "arm.urdf"\nmimic = "independent"\n')
    scenario = (tmp_path / "s.toml").read_text().replace("[[gates]]", '[motion.elbow]\ntype = "locked"\n[[gates]]', 1)
    (tmp_path / "s.toml").write_text(scenario.replace("torques.closed_chain.loop_forces_vs_mujoco_max_rel_error",
                                                      "torques.pinocchio_vs_mujoco.max_rel_error"))
    assert main(["run", str(tmp_path / "s.toml"), "--out", str(tmp_path / "out2"), "--quiet"]) == 0
    assert capsys.readouterr().err.count("joint 'elbow' mimics 'shoulder'") == 1
    notes = json.loads((tmp_path / "out2" / "results.json").read_text())["scenario"]["model_notes"]
    assert [n.startswith("joint 'elbow' mimics 'shoulder'") for n in notes] == [True]


def test_a_massless_link_fixed_to_a_body_adds_its_rotational_inertia(tmp_path):
    """A link of zero mass with an inertia tensor, fixed to the forearm (a sensor's housing, say),
    is part of the forearm: its moments add to the forearm's about their common centre of mass."""
    text = EXAMPLE_URDF.read_text().replace("</robot>", '''  <joint name="mount" type="fixed">
    <parent link="fore"/>
    <child link="housing"/>
    <origin xyz="0.4 0 0" rpy="0 0 0"/>
  </joint>
  <link name="housing">
    <inertial>
      <mass value="0"/>
      <inertia ixx="0.002" ixy="0" ixz="0" iyy="0.002" iyz="0" izz="0.002"/>
    </inertial>
  </link>
</robot>''')
    (tmp_path / "arm.urdf").write_text(text)
    (tmp_path / "arm.toml").write_text('[urdf]\nfile = "arm.urdf"\n')
    (tmp_path / "plain.urdf").write_text(EXAMPLE_URDF.read_text())
    (tmp_path / "plain.toml").write_text('[urdf]\nfile = "plain.urdf"\n')
    with_housing, plain = load_spec(tmp_path / "arm.toml").body("fore"), load_spec(tmp_path / "plain.toml").body("fore")
    assert with_housing.mass == plain.mass
    np.testing.assert_allclose(np.sort(np.diag(with_housing.I_B)), np.sort(np.diag(plain.I_B)) + 0.002, rtol=1e-12)


@pytest.mark.slow  # a few seconds: a whole pipeline or a subprocess
def test_the_written_excitation_holds_every_limit_and_starts_and_ends_at_rest(tmp_path, capsys):
    """`harness excite ur5_excitation` writes one period of the optimised trajectory. Checked on the
    CSV alone with Pinocchio's own URDF model (its position, velocity and effort limits, its RNEA):
    every sample within every limit, the scenario's 8 rad/s^2 too, and q', q'' zero (to 1e-9) at
    both ends. The optimisation improves the condition number it reports."""
    import pandas as pd

    out = tmp_path / "traj.csv"
    assert main(["excite", str(SCENARIOS / "ur5_excitation.toml"), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "at rest at both ends" in printed
    df = pd.read_csv(out)
    model = pin.buildModelFromUrdf(str(example_robot_data_path("ur5")))
    model.gravity.linear = np.array([0.0, 0.0, -9.80665])
    names = [model.names[i] for i in range(1, model.njoints)]
    q, qd, qdd = (df[[f"{k}_{j}" for j in names]].to_numpy() for k in ("q", "qd", "qdd"))
    assert np.all(q >= model.lowerPositionLimit) and np.all(q <= model.upperPositionLimit)
    assert np.all(np.abs(qd) <= model.velocityLimit)
    assert np.all(np.abs(qdd) <= 8.0)
    data = model.createData()
    tau = np.array([pin.rnea(model, data, q[k], qd[k], qdd[k]) for k in range(len(q))])
    assert np.all(np.abs(tau) <= model.effortLimit)
    for row in (0, -1):
        assert np.max(np.abs(qd[row])) < 1e-9 and np.max(np.abs(qdd[row])) < 1e-9
    assert df["t"].iloc[-1] == pytest.approx(2 * np.pi / 0.8)


def test_d_optimality_raises_the_information_and_keeps_the_limits():
    """The other criterion: -log det of the scaled information matrix per parameter falls from the
    seeded start, and the limits hold (40 evaluations keep the test short)."""
    import dataclasses

    from harness.api import load_scenario
    from harness.identify.excitation import _criterion, _series, at_rest, optimise
    from harness.identify.torque_id import structural_base

    sc = load_scenario(SCENARIOS / "ur5_excitation.toml")
    from harness.stages.shared import with_friction

    settings = dataclasses.replace(sc.excitation, criterion="d-optimality", evaluations=40)
    optimised, report = optimise(sc, settings, with_friction(sc))
    assert report["criterion"] == "d-optimality"
    assert max(report["largest_fraction_of_limits"].values()) <= 1.0
    pm = build_model(sc.robot, sc.gravity_W)
    base = structural_base(pm, sc.robot.limits)
    t = np.linspace(0, 2 * np.pi / 0.8, 60, endpoint=False)
    q_opt = np.column_stack([m.evaluate(t)[0] for m in optimised.motion.values()])
    qd_opt = np.column_stack([m.evaluate(t)[1] for m in optimised.motion.values()])
    qdd_opt = np.column_stack([m.evaluate(t)[2] for m in optimised.motion.values()])
    rng = np.random.default_rng(sc.excitation.seed)
    lim = np.clip(np.array([sc.robot.limits[j] for j in sc.robot.joint_names]), -np.pi, np.pi)
    half = (lim[:, 1] - lim[:, 0]) / 2
    x0 = rng.uniform(-1, 1, (6, 2, 2)) * 0.3 * half[:, None, None] * 0.8
    start = _criterion(pm, *_series(at_rest(x0), lim.mean(axis=1), 0.8, t), base, "d-optimality")
    assert _criterion(pm, q_opt, qd_opt, qdd_opt, base, "d-optimality") < start
    assert dataclasses.is_dataclass(optimised)
