"""A spring in the drive's law (harness/model/friction.py, the `spring` family: k q, its rest position in
the offset). Checked against MuJoCo's own springs (a joint's `stiffness` at `springref`, a drive tendon's at
its `springlength`) through mj_inverse of the file itself, which shares nothing with the harness's law;
against the law written out here; and, on a bench log whose wrist carries a spring, by the identification
that finds it (slow)."""

from __future__ import annotations

import dataclasses
import json

import mujoco
import numpy as np
import pytest

from harness.cli import main
from harness.engines.pinocchio import build_model, rnea
from harness.identify.laws import Law, extra_regressor
from harness.model import friction
from harness.model.mjcf import write_mjcf
from tests.conftest import SCENARIOS, bench_log, log_scenario, mujoco_inverse
from tests.test_mjcf import ARM, _spec

SPRUNG = (ARM.replace('frictionloss="0.3"/>', 'stiffness="4" springref="25"/>')  # degrees, as the file's angles
          .replace('ref="20" range="-120 120"/>', 'ref="20" range="-120 120" stiffness="1.5"/>')
          .replace('damping="2"/>', 'damping="2" stiffness="300" springref="0.03"/>'))
# two hinges on two drive tendons, the second's motor geared and sprung (its rest length 0.1)
TENDONS = """<mujoco model="sprung_drives">
  <worldbody>
    <body name="upper" pos="0 0 0.1">
      <joint name="a" type="hinge" axis="0 0 1"/>
      <geom type="capsule" fromto="0 0 0 0.4 0 0" size="0.04" density="2700"/>
      <body name="fore" pos="0.4 0 0">
        <joint name="b" type="hinge" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0.3 0 0.05" size="0.03" density="2700"/>
      </body>
    </body>
  </worldbody>
  <tendon>
    <fixed name="m1" armature="0.01" damping="0.2"><joint joint="a" coef="1"/></fixed>
    <fixed name="m2" stiffness="2.5" springlength="0.1" damping="0.1">
      <joint joint="a" coef="0.5"/><joint joint="b" coef="1"/>
    </fixed>
  </tendon>
  <actuator>
    <motor name="d1" tendon="m1" gear="1"/>
    <motor name="d2" tendon="m2" gear="3"/>
  </actuator>
</mujoco>
"""


@pytest.mark.parametrize(("xml", "name", "scales"), [(SPRUNG, "arm", (2.0, 1.5, 0.08)),
                                                     (TENDONS, "drives", (2.0, 2.0))])
def test_mujocos_springs_are_read_into_the_law_and_its_inverse_dynamics_agrees(tmp_path, xml, name, scales):
    """Joint springs (k at springref, in the file's degrees; on a hinge and a slide) and a geared drive
    tendon's (k at springlength L_s, read as the motor's k/g^2 with offset -k L_s/g): Pinocchio's RNEA of the
    spec the harness read, with its law, is MuJoCo's mj_inverse of the file at 50 random states within 1e-9
    of the largest torque (round-off is 1e-13). Left out of the harness's law (stiffness 0), the two differ by
    the springs' torques."""
    xml = xml.replace('frictionloss="0.3"', "")
    spec = _spec(tmp_path, xml, name)
    laws = dict(zip(spec.drive_names, spec.frictions, strict=True))
    if name == "arm":
        assert laws["shoulder"].stiffness == 4.0
        assert laws["shoulder"].offset == pytest.approx(-4.0 * np.radians(25), rel=1e-12)
        assert (laws["slide"].stiffness, laws["slide"].offset) == (300.0, pytest.approx(-300.0 * 0.03, rel=1e-12))
    else:
        assert laws["m2"].stiffness == pytest.approx(2.5 / 9, rel=1e-15)
        assert laws["m2"].offset == pytest.approx(-2.5 * 0.1 / 3, rel=1e-15)
    rng = np.random.default_rng(3)
    n = len(spec.joints)
    q, qd, qdd = (rng.uniform(-1, 1, (50, n)) * s for s in (np.array(scales), 2.0, 5.0))
    # the file itself, its springs MuJoCo's own (qfrc_passive)
    theirs = mujoco_inverse(mujoco.MjModel.from_xml_path(str(tmp_path / f"{name}.xml")), q, qd, qdd)
    ours = rnea(build_model(spec, spec.gravity_W), q, qd, qdd).tau
    assert np.max(np.abs(ours - theirs)) <= 1e-9 * np.max(np.abs(theirs))
    slack = dataclasses.replace(spec, joints=tuple(dataclasses.replace(j, friction=dataclasses.replace(
        j.friction, stiffness=0.0)) for j in spec.joints))
    assert np.max(np.abs(rnea(build_model(slack, spec.gravity_W), q, qd, qdd).tau - theirs)) > 1e-3


