"""MJCF model files (`[mjcf] file = ...`, harness/model/mjcf.py) read through MuJoCo's compiler. The
check is independent of the reader: MuJoCo's own inverse dynamics (mj_inverse) of the file itself,
against Pinocchio's RNEA of the RobotSpec the harness read, at random states. Tolerance 1e-9
relative (agreement of the two engines is about 1e-13 on these models)."""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np
import pytest

from harness.api import load_scenario
from harness.base.tomlio import InputError
from harness.cli import main
from harness.engines.pinocchio import build_model, rnea
from harness.model.load import load_spec
from tests.conftest import mujoco_inverse

# an arm written the way MJCF files are: defaults and classes, degrees and Euler angles, inertia
# from geoms, a welded sub-body, a joint `ref`, a slide joint, joint damping, armature and
# frictionloss, a geared motor with a force range, and gravity of its own
ARM = """<mujoco model="arm">
  <compiler angle="degree" autolimits="true"/>
  <option gravity="0.3 -0.2 -9.7"/>
  <default>
    <joint damping="0.4" armature="0.02"/>
    <default class="big"><geom type="capsule" size="0.05" density="2700"/></default>
  </default>
  <worldbody>
    <body name="base" pos="0 0 0.1">
      <geom type="box" size="0.1 0.1 0.05" density="1000"/>
      <body name="upper" pos="0 0 0.1" euler="0 0 30">
        <joint name="shoulder" type="hinge" axis="0 0 1" range="-170 170" frictionloss="0.3"/>
        <geom class="big" fromto="0 0 0 0.4 0 0.1"/>
        <body name="bracket" pos="0.4 0 0.1" euler="10 0 0">
          <geom type="box" size="0.03 0.02 0.05" density="7800" pos="0.01 0 0"/>
        </body>
        <body name="fore" pos="0.4 0 0.1" quat="0.9 0.1 0.3 0.2">
          <joint name="elbow" type="hinge" axis="0 1 0" ref="20" range="-120 120"/>
          <geom class="big" fromto="0 0 0 0.3 0.05 0"/>
          <body name="tool" pos="0.3 0.05 0">
            <joint name="slide" type="slide" axis="1 0 0" range="-0.1 0.1" damping="2"/>
            <inertial pos="0.02 0.01 0" mass="0.7" fullinertia="0.002 0.003 0.0025 0.0002 -0.0001 0.0003"/>
          </body>
        </body>
      </body>
    </body>
  </worldbody>
  <actuator>
    <motor name="m_shoulder" joint="shoulder" gear="50" forcerange="-2 2"/>
  </actuator>
</mujoco>
"""


def _spec(tmp_path, xml: str, name: str = "arm"):
    (tmp_path / f"{name}.xml").write_text(xml)
    (tmp_path / f"{name}.toml").write_text(f'[mjcf]\nfile = "{name}.xml"\n')
    return load_spec(tmp_path / f"{name}.toml")


def test_an_mjcf_arm_is_read_as_mujoco_simulates_it(tmp_path):
    spec = _spec(tmp_path, ARM)
    assert spec.joint_names == ["shoulder", "elbow", "slide"]
    assert [j.type for j in spec.joints] == ["revolute", "revolute", "prismatic"]
    np.testing.assert_array_equal(spec.gravity_W, [0.3, -0.2, -9.7])
    assert spec.limits["shoulder"] == pytest.approx((np.radians(-170), np.radians(170)), rel=1e-15)
    assert spec.drive_limits == {"shoulder": {"effort": 100.0}}  # force range x gear
    f = {j.name: j.friction for j in spec.joints}
    assert (f["shoulder"].armature, f["shoulder"].viscous, f["shoulder"].coulomb) == (0.02, 0.4, 0.3)
    assert (f["slide"].viscous, f["slide"].coulomb_velocity) == (2.0, 0.0)  # dry friction: a sharp sign
    model = mujoco.MjModel.from_xml_path(str(tmp_path / "arm.xml"))
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_FRICTIONLOSS  # dry friction: a constraint, compared apart
    rng = np.random.default_rng(0)
    q, qd, qdd = (rng.uniform(-1, 1, (50, 3)) * s for s in (np.array([2.0, 1.5, 0.08]), 2.0, 5.0))
    tau = mujoco_inverse(model, q, qd, qdd)
    no_dry = dataclasses.replace(spec, joints=tuple(
        dataclasses.replace(j, friction=dataclasses.replace(j.friction, coulomb=0.0)) for j in spec.joints))
    ours = rnea(build_model(no_dry, spec.gravity_W), q, qd, qdd).tau
    assert np.max(np.abs(ours - tau)) <= 1e-9 * np.max(np.abs(tau))


