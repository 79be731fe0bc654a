"""Floating bases (harness/model/floating.py, harness/engines/floating.py): the harness's convention
mapped to MuJoCo's free joint and Pinocchio's free-flyer, checked against a single free body's
Newton-Euler equations in closed form, the engines against each other, and the files' own readings
(MuJoCo's model of an MJCF file, Pinocchio's parsers) at random states with unit quaternions."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from harness.base.numerics import largest_relative_difference
from harness.engines import floating as engines
from harness.model import floating, quaternion
from harness.model.kinematics import cross
from harness.model.load import spec_from_data
from tests.conftest import ROOT

GRAVITY_W = np.array([0.0, 0.0, -9.81])

# a free body whose frame is tilted and off the origin, its centre of mass off its frame's origin and
# its principal axes tilted again: every convention (quaternion order, velocity and force frames) matters
BRICK = """<mujoco model="brick">
  <worldbody>
    <body name="brick" pos="0.3 -0.1 1.2" quat="0.9 0.2 -0.3 0.1">
      <freejoint name="free"/>
      <inertial pos="0.05 -0.02 0.03" quat="0.8 0.1 0.4 -0.2" mass="2.5" diaginertia="0.03 0.02 0.011"/>
    </body>
  </worldbody>
</mujoco>"""

# a quadruped's trunk (tilted in the file) with a leg, a plate fixed to it and a two-hinge arm
DOG = """<mujoco model="dog">
  <worldbody>
    <body name="trunk" pos="0.1 -0.2 0.5" euler="0.3 -0.2 0.4">
      <freejoint name="root"/>
      <geom type="box" size="0.2 0.1 0.05" mass="5"/>
      <body name="plate" pos="0.05 0 0.06"><geom type="box" size="0.05 0.05 0.01" mass="0.5" pos="0.01 0.02 0"/></body>
      <body name="thigh" pos="0.2 0.1 0">
        <joint name="hip" type="hinge" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0 0 -0.2" size="0.02" mass="0.8"/>
        <body name="shin" pos="0 0 -0.2">
          <joint name="knee" type="hinge" axis="0 1 0"/>
          <geom type="capsule" fromto="0 0 0 0.02 0 -0.2" size="0.015" mass="0.4"/>
        </body>
      </body>
      <body name="arm" pos="-0.2 -0.1 0">
        <joint name="a1" type="hinge" axis="1 0 0"/>
        <joint name="a2" type="hinge" axis="0 0 1"/>
        <geom type="capsule" fromto="0 0 0 -0.1 0 -0.15" size="0.02" mass="0.6"/>
      </body>
    </body>
  </worldbody>