def test_the_spring_is_k_q_and_needs_the_positions():
    """friction.torque with a spring is the law written out here, f_v q' + f_c tanh(q'/v_c) + f_o + k q;
    the regressor's spring column is q itself (its coefficient k); without the positions, asked for a
    spring, both refuse rather than leave it out."""
    law = (friction.JointFriction(viscous=0.5, coulomb=1.2, offset=-0.3, coulomb_velocity=0.02, stiffness=7.0),
           friction.JointFriction(viscous=0.1))
    rng = np.random.default_rng(1)
    q, qd, qdd = rng.standard_normal((3, 20, 2))
    expected = np.column_stack([0.5 * qd[:, 0] + 1.2 * np.tanh(qd[:, 0] / 0.02) - 0.3 + 7.0 * q[:, 0], 0.1 * qd[:, 1]])
    np.testing.assert_allclose(friction.torque(law, qd, qdd, q=q), expected, rtol=1e-14, atol=1e-14)
    np.testing.assert_allclose(friction.Dry.of(law)(qd, q=q) + np.array([0.5, 0.1]) * qd, expected,
                               rtol=1e-14, atol=1e-14)
    E = extra_regressor((Law("spring", 0.02), Law()), qd, None, q=q)
    np.testing.assert_array_equal(E.reshape(20, 2, 1)[:, :, 0], np.column_stack([q[:, 0], np.zeros(20)]))
    for call in (lambda: friction.torque(law, qd, qdd), lambda: friction.Dry.of(law)(qd),
                 lambda: extra_regressor((Law("spring", 0.02), Law()), qd, None)):
        with pytest.raises(ValueError, match="position"):
            call()


def test_a_spring_written_as_mjcf_reloads_as_the_same_spring(tmp_path):
    """write_mjcf puts a joint's spring in its `stiffness` (springref 0; the law's offset has no place in
    MJCF) and a drive's in its tendon's (springlength 0): read back, each law's stiffness is the same
    double, and a tendon's the same through its gear of 1."""
    for xml, name in ((SPRUNG.replace('frictionloss="0.3"', ""), "arm"), (TENDONS, "drives")):
        spec = _spec(tmp_path, xml, name)
        again = _spec(tmp_path, write_mjcf(spec, spec.gravity_W), f"{name}_again")
        assert [f.stiffness for f in again.frictions] == [f.stiffness for f in spec.frictions]


@pytest.mark.slow  # an 8 s bench log through the whole pipeline
def test_a_wrists_spring_is_found_by_the_search_that_may_choose_it_and_not_given_elsewhere(tmp_path):
    """Noise-free bench log of the UR5 with drives whose wrist 2 carries a spring of 3 N m/rad, identified
    on the model without it, `[friction_law] families` naming `spring` beside the plain law: wrist 2 gets
    the spring and every other joint the plain law; k within 1 % (the central differences of the log's
    velocities at 200 Hz are the floor of every coefficient, as with the plain law), the validation
    torques within 1e-4 of the log's. The exported model reloads with the spring."""
    from harness.api import load_scenario
    from harness.model.load import load_spec

    model = SCENARIOS.parent / "models" / "ur5_friction.toml"
    text = model.read_text().replace('name = "ur5_friction"', 'name = "sprung"')
    head, tail = text.split("[joints.wrist_2_joint]\n")
    (tmp_path / "sprung.toml").write_text(head + "[joints.wrist_2_joint]\nstiffness = 3.0\n" + tail)
    truth = load_spec(tmp_path / "sprung.toml")
    bench_log(dataclasses.replace(load_scenario(SCENARIOS / "ur5_friction.toml"), robot=truth), tmp_path, 8.0, 1600)
    log_scenario(tmp_path, model, '[friction_law]\nfamilies = ["viscous_coulomb", "spring"]\n'
                 '[[gates]]\nmetric = "log_identification.validation_rel_error.consistent"\nlimit = 1\n')
    assert main(["run", str(tmp_path / "s.toml"), "--out", str(tmp_path / "out"), "--quiet"]) == 0
    li = json.loads((tmp_path / "out" / "results.json").read_text())["log_identification"]
    families = li["friction_law"]["families"]
    assert families == {j: "spring" if j == "wrist_2_joint" else "viscous_coulomb" for j in families}
    assert li["consistent"]["friction"]["wrist_2_joint"]["stiffness"] == pytest.approx(3.0, rel=1e-2)
    assert li["validation_rel_error"]["consistent"] <= 1e-4
    reloaded = load_spec(tmp_path / "out" / "identified" / "robot.toml")
    assert reloaded.joint("wrist_2_joint").friction.stiffness == pytest.approx(3.0, rel=1e-2)


@pytest.mark.slow  # harness init and its project's run (2.7 s)
def test_init_on_an_mjcf_file_with_springs_passes_out_of_the_box(tmp_path):
    """`harness init --mjcf` on the sprung arm: the placeholder model (Pinocchio's parser, which reads no
    spring) and the template's method take the file's springs as the harness read them (k q less k q_ref),
    and the project passes all six gates; without them the slide's torque is off by its spring (1.15 of
    the largest torque, measured before the template carried them)."""
    (tmp_path / "arm.xml").write_text(SPRUNG.replace('frictionloss="0.3"', ""))
    assert main(["init", str(tmp_path / "p"), "--mjcf", str(tmp_path / "arm.xml")]) == 0
    assert main(["run", str(tmp_path / "p" / "scenario.toml"), "--out", str(tmp_path / "o"), "--quiet"]) == 0
    gates = json.loads((tmp_path / "o" / "results.json").read_text())["gates"]
    assert len(gates) == 6 and all(g["passed"] for g in gates)