def test_a_scenario_takes_the_files_gravity_unless_it_states_its_own(tmp_path):
    _spec(tmp_path, ARM)
    motion = "".join(f'[motion.{j}]\ntype = "locked"\n' for j in ("shoulder", "elbow", "slide"))
    gate = '[[gates]]\nmetric = "torques.pinocchio_vs_mujoco.max_rel_error"\nlimit = 1e-9\n'
    head = '[scenario]\nmodel = "arm.toml"\nduration = 0.1\noutput_steps = 10\n'
    (tmp_path / "a.toml").write_text(head + motion + gate)
    (tmp_path / "b.toml").write_text(head.replace("output_steps", "gravity = [0.0, 0.0, -1.0]\noutput_steps")
                                     + motion + gate)
    np.testing.assert_array_equal(load_scenario(tmp_path / "a.toml").gravity_W, [0.3, -0.2, -9.7])
    np.testing.assert_array_equal(load_scenario(tmp_path / "b.toml").gravity_W, [0.0, 0.0, -1.0])


REFUSED = {
    # a ball joint is read as three hinges (tests/test_ball_joints.py), where they act as it does
    "a ball joint with armature": ('<joint name="shoulder" type="hinge" axis="0 0 1" range="-170 170"',
                                        '<joint name="shoulder" type="ball"',
                                        "ball joint 'shoulder' has armature"),
    "a ball joint with a spring": ('<joint name="shoulder" type="hinge" axis="0 0 1" range="-170 170" '
                                   'frictionloss="0.3"/>',
                                   '<joint name="shoulder" type="ball" damping="0" armature="0" stiffness="2"/>',
                                   "ball joint 'shoulder' has stiffness"),
    # a body of several joints is the chain of joints it is (below), where it can be one
    "a slide after a body's first joint": ('<joint name="elbow" type="hinge" axis="0 1 0" ref="20" range="-120 120"/>',
                                           '<joint name="elbow" type="hinge" axis="0 1 0"/>'
                                           '<joint name="twist" type="slide" axis="1 0 0"/>',
                                           "body 'fore' has 2 joints and joint 'twist', not its first, is not a hinge"),
    "a body's joints apart": ('<joint name="elbow" type="hinge" axis="0 1 0" ref="20" range="-120 120"/>',
                              '<joint name="elbow" type="hinge" axis="0 1 0"/>'
                              '<joint name="twist" axis="1 0 0" pos="0.1 0 0"/>',
                              "body 'fore' has 2 joints 0.1 m apart"),
    "free joint below the root": ('<joint name="slide" type="slide" axis="1 0 0" range="-0.1 0.1" damping="2"/>',
                                  '<freejoint name="loose"/>', "free joint can only be used on top level; Element"),
    "tendon": ("</worldbody>", '</worldbody><tendon><fixed name="couple"><joint joint="shoulder" coef="1"/>'
                               '<joint joint="elbow" coef="-1"/></fixed></tendon>', "tendon 'couple'"),
    "equality": ("</worldbody>", '</worldbody><equality><joint name="geared" joint1="shoulder" joint2="elbow" '
                                 'polycoef="0 1 0.5 0 0"/></equality>', "equality constraint 'geared' couples its "
                                 "joints by a polynomial of degree above 1"),
    # a linear spring is read (tests/test_springs.py); a polynomial one is not the law's
    "nonlinear spring": ('range="-170 170" frictionloss="0.3"/>', 'range="-170 170" stiffness="5 1 0"/>',
                         "joint 'shoulder': a spring's polynomial terms"),
    "not MJCF": ("<mujoco", "<notmujoco", "MuJoCo cannot compile it"),
}


@pytest.mark.parametrize("case", list(REFUSED))
def test_what_the_harness_cannot_model_is_refused_in_one_line_naming_the_element(tmp_path, capsys, case):
    old, new, message = REFUSED[case]
    assert old in ARM
    with pytest.raises(InputError) as err:
        _spec(tmp_path, ARM.replace(old, new, 1))
    line = err.value.one_line()
    assert message in line and "arm.xml" in line and "\n" not in line


