"""A URDF's <transmission> elements read as the model's drives (harness/model/urdf_transmissions.py,
`[drives] urdf_transmissions = true`): checked against ros2_control's own maps between actuators and
joints (transmission_interface's SimpleTransmission and DifferentialTransmission, written out here from
their documented equations), against the same drives stated as [drives] (N whole and joint_offset), and
refused in one line where a kind or a layout is not read."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from harness.base.tomlio import InputError
from harness.engines.pinocchio import build_model, rnea
from harness.model.load import load_spec
from tests.conftest import ROOT

URDF = (ROOT / "examples" / "two_link_arm" / "two_link_arm.urdf").read_text()
G = np.array([0.0, 0.0, -9.81])
# ROS 1's layout: a simple transmission's reduction on its actuator, roles as elements (written out of order)
SIMPLE_ROS1 = """
  <transmission name="shoulder_trans"><type>transmission_interface/SimpleTransmission</type>
    <joint name="shoulder"><hardwareInterface>hardware_interface/EffortJointInterface</hardwareInterface>
      <offset>0.25</offset></joint>
    <actuator name="shoulder_motor"><mechanicalReduction>-50</mechanicalReduction></actuator></transmission>
  <transmission name="elbow_trans"><type>transmission_interface/SimpleTransmission</type>
    <joint name="elbow"/><actuator name="elbow_motor"><mechanicalReduction>30</mechanicalReduction></actuator>
  </transmission>"""
DIFFERENTIAL_ROS1 = """
  <transmission name="wrist"><type>transmission_interface/DifferentialTransmission</type>
    <actuator name="m_b"><role>actuator2</role><mechanicalReduction>-30</mechanicalReduction></actuator>
    <actuator name="m_a"><role>actuator1</role><mechanicalReduction>20</mechanicalReduction></actuator>
    <joint name="shoulder"><role>joint1</role><offset>0.1</offset><mechanicalReduction>2</mechanicalReduction></joint>
    <joint name="elbow"><role>joint2</role><offset>-0.2</offset><mechanicalReduction>1.5</mechanicalReduction></joint>
  </transmission>"""
# ros2_control's layout: <plugin>, roles as attributes, a simple transmission's reduction on its joint
DIFFERENTIAL_ROS2 = """
  <transmission name="wrist"><plugin>transmission_interface/DifferentialTransmission</plugin>
    <actuator name="m_a" role="actuator1"><mechanical_reduction>20</mechanical_reduction></actuator>
    <actuator name="m_b" role="actuator2"><mechanical_reduction>-30</mechanical_reduction></actuator>
    <joint name="shoulder" role="joint1"><mechanical_reduction>2</mechanical_reduction><offset>0.1</offset></joint>
    <joint name="elbow" role="joint2"><mechanical_reduction>1.5</mechanical_reduction><offset>-0.2</offset></joint>
  </transmission>"""


def _model(folder: Path, transmissions: str, drives: str = "urdf_transmissions = true\n", name: str = "arm") -> Path:
    (folder / f"{name}.urdf").write_text(URDF.replace("</robot>", transmissions + "\n</robot>"))
    (folder / f"{name}.toml").write_text(f'[model]\nname = "{name}"\n[urdf]\nfile = "{name}.urdf"\n'
                                         + (f"[drives]\n{drives}" if drives else ""))
    return folder / f"{name}.toml"


def _ros2_control_to_joints(kind: str, x_a: np.ndarray, tau_a: np.ndarray):
    """transmission_interface's actuator_to_joint for this file's transmissions: positions and efforts."""
    if kind == "simple":  # x_j = x_a / n + x_off, tau_j = n tau_a, per transmission
        n, off = np.array([-50.0, 30.0]), np.array([0.25, 0.0])
        return x_a / n + off, n * tau_a
    (a1, a2), (j1, j2), off = (20.0, -30.0), (2.0, 1.5), np.array([0.1, -0.2])
    s, d = x_a[:, 0] / a1 + x_a[:, 1] / a2, x_a[:, 0] / a1 - x_a[:, 1] / a2
    x_j = np.column_stack([s / (2 * j1), d / (2 * j2)]) + off
    tau_j = np.column_stack([j1 * (tau_a[:, 0] * a1 + tau_a[:, 1] * a2), j2 * (tau_a[:, 0] * a1 - tau_a[:, 1] * a2)])
    return x_j, tau_j


@pytest.mark.parametrize(("kind", "text"), [("simple", SIMPLE_ROS1), ("differential", DIFFERENTIAL_ROS1),
                                            ("differential", DIFFERENTIAL_ROS2)])
def test_a_urdfs_transmissions_map_the_motors_as_ros2_control_does(tmp_path, kind, text):
    """At 50 random actuator positions and efforts, the drives read from the URDF give ros2_control's
    joint positions and efforts (actuator_to_joint) to 1e-12; the motors are the actuators, each on the
    row of its role's joint."""
    t = load_spec(_model(tmp_path, text)).transmission
    rng = np.random.default_rng(3)
    x_a, tau_a = rng.uniform(-5, 5, (50, 2)), rng.uniform(-2, 2, (50, 2))
    x_j, tau_j = _ros2_control_to_joints(kind, x_a, tau_a)
    np.testing.assert_allclose(t.joint_positions(x_a), x_j, rtol=0, atol=1e-12)
    np.testing.assert_allclose(t.joint_torques(tau_a), tau_j, rtol=1e-12, atol=0)
    assert t.motors == (("shoulder_motor", "elbow_motor") if kind == "simple" else ("m_a", "m_b"))


