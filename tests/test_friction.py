"""Joint friction and rotor inertia (harness/model/friction.py): the law, how a model declares it (its own
TOML, a URDF's <dynamics>), MuJoCo simulating it against Pinocchio and the graph model adding it,
and the joint-torque identification finding it again on the bench where the truth is known."""

from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest

from harness.cli import main
from harness.engines.pinocchio import build_model, rnea
from harness.model import friction
from harness.model.friction import JointFriction
from harness.model.load import load_spec
from harness.model.urdf import example_robot_data_path
from tests.conftest import MODELS, SCENARIOS, results_of

rng = np.random.default_rng(11)


def test_the_law_term_by_term():
    """I_a q'' + f_v q' + f_c tanh(q'/v_c) + f_o, and a sharp sign where v_c = 0."""
    fr = (JointFriction(0.3, 2.0, 4.0, 0.5, 0.02), JointFriction(0.1, 1.0, 3.0, -0.2, 0.0))
    qd, qdd = rng.normal(size=(50, 2)), rng.normal(size=(50, 2))
    expected = np.column_stack([0.3 * qdd[:, 0] + 2.0 * qd[:, 0] + 4.0 * np.tanh(qd[:, 0] / 0.02) + 0.5,
                                0.1 * qdd[:, 1] + 1.0 * qd[:, 1] + 3.0 * np.sign(qd[:, 1]) - 0.2])
    np.testing.assert_allclose(friction.torque(fr, qd, qdd), expected, rtol=1e-15, atol=1e-15)
    np.testing.assert_allclose(friction.dry(fr, qd) + qd * [2.0, 1.0] + qdd * [0.3, 0.1], expected, rtol=1e-14,
                               atol=1e-14)


def test_the_families_term_by_term():
    """Asymmetric: f_v + f_va and f_c + f_ca moving positively, f_v - f_va and f_c - f_ca negatively;
    Stribeck: f_s s exp(-(q'/v_s)^2); load: f_l |tau_R| s. Written out here branch by branch."""
    fr = (JointFriction(0.0, 2.0, 4.0, 0.0, 0.05, viscous_asymmetry=0.5, coulomb_asymmetry=-1.0),
          JointFriction(0.0, 1.0, 3.0, 0.0, 0.02, stribeck=1.5, stribeck_velocity=0.1),
          JointFriction(0.0, 1.0, 3.0, 0.0, 0.0, load_coulomb=0.02))
    qd, qdd, tau_R = rng.normal(size=(80, 3)), np.zeros((80, 3)), rng.normal(scale=30.0, size=(80, 3))
    s0, s1 = np.tanh(qd[:, 0] / 0.05), np.tanh(qd[:, 1] / 0.02)
    up = qd[:, 0] > 0
    expected = np.column_stack([np.where(up, 2.5 * qd[:, 0] + 3.0 * s0, 1.5 * qd[:, 0] + 5.0 * s0),
                                1.0 * qd[:, 1] + 3.0 * s1 + 1.5 * s1 * np.exp(-(qd[:, 1] / 0.1) ** 2),
                                1.0 * qd[:, 2] + (3.0 + 0.02 * np.abs(tau_R[:, 2])) * np.sign(qd[:, 2])])
    np.testing.assert_allclose(friction.torque(fr, qd, qdd, tau_R), expected, rtol=1e-13, atol=1e-13)
    assert [f.family for f in fr] == ["asymmetric", "stribeck", "load"]
    with pytest.raises(ValueError, match="rigid-body torque"):
        friction.torque(fr, qd, qdd)


def test_a_urdf_dynamics_tag_is_read_as_viscous_and_coulomb_and_the_model_file_adds_the_rest(tmp_path):
    urdf = example_robot_data_path("panda")
    if urdf is None:
        pytest.skip("example-robot-data is not installed")
    text = urdf.read_text()
    # the URDF's own damping of panda_joint1, read independently of the reader under test
    block = re.search(r'<joint name="panda_joint1".*?</joint>', text, re.S).group(0)
    damping = float(re.search(r'damping="([^"]+)"', block).group(1))
    (tmp_path / "p.toml").write_text('[urdf]\nrobot = "panda"\n\n[joints.panda_joint1]\narmature = 0.2\n'
                                     'coulomb = 1.5\ncoulomb_velocity = 0.01\n')
    f = load_spec(tmp_path / "p.toml").joint("panda_joint1").friction
    assert f == JointFriction(armature=0.2, viscous=damping, coulomb=1.5, offset=0.0, coulomb_velocity=0.01)