def test_a_body_of_several_joints_is_the_chain_of_joints_it_is(tmp_path):
    """A universal joint at the elbow (the file's hinge, with its `ref`, then a twist about the forearm,
    MuJoCo applying the second as the first has turned it) and a gimbal of three hinges at the tool: each
    joint after a body's first is carried by a massless body at their point. The harness's model against
    MuJoCo's own model of the file (mj_inverse) and against Pinocchio's own parser of it (the joints
    written as nested bodies: harness/engines/pinocchio_file.py), at 100 random states: to 1e-9 of each
    joint's largest torque (the audit's figures; round-off ~1e-14)."""
    from harness.runner.audit import TOLERANCE, audit

    xml = ARM.replace('range="-120 120"/>', 'range="-120 120"/><joint name="twist" axis="1 0 0" range="-90 90"/>')
    xml = xml.replace('<joint name="slide" type="slide" axis="1 0 0" range="-0.1 0.1" damping="2"/>',
                      '<joint name="g1" axis="0 0 1"/><joint name="g2" axis="0 1 0"/><joint name="g3" axis="1 0 0"/>')
    spec = _spec(tmp_path, xml)
    assert spec.joint_names == ["shoulder", "elbow", "twist", "g1", "g2", "g3"]
    chain = [(j.parent, j.child) for j in spec.joints]
    assert chain == [("world", "upper"), ("upper", "fore[elbow]"), ("fore[elbow]", "fore"), ("fore", "tool[g1]"),
                     ("tool[g1]", "tool[g2]"), ("tool[g2]", "tool")]
    assert [b.name for b in spec.bodies if b.massless] == ["fore[elbow]", "tool[g1]", "tool[g2]"]
    row = audit("arm", tmp_path / "arm.toml")
    assert row.verdict == "agrees", row.reason
    assert row.torques_vs_mujoco_file <= TOLERANCE and row.torques_vs_pinocchio <= TOLERANCE
    assert row.mass_matrix_vs_pinocchio <= TOLERANCE
    # the carriages' parameters are known zeros in the harness's base, columns of Pinocchio's nested bodies
    assert row.base_parameters == row.massive_ranks[0] == row.massive_ranks[1] < row.pinocchio_regressor_rank


def test_a_floating_base_is_fixed_to_the_world_and_said_so(tmp_path, capsys):
    base = '<body name="base" pos="0 0 0.1">'
    floating = ARM.replace(base, base + '<freejoint name="float"/>')
    spec = _spec(tmp_path, floating)
    assert spec.joint_names == ["shoulder", "elbow", "slide"]
    assert len(spec.notes) == 1 and "'float'" in spec.notes[0] and "fixed to the world" in spec.notes[0]
    fixed = _spec(tmp_path, ARM, "fixed")
    for a, b in zip(spec.joints, fixed.joints, strict=True):  # at the file's pose: the same robot
        np.testing.assert_allclose(a.p_W0, b.p_W0, rtol=0, atol=1e-15)
    motion = "".join(f'[motion.{j}]\ntype = "locked"\n' for j in spec.joint_names)
    gate = '[[gates]]\nmetric = "torques.pinocchio_vs_mujoco.max_rel_error"\nlimit = 1e-9\n'
    head = '[scenario]\nmodel = "arm.toml"\nduration = 0.1\noutput_steps = 10\n'
    (tmp_path / "s.toml").write_text(head + motion + gate)
    assert main(["run", str(tmp_path / "s.toml"), "--out", str(tmp_path / "out"), "--quiet"]) == 0
    assert "warning: s: arm.xml: free joint 'float'" in capsys.readouterr().err


def test_the_graph_theory_model_carries_a_universal_joint_on_a_body_and_its_study_refuses_parallel_hinges(tmp_path):
    """The first seed's method reads a chain of hinges through a massless carriage on a body (a universal
    joint read from an MJCF file) as one edge from the body's massive ancestor: its joint torques are
    Pinocchio's at random states (to 1e-12 of the largest; round-off is ~1e-15). The study's constraint
    equations (Section 2.4) read it as the joint point and the angle between the two axes (judged on a
    recording in tests/test_lagrange.py); two hinges about one axis leave a rotation unconstrained that
    they cannot make, and are refused in one line naming them."""
    from harness.engines import pinocchio as pin_engine
    from harness.model.states import random_states
    from harness.papers.graph_theory_2021.constraints import build_constraints
    from harness.papers.graph_theory_2021.dynamics import build_graph_model
    from harness.papers.graph_theory_2021.inverse import inverse_dynamics_of_motion

    spec = _spec(tmp_path, ARM.replace('range="-120 120"/>', 'range="-120 120"/><joint name="twist" axis="1 0 0"/>'))
    n = len(spec.joints)
    q, qd, qdd = random_states(np.full(n, -1.0), np.full(n, 1.0), np.ones(n), np.ones(n), 40, seed=3)
    graph = build_graph_model(spec, spec.gravity_W)
    ours = inverse_dynamics_of_motion(spec, graph, q, qd, qdd).tau
    pin = pin_engine.rnea(pin_engine.build_model(spec.rigid(), spec.gravity_W), q, qd, qdd).tau
    assert np.abs(ours - pin).max() <= 1e-12 * np.abs(pin).max()
    rows = build_constraints(spec, graph.topology).rows
    assert [r.label for r in rows if r.joint == "twist"] == ["x", "y", "z", "angle"]
    twice = _spec(tmp_path, ARM.replace('range="-120 120"/>', 'range="-120 120"/><joint name="twist" axis="0 1 0"/>'))
    with pytest.raises(ValueError, match="two or three hinges at one point whose axes span their rotations"):
        build_constraints(twice, build_graph_model(twice, twice.gravity_W).topology)