</mujoco>"""


def _mjcf(tmp_path: Path, xml: str):
    (tmp_path / "robot.xml").write_text(xml)
    return spec_from_data({"mjcf": {"file": "robot.xml"}}, tmp_path / "robot.toml")


def test_random_base_states_have_unit_quaternions_spread_over_so3():
    """Normalised Gaussian quaternions (w >= 0): unit to round-off, and their rotations' mean is near
    zero (a uniform distribution on SO(3) has E[R] = 0; 2,000 draws: each entry's standard error 0.013)."""
    base = floating.random_base_motion(2000, seed=4)
    assert np.abs(np.linalg.norm(base.quat_wxyz, axis=1) - 1.0).max() <= 1e-15 and base.quat_wxyz[:, 0].min() >= 0.0
    assert np.abs(base.R_WB.mean(axis=0)).max() <= 0.05


def test_a_free_body_s_base_rows_are_its_newton_euler_equations(tmp_path):
    """A single free body: the world's wrench on it is F = m (a_c - g) and, about its frame's origin,
    M = I_W alpha + omega x I_W omega + r x F (r from the origin to the centre of mass, world axes), at 50
    random states, in both engines: to 1e-12 of the largest (round-off ~1e-15). A wrong quaternion order,
    velocity frame or force frame in either engine's mapping is off by the order of the values."""
    spec = _mjcf(tmp_path, BRICK)
    assert spec.joints == () and spec.floating.joint == "free"
    body, R_WF0, p_WF0 = spec.floating.body, spec.floating.R_WF0, spec.floating.p_WF0
    c_F = R_WF0.T @ (body.p_W_com0 - p_WF0)  # the centre of mass in the base frame
    I_F = R_WF0.T @ body.R_WB0 @ body.I_B @ body.R_WB0.T @ R_WF0
    base = floating.random_base_motion(50, seed=7)
    R = base.R_WB
    r = R @ c_F
    w, alpha = base.omega_W, base.alpha_W
    a_c = base.a_W + cross(alpha, r) + cross(w, cross(w, r))
    F = body.mass * (a_c - GRAVITY_W)
    I_W = R @ I_F @ np.swapaxes(R, 1, 2)
    Iw = np.einsum("nij,nj->ni", I_W, w)
    M = np.einsum("nij,nj->ni", I_W, alpha) + cross(w, Iw) + cross(r, F)
    expected = np.concatenate([F, M], axis=1)
    none = np.zeros((50, 0))
    for engine in engines.ENGINES:
        got = engines.inverse_dynamics(spec, GRAVITY_W, base, none, none, none, engine).base
        assert np.abs(got - expected).max() <= 1e-12 * np.abs(expected).max(), engine


def test_the_two_engines_and_the_files_own_readings_agree_on_a_floating_robot(tmp_path):
    """A trunk on a free joint with a leg and a two-hinge arm: MuJoCo's free joint and Pinocchio's
    free-flyer, built from the harness's reading, with a wrench on the trunk and on the arm; Pinocchio's own
    MJCF parser with its free-flyer; MuJoCo's own model of the file: the base rows and the joints' torques
    at 100 random states, and the mass matrices, to 1e-12 (round-off ~1e-15), through `harness audit`,
    which also judges the robot with its base fixed at the file's pose against Pinocchio's parser held
    there."""
    from harness.runner.audit import audit

    _mjcf(tmp_path, DOG)
    row = audit("dog", tmp_path / "robot.xml")
    assert row.verdict == "agrees", row.reason
    assert row.root.startswith("floating") and set(row.floating) == {
        "floating_engines", "floating_mass_matrix", "floating_vs_pinocchio_parser", "floating_vs_mujoco_file"}
    assert max(row.floating.values()) <= 1e-12
    assert row.torques_vs_pinocchio <= 1e-12  # fixed at the file's (tilted) pose, as Pinocchio's parser is held


def test_the_floating_robot_s_external_wrench_is_what_the_base_rows_lose(tmp_path):
    """A wrench on the trunk changes the base rows by exactly that wrench moved to the base origin, and the
    joints' torques not at all (Pinocchio, 20 random states, to 1e-12)."""
    spec = _mjcf(tmp_path, DOG)
    base = floating.random_base_motion(20, seed=3)
    rng = np.random.default_rng(5)
    q, qd, qdd = rng.uniform(-1, 1, (3, 20, len(spec.joints)))
    F, M = rng.normal(size=(20, 3)), rng.normal(size=(20, 3))
    free = engines.inverse_dynamics(spec, GRAVITY_W, base, q, qd, qdd, "pinocchio")
    pushed = engines.inverse_dynamics(spec, GRAVITY_W, base, q, qd, qdd, "pinocchio",
                                      (engines.Wrench("trunk", F, M),))
    c_W = base.p_W + np.einsum("nij,j->ni", base.R_WB, spec.floating.R_WF0.T @ (spec.floating.body.p_W_com0
                                                                                - spec.floating.p_WF0))
    wrench_at_origin = np.concatenate([F, M + cross(c_W - base.p_W, F)], axis=1)
    assert np.abs(free.base - pushed.base - wrench_at_origin).max() <= 1e-12 * np.abs(free.base).max()
    assert np.abs(free.tau - pushed.tau).max() <= 1e-12 * np.abs(free.tau).max()


ARM_URDF = ROOT / "examples" / "two_link_arm" / "two_link_arm.urdf"
FLOATING_JOINT = """<link name="world"/>
  <joint name="float" type="floating">
    <parent link="world"/>
    <child link="base"/>
    <origin xyz="0.1 0.2 0.8" rpy="0.3 0.1 -0.2"/>
  </joint>
  <link name="base">
    <inertial>
      <origin xyz="0.02 -0.01 0.05" rpy="0.1 0 0.2"/>
      <mass value="4.0"/>
      <inertia ixx="0.05" ixy="0.001" ixz="0" iyy="0.04" iyz="0.002" izz="0.03"/>
    </inertial>
  </link>"""


@pytest.mark.parametrize("how", ["floating joint", "floating = true"])
def test_a_urdf_floating_base_is_read_and_judged(tmp_path, how):
    """A URDF's `floating` joint from its root link, or a model file's `floating = true` for its root link:
    the base is the link (with its inertial), its frame where the file draws it; fixed at that pose for a
    fixed-base reading, said in one note; free, the engines and Pinocchio's own URDF parser agree to 1e-12."""
    from harness.runner.audit import audit

    if how == "floating joint":
        (tmp_path / "arm.urdf").write_text(ARM_URDF.read_text().replace('<link name="base"/>', FLOATING_JOINT))
        (tmp_path / "arm.toml").write_text('[urdf]\nfile = "arm.urdf"\n')
        joint, pose = "float", np.array([0.1, 0.2, 0.8])
    else:
        base_link = FLOATING_JOINT[FLOATING_JOINT.index('<link name="base">'):]
        (tmp_path / "arm.urdf").write_text(ARM_URDF.read_text().replace('<link name="base"/>', base_link))
        (tmp_path / "arm.toml").write_text('[urdf]\nfile = "arm.urdf"\nfloating = true\n')
        joint, pose = "root_joint", np.zeros(3)
    row = audit("arm", tmp_path / "arm.toml")
    spec = spec_from_data({"urdf": {"file": "arm.urdf", **({"floating": True} if how != "floating joint" else {})}},
                          tmp_path / "arm.toml")
    assert spec.floating.joint == joint and spec.floating.body.mass == 4.0
    np.testing.assert_allclose(spec.floating.p_WF0, pose, atol=1e-15)
    assert [n.endswith("taken as fixed to the world at the file's pose") for n in spec.notes] == [True]
    assert row.verdict == "agrees", row.reason
    assert max(row.floating.values()) <= 1e-12 and "floating_vs_pinocchio_parser" in row.floating


def test_the_conventions_round_trip_through_each_engine():
    """MuJoCo's and Pinocchio's base coordinates back to the harness's, by the relations the module
    docstring states (a mutant of any of them breaks one of these): position, orientation (either
    quaternion order), twist and acceleration to round-off."""
    base = floating.random_base_motion(30, seed=9)
    R = base.R_WB
    qpos, qvel, qacc = floating.to_mujoco(base)
    q, v, a = floating.to_pinocchio(base)
    np.testing.assert_allclose(quaternion.to_matrix(qpos[:, 3:]), R, atol=1e-15)
    np.testing.assert_allclose(quaternion.to_matrix(q[:, [6, 3, 4, 5]]), R, atol=1e-15)
    np.testing.assert_allclose(qvel[:, :3], base.v_W, atol=1e-15)
    np.testing.assert_allclose(qacc[:, :3], base.a_W, atol=1e-15)
    np.testing.assert_allclose(np.einsum("nij,nj->ni", R, qacc[:, 3:]), base.alpha_W, atol=1e-14)
    np.testing.assert_allclose(np.einsum("nij,nj->ni", R, qvel[:, 3:]), base.omega_W, atol=1e-14)
    np.testing.assert_allclose(np.einsum("nij,nj->ni", R, v[:, :3]), base.v_W, atol=1e-14)
    np.testing.assert_allclose(np.einsum("nij,nj->ni", R, v[:, 3:]), base.omega_W, atol=1e-14)
    # Pinocchio's a is the derivative of v in base axes: a_W = R (a_B + omega_B x v_B)
    np.testing.assert_allclose(np.einsum("nij,nj->ni", R, a[:, :3] + cross(v[:, 3:], v[:, :3])), base.a_W, atol=1e-13)


def test_a_scenario_moves_its_floating_base_and_judges_the_world_s_wrench_on_it(tmp_path, capsys):
    """`harness run` on the trunk-and-legs MJCF with a [base_motion]: the bench moves the base on its free
    joint (said once on the terminal) and records the world's wrench on it; Pinocchio's free-flyer and the
    graph-theory model, given the recorded states, find that wrench and the joints' torques to 1e-9
    (round-off ~1e-14; the joints' friction and rotor inertia on the bench and in both), the base follows
    [base_motion] to 1e-9 m and rad (the integrator's error ~1e-12), and recording.csv reads back with the
    base's columns."""
    import json

    from harness.base.series import read_csv
    from harness.cli import main

    (tmp_path / "robot.xml").write_text(DOG.replace('<joint name="a2" type="hinge" axis="0 0 1"/>', ""))
    (tmp_path / "m.toml").write_text('[mjcf]\nfile = "robot.xml"\n'  # friction and rotor inertia on the joints
                                     '[joints.hip]\narmature = 0.01\nviscous = 0.05\ncoulomb = 0.2\n'
                                     '[joints.knee]\narmature = 0.02\ncoulomb = 0.1\noffset = 0.05\n')
    motion = "".join(f'[motion.{j}]\ntype = "sinusoids"\noffset = 0.1\nsin = [[0.5, {w}]]\n'
                     for j, w in (("hip", 3.0), ("knee", 4.0), ("a1", 2.0)))
    motion += '[model_under_test]\nname = "graph"\nplugin = "graph_theory_2021"\n'
    gates = "".join(f'[[gates]]\nmetric = "torques.{m}"\nlimit = {v}\n' for m, v in (
        ("pinocchio_vs_mujoco.max_rel_error", 1e-9), ("graph_vs_mujoco.max_rel_error", 1e-9),
        ("floating.engines_max_rel_error", 1e-9), ("floating.mass_matrix_max_rel_error", 1e-12),
        ("floating.graph_vs_pinocchio_max_rel_error", 1e-9),
        ("floating.base_wrench_pinocchio_vs_mujoco_max_rel_error", 1e-9),
        ("floating.base_wrench_graph_vs_mujoco_max_rel_error", 1e-9),
        ("floating.base_tracking_position_m", 1e-9), ("floating.base_tracking_angle_rad", 1e-9)))
    head = '[scenario]\nmodel = "m.toml"\nduration = 0.2\noutput_steps = 20\n'
    base = ('[base_motion.yaw]\ntype = "sinusoids"\noffset = 0.3\nsin = [[1.0, 2.0]]\n'
            '[base_motion.z]\ntype = "sinusoids"\noffset = 0.0\nsin = [[0.05, 6.0]]\n'
            '[base_motion.pitch]\ntype = "sinusoids"\noffset = 0.2\ncos = [[0.4, 3.0]]\n')
    (tmp_path / "s.toml").write_text(head + motion + base + gates)
    assert main(["run", str(tmp_path / "s.toml"), "--out", str(tmp_path / "out"), "--quiet"]) == 0
    err = capsys.readouterr().err
    assert err.count("the bench moves the floating base along [base_motion]") == 1 and "fixed to the world" not in err
    fl = json.loads((tmp_path / "out" / "results.json").read_text())["torques"]["floating"]
    assert (fl["base"], fl["joint"], fl["states"]) == ("trunk", "root", 20) and fl["base_motion"].startswith("recorded")
    rec = read_csv(tmp_path / "out" / "recording.csv")
    assert rec.base_pose.shape == (21, 7) and rec.base_wrench_W.shape == (21, 6)
    assert np.abs(rec.base_wrench_W[:, 2]).min() > 1.0  # the weight is carried by the world's wrench
    assert "The bench moved the base along [base_motion]" in (tmp_path / "out" / "report.html").read_text()
    # a base motion the bench cannot follow (a heave of 1e12 m) is bad input naming [base_motion]
    (tmp_path / "s.toml").write_text(head + motion + base.replace("sin = [[0.05, 6.0]]", "sin = [[1e12, 6.0]]") + gates)
    assert main(["run", str(tmp_path / "s.toml"), "--out", str(tmp_path / "big"), "--quiet"]) == 2
    assert "s.toml: base_motion: drives the simulation to non-finite values" in capsys.readouterr().err


def test_a_floating_robot_with_drives_is_moved_by_its_motors_as_pinocchio_says(tmp_path):
    """The trunk's three joints driven through [drives] (gear ratios of either sign, the knee's motor also turning
    with the hip, each motor's rotor inertia, viscous, Coulomb (smooth) friction and offset, and a Coulomb term that
    grows with the load on the coupled motor), the base moved: the bench's joint torques and the world's wrench on
    the base are Pinocchio's free-flyer inverse dynamics with the drives' laws through N (harness/model/drives.py)
    at the recorded states, to 1e-9 of each one's largest (round-off ~1e-14), and not the rigid bodies' alone
    (the drives' terms are over 1e-3 of the torques here). A motor with rotor inertia turning the hip and the arm's
    joint (separate branches, which MuJoCo's tendon armature cannot couple) is refused in one line naming it."""
    from harness.base.tomlio import InputError
    from harness.engines.pinocchio import build_model, rnea
    from harness.runner.scenario import load_scenario
    from harness.sources.bench import record

    (tmp_path / "robot.xml").write_text(DOG.replace('<joint name="a2" type="hinge" axis="0 0 1"/>', ""))
    laws = "".join(f"[drives.motor_{k}]\narmature = {a}\nviscous = {v}\ncoulomb = {c}\noffset = 0.002\n"
                   f"coulomb_velocity = 0.5\n" for k, a, v, c in ((1, 1e-4, 1e-3, 0.01), (2, 2e-4, 2e-3, 0.02),
                                                                  (3, 5e-5, 5e-4, 0.005)))
    drives = '[mjcf]\nfile = "robot.xml"\n[drives]\ngear_ratio = [20, 10, -15]\n'  # hip, a1, knee
    (tmp_path / "m.toml").write_text(drives + 'coupling = [{ motor = "motor_3", joint = "hip", ratio = 5 }]\n'
                                     + laws + "load_coulomb = 0.01\n")
    motion = "".join(f'[motion.{j}]\ntype = "sinusoids"\noffset = 0.1\nsin = [[0.5, {w}]]\n'
                     for j, w in (("hip", 3.0), ("knee", 4.0), ("a1", 2.0)))
    base = ('[base_motion.yaw]\ntype = "sinusoids"\noffset = 0.3\nsin = [[1.0, 2.0]]\n'
            '[base_motion.z]\ntype = "sinusoids"\nsin = [[0.05, 6.0]]\n'
            '[base_motion.pitch]\ntype = "sinusoids"\noffset = 0.2\ncos = [[0.4, 3.0]]\n')
    gate = '[[gates]]\nmetric = "torques.pinocchio_vs_mujoco.max_rel_error"\nlimit = 1e-9\n'
    (tmp_path / "s.toml").write_text('[scenario]\nmodel = "m.toml"\nduration = 0.3\noutput_steps = 30\n'
                                     + motion + base + gate)
    sc = load_scenario(tmp_path / "s.toml")
    assert sc.robot.transmission is not None and sc.robot.floating is not None
    rec = record(sc)
    moved = floating.BaseMotion.from_rows(rec.base_pose, rec.base_twist_W, rec.base_rate_W)
    ref = rnea(build_model(sc.robot, sc.gravity_W, floating=True), rec.q, rec.qd, rec.qdd, base=moved)
    rigid = rnea(build_model(sc.robot.rigid(), sc.gravity_W, floating=True), rec.q, rec.qd, rec.qdd, base=moved)
    assert largest_relative_difference(ref.tau, rec.tau) <= 1e-9
    assert largest_relative_difference(ref.base, rec.base_wrench_W) <= 1e-9
    assert largest_relative_difference(rigid.tau, rec.tau) > 1e-3
    (tmp_path / "m.toml").write_text(drives + 'coupling = [{ motor = "motor_2", joint = "hip", ratio = 5 }]\n' + laws)
    with pytest.raises(InputError) as err:
        record(load_scenario(tmp_path / "s.toml"))
    assert err.value.key == "model" and "[drives.motor_2]" in str(err.value) and "'hip' and 'a1'" in str(err.value)


def test_the_bench_s_wrench_on_a_rigidly_held_robot_is_its_composite_body_s_newton_euler(tmp_path):
    """The trunk with its joints locked (held at 0 by the drive) is one rigid body: the world's wrench the
    bench applies to its base while moving it is F = m (a_c - g), M = I_W alpha + omega x I_W omega + r x F
    about the base frame's origin, with the composite mass, centre of mass and inertia summed from the
    model's bodies (the parallel-axis theorem), in closed form at the recorded base states: to 1e-9 of the
    largest (round-off and the joints' tracking, ~1e-12). The moment left in base axes, or the base's
    angular velocity read as MuJoCo's body-axes one, is off by the order of the values."""
    from harness.runner.scenario import load_scenario
    from harness.sources.bench import record

    (tmp_path / "robot.xml").write_text(DOG)
    (tmp_path / "m.toml").write_text('[mjcf]\nfile = "robot.xml"\n')
    motion = "".join(f'[motion.{j}]\ntype = "locked"\n' for j in ("hip", "knee", "a1", "a2"))
    base = "".join(f'[base_motion.{a}]\ntype = "sinusoids"\noffset = {o}\nsin = [[{s}, {w}]]\n' for a, o, s, w in (
        ("x", 0.1, 0.2, 2.0), ("z", 0.0, 0.1, 5.0), ("roll", 0.4, 0.8, 3.0), ("pitch", -0.3, 0.6, 2.5),
        ("yaw", 1.0, 1.2, 1.5)))
    (tmp_path / "s.toml").write_text('[scenario]\nmodel = "m.toml"\nduration = 0.5\noutput_steps = 50\n'
                                     '[[gates]]\nmetric = "torques.pinocchio_vs_mujoco.max_rel_error"\nlimit = 1e-9\n'
                                     + motion + base)
    sc = load_scenario(tmp_path / "s.toml")
    rec = record(sc)
    spec, fb = sc.robot, sc.robot.floating
    bodies = [fb.body, *spec.massive_bodies]
    m = sum(b.mass for b in bodies)
    c_W0 = sum(b.mass * b.p_W_com0 for b in bodies) / m  # at the file's pose, q = 0
    I_W0 = sum(b.R_WB0 @ b.I_B @ b.R_WB0.T + b.mass * ((b.p_W_com0 - c_W0) @ (b.p_W_com0 - c_W0) * np.eye(3)
                                                       - np.outer(b.p_W_com0 - c_W0, b.p_W_com0 - c_W0))
               for b in bodies)
    c_F, I_F = fb.R_WF0.T @ (c_W0 - fb.p_WF0), fb.R_WF0.T @ I_W0 @ fb.R_WF0
    base = floating.BaseMotion.from_rows(rec.base_pose, rec.base_twist_W, rec.base_rate_W)
    R, w, alpha = base.R_WB, base.omega_W, base.alpha_W
    r = R @ c_F
    F = m * (base.a_W + cross(alpha, r) + cross(w, cross(w, r)) - sc.gravity_W)
    I_W = R @ I_F @ np.swapaxes(R, 1, 2)
    M = np.einsum("nij,nj->ni", I_W, alpha) + cross(w, np.einsum("nij,nj->ni", I_W, w)) + cross(r, F)
    expected = np.concatenate([F, M], axis=1)
    assert np.abs(rec.base_wrench_W - expected).max() <= 1e-9 * np.abs(expected).max()
    assert np.abs(rec.q).max() <= 1e-9


class _FixedOnly:
    def __init__(self, spec):
        self.joint_names = list(spec.joint_names)

    def inverse_dynamics(self, q, qd, qdd):
        return np.zeros_like(q)


def fixed_only(robot, gravity_W=None):
    """A model under test that answers with the base fixed only (the refusal test's)."""
    return _FixedOnly(robot)


def _trajectory():
    from harness.base.tomlio import Table
    from harness.model.spec import Body, FloatingBase
    from harness.sources.base_motion import read_base_motion

    tilt = quaternion.to_matrix(np.array([0.9, 0.2, -0.3, 0.1]) / np.linalg.norm([0.9, 0.2, -0.3, 0.1]))
    fb = FloatingBase("root", Body("trunk", 1.0, np.eye(3), np.eye(3), np.zeros(3)), tilt, np.array([0.1, -0.2, 0.5]))
    table = {"x": {"type": "sinusoids", "offset": 0.05, "sin": [[0.2, 1.5]]},
             "z": {"type": "polynomial", "coefficients": [0.0, 0.3, -0.2]},
             "roll": {"type": "sinusoids", "offset": 0.1, "sin": [[0.6, 3.0]], "cos": [[0.2, 1.1]]},
             "pitch": {"type": "sinusoids", "offset": 1.4, "sin": [[0.5, 2.3]]},  # through pitch = pi / 2
             "yaw": {"type": "polynomial", "coefficients": [0.3, -1.0, 0.8]}}
    return read_base_motion(Table(table, Path("s.toml"), "base_motion"), fb)


def test_a_prescribed_base_motion_s_twist_and_acceleration_are_its_pose_s_derivatives():
    """[base_motion]'s base twist and acceleration (exact, harness/sources/base_motion.py) against central
    differences of its pose (h = 1e-5 s: truncation ~ h^2 |x'''| ~ 1e-9, round-off ~ eps / h ~ 1e-11; bound
    1e-7), through pitch = pi/2, where roll-pitch-yaw angles would be singular and the product of rotations
    is not; every quaternion unit (a product of rotations, never a sum of quaternions)."""
    trajectory = _trajectory()
    t, h = np.linspace(0.0, 2.0, 41), 1e-5
    now, ahead, behind = (trajectory.evaluate(t + d) for d in (0.0, h, -h))
    assert np.abs(np.linalg.norm(now.quat_wxyz, axis=1) - 1.0).max() <= 1e-15
    dR = (ahead.R_WB - behind.R_WB) / (2 * h) @ np.swapaxes(now.R_WB, 1, 2)  # [omega_W]x
    omega = np.stack([dR[:, 2, 1], dR[:, 0, 2], dR[:, 1, 0]], axis=1)
    np.testing.assert_allclose(omega, now.omega_W, atol=1e-7)
    np.testing.assert_allclose((ahead.omega_W - behind.omega_W) / (2 * h), now.alpha_W, atol=1e-7)
    np.testing.assert_allclose((ahead.p_W - behind.p_W) / (2 * h), now.v_W, atol=1e-7)
    np.testing.assert_allclose((ahead.v_W - behind.v_W) / (2 * h), now.a_W, atol=1e-7)
    at_rest = trajectory.evaluate(np.zeros(1))
    expected = quaternion.from_matrix(trajectory.R_WF0 @ _rotation(0, 0.1 + 0.2) @ _rotation(1, 1.4)
                                      @ _rotation(2, 0.3))
    np.testing.assert_allclose(at_rest.quat_wxyz[0], expected, atol=1e-15)


def _rotation(axis: int, angle: float) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    return Rotation.from_rotvec(angle * np.eye(3)[axis]).as_matrix()


def test_a_base_motion_for_a_robot_without_a_floating_base_or_of_another_coordinate_is_refused(tmp_path):
    from harness.base.tomlio import InputError
    from harness.runner.scenario import load_scenario

    (tmp_path / "robot.xml").write_text(DOG)
    (tmp_path / "fixed.xml").write_text(DOG.replace('<freejoint name="root"/>', ""))
    motion = "".join(f'[motion.{j}]\ntype = "locked"\n' for j in ("hip", "knee", "a1", "a2"))
    for model, base, key, said in (("fixed.xml", "[base_motion.x]\ntype = \"locked\"\n", "base_motion",
                                    "has no floating base"),
                                   ("robot.xml", "[base_motion.surge]\ntype = \"locked\"\n", "base_motion.surge",
                                    "unknown key"),
                                   ("robot.xml", "[base_motion.x]\ntype = \"locked\"\n[estimators]\n",
                                    "estimators", "base is fixed"),
                                   ("robot.xml", "[base_motion.x]\ntype = \"locked\"\n[model_under_test]\nname = "
                                    "\"mine\"\npython = \"tests.test_floating:fixed_only\"\n[[gates]]\nmetric = "
                                    "\"torques.mine_vs_mujoco.max_rel_error\"\nlimit = 1e-9\n", "model_under_test",
                                    "no floating_inverse_dynamics")):
        (tmp_path / "m.toml").write_text(f'[mjcf]\nfile = "{model}"\n')
        gate = '[[gates]]\nmetric = "torques.pinocchio_vs_mujoco.max_rel_error"\nlimit = 1e-9\n'
        (tmp_path / "s.toml").write_text('[scenario]\nmodel = "m.toml"\nduration = 0.2\noutput_steps = 20\n'
                                         + motion + base + gate)
        with pytest.raises(InputError) as err:
            load_scenario(tmp_path / "s.toml")
        assert err.value.key == key and said in str(err.value) and "\n" not in err.value.one_line()


@pytest.mark.parametrize("robot", ["mjcf", "urdf"])
def test_the_graph_theory_model_with_its_base_as_a_six_dof_joint_agrees_with_both_engines(tmp_path, robot):
    """The first seed's method with the base as one more body on a six-degree-of-freedom joint to the
    ground (harness/papers/graph_theory_2021/floating.py: the tree's bodies moved by the base's motion, the
    base's own Newton-Euler equations with the joints on it pulling back): its base rows and joint torques
    against Pinocchio's free-flyer and MuJoCo's free joint at 40 random states, and along a prescribed base
    motion through pitch = pi/2, to 1e-12 (round-off ~1e-15). A Coriolis term 2 omega x v left out is off
    by the order of the values."""
    from harness.papers.graph_theory_2021.dynamics import build_graph_model
    from harness.papers.graph_theory_2021.floating import floating_inverse_dynamics

    if robot == "mjcf":  # the trunk with a leg (the two-hinge arm is a carriage the method does not carry)
        spec = _mjcf(tmp_path, DOG.replace('<joint name="a2" type="hinge" axis="0 0 1"/>', ""))
    else:
        (tmp_path / "arm.urdf").write_text(ARM_URDF.read_text().replace('<link name="base"/>', FLOATING_JOINT))
        spec = spec_from_data({"urdf": {"file": "arm.urdf"}}, tmp_path / "arm.toml")
    graph = build_graph_model(spec, GRAVITY_W)
    rng = np.random.default_rng(11)
    for base in (floating.random_base_motion(40, seed=12), _trajectory().evaluate(np.linspace(0.0, 2.0, 40))):
        q, qd, qdd = rng.uniform(-1, 1, (3, 40, len(spec.joints)))
        rows, tau = floating_inverse_dynamics(spec, graph, base, q, qd, qdd)
        for engine in engines.ENGINES:
            ref = engines.inverse_dynamics(spec, GRAVITY_W, base, q, qd, qdd, engine)
            assert largest_relative_difference(rows, ref.base) <= 1e-12, engine
            assert largest_relative_difference(tau, ref.tau) <= 1e-12, engine


@pytest.mark.parametrize("metric", ["torques.floating.mine_vs_pinocchio_max_rel_error",
                                    "torques.floating.base_wrench_mine_vs_mujoco_max_rel_error"])
def test_a_gate_on_a_model_s_floating_figures_judges_it(metric):
    """A model under test judged only with its base free is judged (a scenario refuses one no gate judges)."""
    from harness.runner.gates import Gate
    from harness.runner.judging import judged

    assert judged("model_under_test", "mine", (Gate("g", metric, 1e-9),))
    assert not judged("model_under_test", "other", (Gate("g", metric, 1e-9),))


def test_the_floating_regressor_is_the_free_flyer_s_inverse_dynamics_and_identifies_from_the_base_rows(tmp_path):
    """harness/identify/floating_id.py: Y theta is the floating robot's inverse dynamics (base rows in world
    axes, then the joints) of both engines at 40 random states, to 1e-12 (round-off ~1e-16; the base rows
    left in Pinocchio's base axes are off by the order of the values), and with the joints' drive columns
    Pinocchio's torques plus the drives' law, those columns zero on the base rows. From the base rows alone the trunk
    with a leg and a two-hinge arm has more base parameters than bolted down (the base's own, and what its
    motion excites), and exact data at 60 random states give them to 1e-9 and another 60 states' rows, base
    and joints, to 1e-9 of their largest (round-off through the fit's conditioning); the consistent fit keeps
    every body physical and predicts them to 1e-5, and its MJCF export (a free joint) reads back as the same
    robot in both engines to 1e-12."""
    from harness.engines.pinocchio import build_model
    from harness.identify import floating_id
    from harness.identify.consistent import consistency
    from harness.identify.torque_id import structural_base
    from harness.model.states import random_states

    spec = _mjcf(tmp_path, DOG)
    pm = build_model(spec, GRAVITY_W, floating=True)
    n = len(spec.joints)

    def states(count, seed):
        base = floating.random_base_motion(count, seed)
        return (base, *random_states(-np.ones(n), np.ones(n), np.ones(n), 3 * np.ones(n), count, seed))

    theta = floating_id.true_parameters(pm)
    assert len(theta) == len(floating_id.parameter_names(spec, pm)) == 10 * (1 + len(spec.joints))
    for engine in engines.ENGINES:
        s = states(40, 1)
        ref = engines.inverse_dynamics(spec, GRAVITY_W, *s, engine)
        expected = np.concatenate([ref.base, ref.tau], axis=1)
        assert np.abs(floating_id.regressor(pm, *s) @ theta - expected).max() <= 1e-12 * np.abs(expected).max()
    # the joints' drives: on their own rows alone, as Pinocchio's torques plus the drives' law
    from harness.model import drives
    from harness.model.friction import JointFriction

    law = JointFriction(armature=0.01, viscous=0.05, coulomb=0.2, offset=0.03)
    pm_f = build_model(spec.with_frictions((law,) * n), GRAVITY_W, floating=True)
    s = states(40, 4)
    ref = engines.inverse_dynamics(spec, GRAVITY_W, *s, "pinocchio")
    tau = ref.tau + drives.torque(pm_f.frictions, None, s[2], s[3], ref.tau)
    Y = floating_id.regressor(pm_f, *s, with_friction=True)
    expected = np.concatenate([ref.base, tau], axis=1)
    assert np.abs(Y @ floating_id.true_parameters(pm_f, True) - expected).max() <= 1e-12 * np.abs(expected).max()
    assert not Y[:, :6, len(theta):].any()  # never on the base rows
    fixed = structural_base(build_model(spec, GRAVITY_W), spec.limits)
    for rows in floating_id.ROWS:
        structure = floating_id.structural_base(pm, spec.limits, rows)
        assert len(structure.independent) > len(fixed.independent)
        # found from the base rows alone or from all, the structure holds on every row, the joints' too (a
        # floating base's rows see every base parameter the whole regressor does: Ayusawa, Venture and Nakamura)
        Y = floating_id.selected(floating_id.regressor(pm, *states(30, 6)), "all")
        whole = Y @ theta
        assert np.abs(Y[:, structure.independent] @ structure.of(theta) - whole).max() <= 1e-9 * np.abs(whole).max()

        validation = _exact(spec, states(60, 3), rows)
        training = _exact(spec, states(60, 2), rows)
        fit, beta_true, err = floating_id.identify(pm, structure, rows, training, validation)
        assert np.abs(fit.beta - beta_true).max() <= 1e-9 * np.abs(beta_true).max()
        assert np.abs(err).max() <= 1e-9 * np.abs(validation[-1]).max()
        if rows != "base":
            continue
        # the consistent fit: every body physical, the base's included, and the rows predicted to its pull's
        # cost on exact data (PULL = 1e-4 of the residual, floored at 1e-8 of the rows: 1e-7 measured)
        physical, links = floating_id.consistent(pm, spec, rows, training, False)
        assert links[0] == "trunk" and all(consistency(t)["consistent"] for t in physical.theta)
        predicted = floating_id.consistent_rows(pm, physical, rows, validation, False)
        assert np.abs(predicted - validation[-1]).max() <= 1e-5 * np.abs(validation[-1]).max()
        # exported as an MJCF file on a free joint, read back: the same robot, base and joints, to round-off
        from harness.model.export import identified_floating_spec
        from harness.model.mjcf import write_mjcf

        (tmp_path / "identified.xml").write_text(write_mjcf(identified_floating_spec(spec, physical.theta,
                                                                                     spec.frictions),
                                                            GRAVITY_W, floating=True))
        back = spec_from_data({"mjcf": {"file": "identified.xml"}}, tmp_path / "identified.toml")
        s = states(30, 5)
        expected = floating_id.consistent_rows(pm, physical, "all", s, False)
        for engine in engines.ENGINES:
            ref = engines.inverse_dynamics(back, GRAVITY_W, *s, engine)
            got = np.concatenate([ref.base, ref.tau], axis=1)
            assert np.abs(got - expected).max() <= 1e-12 * np.abs(expected).max()


def _exact(spec, s: tuple, rows: str) -> tuple:
    """(base, q, q', q'', rows measured) of the states s, the rows Pinocchio's free-flyer inverse dynamics'."""
    from harness.identify import floating_id

    ref = engines.inverse_dynamics(spec, GRAVITY_W, *s, "pinocchio")
    return (*s, floating_id.measured(ref.base, ref.tau, rows))


@pytest.mark.slow  # four floating-base runs (1.4 s)
def test_a_moving_base_s_torque_identification_reads_the_base_rows_and_is_judged_on_another_motion(tmp_path):
    """`[torque_identification] rows = "base"` beside [base_motion]: the bench's recorded wrench on the base
    alone (no joint torque) identifies the trunk's base parameters, and the validation motion's wrench is
    predicted to 1e-8 of its largest force and moment (exact recordings through a fit of condition ~1e6);
    results.json says which rows were read and how many base parameters the robot bolted down would have.
    With 1 % noise on that wrench ([measurement.noise.base_wrench]) the fit reads the noisy rows. With the
    joints' torques too, a hip's Coulomb friction is found on its own row. A validation that does not move
    the base, rows on a fixed base, friction from the base rows, a friction family's terms (which that fit
    has no columns for) and noise on a base wrench no bench moved are each refused in one line."""
    import json

    from harness.base.tomlio import InputError
    from harness.cli import main
    from harness.runner.scenario import load_scenario

    (tmp_path / "robot.xml").write_text(DOG.replace('<joint name="a2" type="hinge" axis="0 0 1"/>', ""))
    (tmp_path / "m.toml").write_text('[mjcf]\nfile = "robot.xml"\n')
    (tmp_path / "f.toml").write_text('[mjcf]\nfile = "robot.xml"\n[joints.hip]\ncoulomb = 0.2\n')
    (tmp_path / "sf.toml").write_text('[mjcf]\nfile = "robot.xml"\n[joints.hip]\ncoulomb = 0.2\nstribeck = 0.1\n'
                                      'stribeck_velocity = 0.05\n')

    def motion(scale):
        joints = "".join(f'[motion.{j}]\ntype = "sinusoids"\noffset = 0.1\nsin = [[0.5, {w * scale}], [0.2, {3 * w}]]\n'
                         for j, w in (("hip", 3.0), ("knee", 4.0), ("a1", 2.0)))
        return joints + "".join(f'[base_motion.{a}]\ntype = "sinusoids"\noffset = 0.0\nsin = [[{s}, {w * scale}]]\n'
                                for a, s, w in (("x", 0.05, 2.1), ("y", 0.04, 2.9), ("z", 0.03, 3.7),
                                                ("roll", 0.3, 1.7), ("pitch", 0.3, 2.3), ("yaw", 0.5, 1.1)))

    gate = '[[gates]]\nmetric = "torques.pinocchio_vs_mujoco.max_rel_error"\nlimit = 1e-9\n'
    head = '[scenario]\nmodel = "{}"\nduration = 1.0\noutput_steps = 100\n'
    (tmp_path / "v.toml").write_text(head.format("m.toml") + motion(0.8) + gate)
    (tmp_path / "still.toml").write_text(head.format("m.toml") + motion(0.8).split("[base_motion.x]")[0] + gate)
    fit = '[torque_identification]\nvalidation = "{}"\nrows = "{}"\n'
    (tmp_path / "s.toml").write_text(head.format("m.toml") + motion(1.0) + fit.format("v.toml", "base")
                                     + "consistent = true\n" + gate
                                     + '[[gates]]\nmetric = "torque_identification.validation.max_rel_error"\n'
                                       'limit = 1e-8\n')
    assert main(["run", str(tmp_path / "s.toml"), "--out", str(tmp_path / "out"), "--quiet"]) == 0
    ti = json.loads((tmp_path / "out" / "results.json").read_text())["torque_identification"]
    assert ti["rows"] == "base" and ti["base_parameters"] > ti["fixed_base_parameters"]
    assert ti["validation"]["max_rel_joint"].startswith("base.")
    assert "Identification of the floating robot from the world" in (tmp_path / "out" / "report.html").read_text()
    assert not ti["consistent"]["inconsistent_links"] and ti["consistent"]["validation"]["max_rel_error"] <= 1e-3
    assert ti["consistent"]["exported"] == ["identified/robot.xml"]  # an MJCF robot: no URDF to write into
    exported = spec_from_data({"mjcf": {"file": str(tmp_path / "out" / "identified" / "robot.xml")}},
                              tmp_path / "back.toml")
    assert exported.floating.joint == "root"
    assert exported.floating.body.mass == pytest.approx(ti["consistent"]["masses"]["trunk"]["identified"], rel=1e-12)
    # 1 % noise on the world's wrench on the base (the scenario's and the validation's): the fit reads it
    noisy = "[measurement]\nseed = 3\n[measurement.noise.base_wrench]\nrelative = 0.01\n"
    (tmp_path / "vn.toml").write_text(head.format("m.toml") + motion(0.8) + noisy + gate)
    (tmp_path / "s.toml").write_text(head.format("m.toml") + motion(1.0) + fit.format("vn.toml", "base") + noisy + gate)
    assert main(["run", str(tmp_path / "s.toml"), "--out", str(tmp_path / "n"), "--quiet"]) == 0
    ti = json.loads((tmp_path / "n" / "results.json").read_text())["torque_identification"]
    assert 1e-3 < ti["validation"]["max_rel_error"] < 0.1  # the validation rows' own 1 % (1.8e-2 measured)
    # a hip with Coulomb friction: all rows identify it on the hip's own (the base rows never see it)
    (tmp_path / "fv.toml").write_text(head.format("f.toml") + motion(0.8) + gate)
    (tmp_path / "s.toml").write_text(head.format("f.toml") + motion(1.0) + fit.format("fv.toml", "all") + gate)
    assert main(["run", str(tmp_path / "s.toml"), "--out", str(tmp_path / "out"), "--quiet", "--replace"]) == 0
    ti = json.loads((tmp_path / "out" / "results.json").read_text())["torque_identification"]
    assert ti["rows"] == "all" and ti["friction"]["joints"]["hip"]["coulomb"]["rel_error"] <= 1e-6
    assert ti["validation"]["max_rel_error"] <= 1e-8
    for model, table, key, said in (("m.toml", '[torque_identification]\nvalidation = "still.toml"\n',
                                     "torque_identification", "neither"),
                                    ("f.toml", fit.format("fv.toml", "base") + "friction = true\n",
                                     "torque_identification.friction", "never reach the base rows"),
                                    ("sf.toml", fit.format("fv.toml", "all"), "torque_identification.friction",
                                     "not a friction family's terms: hip (stribeck)")):
        (tmp_path / "s.toml").write_text(head.format(model) + motion(1.0) + table + gate)
        with pytest.raises(InputError) as err:
            load_scenario(tmp_path / "s.toml")
        assert err.value.key == key and said in str(err.value), str(err.value)
    (tmp_path / "s.toml").write_text(head.format("m.toml") + motion(1.0).split("[base_motion.x]")[0]
                                     + fit.format("still.toml", "base") + gate)
    with pytest.raises(InputError) as err:
        load_scenario(tmp_path / "s.toml")
    assert err.value.key == "torque_identification.rows"
    (tmp_path / "s.toml").write_text(head.format("m.toml") + motion(1.0).split("[base_motion.x]")[0] + noisy + gate)
    with pytest.raises(InputError) as err:
        load_scenario(tmp_path / "s.toml")
    assert err.value.key == "measurement.noise.base_wrench"


@pytest.mark.parametrize("how", ["floating joint", "floating = true"])
def test_a_floating_robot_s_consistent_fit_is_exported_as_a_urdf_with_a_floating_joint(tmp_path, how):
    """The two-link arm on a floating base (a URDF floating joint, or its root link made floating): the
    consistent fit of exact base rows at 80 random states, written into the URDF (harness/model/export.py,
    write_urdf with the base's parameters: its link's inertial, the links fixed to it without theirs, a
    floating joint where the file has none) reads back, by the harness's reader and by Pinocchio's own URDF
    parser through it, as the robot the fit predicts: both engines' base rows and joint torques at 30
    random states to 1e-12 of the largest (round-off)."""
    from harness.engines.pinocchio import build_model
    from harness.identify import floating_id
    from harness.model.export import write_urdf
    from harness.model.states import random_states

    base_link = FLOATING_JOINT[0 if how == "floating joint" else FLOATING_JOINT.index('<link name="base">'):]
    (tmp_path / "arm.urdf").write_text(ARM_URDF.read_text().replace('<link name="base"/>', base_link))
    spec = spec_from_data({"urdf": {"file": "arm.urdf", **({"floating": True} if how != "floating joint" else {})}},
                          tmp_path / "arm.toml")
    pm = build_model(spec, GRAVITY_W, floating=True)
    n = len(spec.joints)

    def states(count, seed):
        return (floating.random_base_motion(count, seed),
                *random_states(-np.ones(n), np.ones(n), np.ones(n), 3 * np.ones(n), count, seed))

    physical, _ = floating_id.consistent(pm, spec, "base", _exact(spec, states(80, 1), "base"), False)
    (tmp_path / "identified.urdf").write_text(write_urdf(spec, physical.theta[1:], spec.frictions, physical.theta[0]))
    back = spec_from_data({"urdf": {"file": "identified.urdf"}}, tmp_path / "identified.toml")
    assert back.floating is not None and back.floating.body.mass == pytest.approx(physical.theta[0, 0], rel=1e-12)
    s = states(30, 2)
    expected = floating_id.consistent_rows(pm, physical, "all", s, False)
    for engine in engines.ENGINES:
        ref = engines.inverse_dynamics(back, GRAVITY_W, *s, engine)
        got = np.concatenate([ref.base, ref.tau], axis=1)
        assert np.abs(got - expected).max() <= 1e-12 * np.abs(expected).max(), engine


def test_a_floating_fit_weights_each_row_by_its_own_noise(tmp_path):
    """The DOG's rows read with noise of their own sizes (the base's force 0.5 N, its moment 0.01 N m, the joints'
    torques 0.02 N m; Gaussian, seeded) at 800 random states: floating_id.row_weights finds each row's noise
    within 10 % of what was put in (5.2 % measured; the sampling error of a standard deviation from 800 samples
    is 2.5 %, and the fit takes its share) and weighs each by the inverse of its variance; the weighted fit is
    the least squares of the rows each divided by its own estimated noise, written out here with numpy; and on
    another 200 states' exact rows, the weighted least squares and the weighted consistent fit are each at least
    twice as close as the ordinary ones (measured: 10.0 and 9.8 times). The ordinary fit's residual alone gives
    the moment's rows a third more noise than they have, and the weights' passes remove that."""
    from harness.engines.pinocchio import build_model
    from harness.identify import floating_id
    from harness.model.states import random_states

    spec = _mjcf(tmp_path, DOG)
    pm = build_model(spec, GRAVITY_W, floating=True)
    n = len(spec.joints)

    def states(count, seed):
        return (floating.random_base_motion(count, seed),
                *random_states(-np.ones(n), np.ones(n), np.ones(n), 3 * np.ones(n), count, seed))

    sigma = np.array([0.5] * 3 + [0.01] * 3 + [0.02] * n)
    exact = _exact(spec, states(800, 11), "all")
    noisy = (*exact[:4], exact[4] + sigma * np.random.default_rng(5).standard_normal(exact[4].shape))
    structure = floating_id.structural_base(pm, spec.limits, "all")
    Y = floating_id.regressor(pm, *noisy[:4], with_friction=True)
    weights, noise = floating_id.row_weights(pm, structure, "all", noisy, Y)
    np.testing.assert_allclose(noise, sigma, rtol=0.1)
    assert weights.max() == 1.0 and np.allclose(weights, noise.min() ** 2 / noise**2, rtol=1e-12, atol=0)
    wls, _, _ = floating_id.identify(pm, structure, "all", noisy, None, Y, weights)
    W1 = Y.reshape(-1, Y.shape[-1])[:, structure.independent] / np.tile(noise, len(Y))[:, None]
    by_hand = np.linalg.lstsq(W1, (noisy[4] / noise).ravel(), rcond=None)[0]
    np.testing.assert_allclose(wls.beta, by_hand, rtol=0, atol=1e-9 * np.abs(by_hand).max())
    ols, _, _ = floating_id.identify(pm, structure, "all", noisy, None, Y)
    judged = _exact(spec, states(200, 12), "all")
    rows = floating_id.selected(floating_id.regressor(pm, *judged[:4]), "all")[:, structure.independent]

    def off(predicted):  # each row's RMS error over its RMS, the largest
        d = predicted.reshape(judged[4].shape) - judged[4]
        return float(np.max(np.sqrt(np.mean(d**2, axis=0) / np.mean(judged[4] ** 2, axis=0))))

    assert off(rows @ wls.beta) <= 0.5 * off(rows @ ols.beta)
    consistent = [off(floating_id.consistent_rows(pm, floating_id.consistent(pm, spec, "all", noisy, False, Y, w)[0],
                                                  "all", judged, False)) for w in (weights, None)]
    assert consistent[0] <= 0.5 * consistent[1]