def test_the_urdfs_transmissions_are_the_drives_the_same_drives_table_states(tmp_path):
    """The differential read from the URDF, with each motor's law in [drives.MOTOR], is the model whose
    [drives] states N whole and joint_offset: the same N and motor offsets, and Pinocchio's torques with
    the drives equal to the bit at 100 random states."""
    laws = '[drives.m_a]\narmature = 2e-5\nviscous = 3e-4\ncoulomb = 0.01\n[drives.m_b]\nviscous = 2e-4\n'
    read = load_spec(_model(tmp_path, DIFFERENTIAL_ROS1, "urdf_transmissions = true\n" + laws))
    stated = load_spec(_model(tmp_path, DIFFERENTIAL_ROS1, 'motors = ["m_a", "m_b"]\ntransmission = [[40.0, 30.0], '
                              "[-60.0, 45.0]]\njoint_offset = [0.1, -0.2]\n" + laws, name="stated"))
    assert np.array_equal(read.transmission.N, stated.transmission.N)
    assert np.array_equal(read.transmission.offset, stated.transmission.offset)
    rng = np.random.default_rng(5)
    q, qd, qdd = (rng.uniform(-2, 2, (100, 2)) for _ in range(3))
    a, b = (rnea(build_model(s, G), q, qd, qdd).tau for s in (read, stated))
    assert np.array_equal(a, b)


def test_transmissions_a_model_does_not_read_are_said(tmp_path):
    """A URDF whose transmissions state reductions, read without [drives]: the joints driven directly, and
    a note says the transmissions were not read; a URDF whose transmissions are each joint's own at 1 (as
    most published ones) has no such note."""
    spec = load_spec(_model(tmp_path, SIMPLE_ROS1, drives=""))
    assert spec.transmission is None
    assert any("<transmission>" in n and "urdf_transmissions = true" in n for n in spec.notes)
    unit = SIMPLE_ROS1.replace("-50", "1").replace("30", "1").replace("<offset>0.25</offset>", "")
    assert not any("<transmission>" in n for n in load_spec(_model(tmp_path, unit, drives="", name="unit")).notes)


@pytest.mark.parametrize(("text", "drives", "key", "said"), [
    (DIFFERENTIAL_ROS1.replace("DifferentialTransmission", "HalfDifferentialTransmission"),
     "urdf_transmissions = true\n", "drives.urdf_transmissions", "HalfDifferentialTransmission"),
    (SIMPLE_ROS1[: SIMPLE_ROS1.index("<transmission name=\"elbow_trans\"")], "urdf_transmissions = true\n",
     "drives.urdf_transmissions", "'elbow' has no <transmission>"),
    (SIMPLE_ROS1.replace('<joint name="elbow"/>', '<joint name="elbow"><mechanical_reduction>4</mechanical_reduction>'
                                                  "</joint>"),
     "urdf_transmissions = true\n", "drives.urdf_transmissions", "both its joint"),
    (SIMPLE_ROS1.replace("<mechanicalReduction>30", "<mechanicalReduction>0"), "urdf_transmissions = true\n",
     "drives.urdf_transmissions", "reduction of 0"),
    (SIMPLE_ROS1, "urdf_transmissions = true\ngear_ratio = [1, 1]\n", "drives.gear_ratio", "<transmission>"),
    (SIMPLE_ROS1.replace('<transmission name="shoulder_trans"><type>transmission_interface/SimpleTransmission</type>',
                         '<transmission name="shoulder_trans" type="pr2_mechanism_model/SimpleTransmission">'),
     "urdf_transmissions = true\n", "drives.urdf_transmissions", "is pr2_mechanism_model/SimpleTransmission"),
    (SIMPLE_ROS1, "urdf_transmissions = false\n", "drives.urdf_transmissions", "leave the key out"),
])
def test_a_transmission_not_read_is_refused_in_one_line(tmp_path, text, drives, key, said):
    with pytest.raises(InputError) as err:
        load_spec(_model(tmp_path, text, drives))
    assert err.value.key == key and said in str(err.value) and "\n" not in str(err.value), str(err.value)


def test_a_urdfs_joint_friction_beside_its_transmissions_is_left_out_where_the_model_file_says(tmp_path):
    """A published URDF with <dynamics> on a joint and transmissions: read with its drives, refused in one
    line naming the joint and the way out (the motors carry the friction); with [urdf] dynamics = false,
    read, every motor without friction but what [drives.MOTOR] states."""
    path = _model(tmp_path, SIMPLE_ROS1)
    urdf = path.with_suffix(".urdf")
    urdf.write_text(urdf.read_text().replace('<joint name="elbow" type="revolute">',
                                             '<joint name="elbow" type="revolute"><dynamics damping="0.2"/>'))
    with pytest.raises(InputError) as err:
        load_spec(path)
    assert err.value.key == "drives" and "'elbow' has friction of its own" in str(err.value)
    assert "dynamics = false" in str(err.value)
    path.write_text(path.read_text().replace("[drives]", "dynamics = false\n[drives]")
                    + "[drives.elbow_motor]\nviscous = 1e-4\n")
    spec = load_spec(path)
    assert [f.viscous for f in spec.frictions] == [0.0, 1e-4]