@pytest.mark.parametrize("v_c", [0.02, 0.0])
def test_a_drive_torque_gives_back_the_rigid_torque_its_law_was_added_to(v_c):
    """friction.rigid_torque inverts the law: tau = tau_R + every term, the load term f_l |tau_R| s (of either
    sign of f_l, |f_l| < 1) included, gives tau_R back to round-off (1e-12 of the largest), with a smooth or
    a sharp Coulomb shape, a Stribeck term, an asymmetry and a spring beside it; the law forward is
    friction.torque, written independently of the inverse."""
    fr = (JointFriction(0.2, 1.0, 3.0, 0.4, v_c, load_coulomb=0.3, stribeck=1.0, stribeck_velocity=0.1),
          JointFriction(0.1, 2.0, 1.0, -0.2, v_c, load_coulomb=-0.6, viscous_asymmetry=0.5, stiffness=4.0),
          JointFriction(0.0, 0.5, 0.0, 0.0, v_c))
    q, qd, qdd = rng.normal(size=(3, 500, 3))
    tau_R = rng.normal(scale=20.0, size=(500, 3))
    tau = tau_R + friction.torque(fr, qd, qdd, tau_R, q)
    np.testing.assert_allclose(friction.rigid_torque(fr, tau, qd, qdd, q), tau_R, rtol=0, atol=1e-12 * 60.0)
    # without the load term the inverse is the plain difference
    plain = tuple(dataclasses.replace(f, load_coulomb=0.0) for f in fr)
    np.testing.assert_array_equal(friction.rigid_torque(plain, tau, qd, qdd, q),
                                  tau - friction.torque(plain, qd, qdd, q=q))


@pytest.mark.parametrize(("text", "message"), [
    ('[joints.panda_joint9]\nviscous = 1.0\n', "no joint 'panda_joint9' in the URDF"),
    ('[joints.panda_joint1]\nviscous = -1.0\n', "viscous"),
    ('[joints.panda_joint1]\nstiction = 1.0\n', "stiction"),
    ('[joints.panda_joint1]\nstribeck = 1.0\n', "stribeck_velocity"),
    ('[joints.panda_joint1]\nstribeck_velocity = -0.1\n', "stribeck_velocity"),
    ('[joints.panda_joint1]\ncoulomb = 1.0\nload_coulomb = -1.0\n', "load_coulomb"),
])
def test_a_bad_friction_declaration_is_refused_in_one_line(tmp_path, capsys, text, message):
    (tmp_path / "p.toml").write_text('[urdf]\nrobot = "panda"\n\n' + text)
    (tmp_path / "s.toml").write_text('[scenario]\nmodel = "p.toml"\nduration = 1.0\noutput_steps = 10\n'
                                     '[[gates]]\nmetric = "torques.pinocchio_vs_mujoco.max_rel_error"\nlimit = 1e-9\n')
    assert main(["run", str(tmp_path / "s.toml"), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0] and "p.toml" in err[0]
    assert not (tmp_path / "out").exists()


@pytest.mark.slow  # a few seconds: a whole pipeline or a subprocess
def test_mujoco_applies_each_term_as_the_law_says(run_scenario):
    """The drive torques MuJoCo records on ur5_friction, less Pinocchio's rigid-body RNEA of the same
    robot without drives, are the law's friction and rotor-inertia torques (to round-off of the
    joint loads): armature in MuJoCo's mass matrix, viscous as its damping, Coulomb and offset applied."""
    out = run_scenario(SCENARIOS / "ur5_friction.toml")
    rec, spec = out.recording, out.scenario.robot
    rigid = load_spec(MODELS / "ur5.toml")
    assert rigid.joint_names == spec.joint_names and all(f.none for f in rigid.frictions)
    cols = [rec.joint_index(j) for j in spec.joint_names]
    q, qd, qdd, tau = rec.q[:, cols], rec.qd[:, cols], rec.qdd[:, cols], rec.tau[:, cols]
    tau_rigid = rnea(build_model(rigid, out.scenario.gravity_W), q, qd, qdd).tau
    law = friction.torque(spec.frictions, qd, qdd)
    assert np.max(np.abs(law)) > 1.0  # the drives matter: several N m
    np.testing.assert_allclose(tau - tau_rigid, law, rtol=0, atol=1e-9 * np.max(np.abs(tau)))


@pytest.mark.slow  # a built-in scenario whole (its gates run in .ci/run; this reads beyond them)
def test_three_sources_agree_with_friction_and_the_identification_finds_it(run_scenario):
    """Ideal data: the torques agree three ways to 1e-9 of the joint loads (measured ~1e-14), and every
    friction term and rotor inertia that is a base parameter on its own comes back to 1e-8
    (measured 8e-13); the armature of the vertical first joint only adds to its link's I_zz."""
    r = results_of(run_scenario(SCENARIOS / "ur5_friction.toml"))
    for pair in ("pinocchio_vs_mujoco", "graph_vs_mujoco", "graph_vs_pinocchio"):
        assert r["torques"][pair]["max_rel_error"] <= 1e-9
    f = r["torque_identification"]["friction"]
    assert f["max_rel_error"] <= 1e-8
    alone = [(j, t) for j, terms in f["joints"].items() for t, e in terms.items() if "true" in e]
    assert len(alone) >= 3 * 6  # viscous, Coulomb and offset of every joint at least
    assert "in" in f["joints"]["shoulder_pan_joint"]["armature"]
    assert r["torque_identification"]["max_rel_error"] <= 1e-8
