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
    data = mujoco.MjData(model)
    rng = np.random.default_rng(0)
    q, qd, qdd = (rng.uniform(-1, 1, (50, 3)) * s for s in (np.array([2.0, 1.5, 0.08]), 2.0, 5.0))
    tau = np.empty_like(q)
    for k in range(len(q)):
        data.qpos[:], data.qvel[:], data.qacc[:] = q[k], qd[k], qdd[k]
        mujoco.mj_inverse(model, data)
        tau[k] = data.qfrc_inverse
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
    "ball joint": ('<joint name="shoulder" type="hinge"', '<joint name="shoulder" type="ball"', "ball joint"),
    "two joints in a body": ('<joint name="elbow" type="hinge" axis="0 1 0" ref="20" range="-120 120"/>',
                             '<joint name="elbow" type="hinge" axis="0 1 0"/><joint name="twist" axis="1 0 0"/>',
                             "has 2 joints"),
    "free joint below the root": ('<joint name="slide" type="slide" axis="1 0 0" range="-0.1 0.1" damping="2"/>',
                                  '<freejoint name="loose"/>', "free joint can only be used on top level; Element"),
    "tendon": ("</worldbody>", '</worldbody><tendon><fixed name="couple"><joint joint="shoulder" coef="1"/>'
                               '<joint joint="elbow" coef="-1"/></fixed></tendon>', "tendon 'couple'"),
    "equality": ("</worldbody>", '</worldbody><equality><joint name="geared" joint1="shoulder" joint2="elbow" '
                                 'polycoef="0 1 0.5 0 0"/></equality>', "equality constraint 'geared' couples its "
                                 "joints by a polynomial of degree above 1"),
    "spring": ('range="-170 170" frictionloss="0.3"/>', 'range="-170 170" stiffness="5"/>', "stiffness"),
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
