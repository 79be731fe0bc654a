"""Joint torques three ways: MuJoCo (what drove the simulation), Pinocchio RNEA (built from the
spec, not from the MJCF) and the graph-theory model (from the recorded motion alone)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from harness.engines.pinocchio import rnea_on_recording
from harness.papers.graph_theory_2021.dynamics import build_graph_model
from harness.papers.graph_theory_2021.inverse import inverse_dynamics
from harness.stages.metrics import joint_load_scale, pair_metrics
from tests.conftest import DATA, MODELS, SCENARIOS, graph_model, readings, results_of

# branch_deep: MuJoCo numbers its coordinates depth-first, the spec breadth-first, and there they differ
SCENARIO_PATHS = pytest.mark.parametrize(
    "path", [SCENARIOS / "kr500_rail.toml", SCENARIOS / "kr500_all_joints.toml",
             DATA / "scenarios" / "branch_sines.toml", DATA / "scenarios" / "branch_deep_sines.toml",
             DATA / "scenarios" / "ball_arm_sines.toml"],
    ids=["kr500_rail", "kr500_all_joints", "branch", "branch_deep", "ball_arm"])
REL = 1e-9  # measured agreement is about 1e-14 of each joint's load


@SCENARIO_PATHS
def test_three_sources_agree_at_every_step_for_every_joint(run_scenario, path):
    torques = results_of(run_scenario(path))["torques"]
    for pair in ("graph_vs_pinocchio", "graph_vs_mujoco", "pinocchio_vs_mujoco"):
        assert torques[pair]["max_rel_error"] <= REL, (pair, torques[pair])
    assert len(torques["samples"]) == len(run_scenario(path).recording.t)


@SCENARIO_PATHS
def test_joint_reaction_wrenches_agree(run_scenario, path):
    """Pinocchio's data.f (moved to the joint point, world components) and the graph model's
    force elements and moments equal the wrenches MuJoCo's sensors recorded."""
    reactions = results_of(run_scenario(path))["torques"]["reactions"]
    for source in ("pinocchio_vs_mujoco", "graph_vs_mujoco"):
        for part in ("force", "moment"):
            assert reactions[source][part]["max_rel_error"] <= REL, (source, part)


def test_all_seven_joints_move_in_the_all_joints_scenario(run_scenario):
    rec = run_scenario(SCENARIOS / "kr500_all_joints.toml").recording
    assert np.all(np.ptp(rec.q, axis=0) > 0.1)


@SCENARIO_PATHS
def test_graph_inverse_dynamics_from_the_recorded_body_motion_equals_the_plugin_from_joint_coordinates(
        run_scenario, path):
    """Two routes into the same Newton-Euler equations: the body motion as MuJoCo recorded it
    (Cardano angles, centre-of-mass accelerations, angular rates), with every recorded joint force
    zeroed so that none can leak in, and the model-under-test plugin, which is given (q, q', q'')
    only and finds the body motion by its own forward kinematics of the tree."""
    out = run_scenario(path)
    seen = readings(out)
    blind = dataclasses.replace(seen, F_W=np.zeros_like(seen.F_W), M_W=np.zeros_like(seen.M_W),
                                tau=np.zeros_like(seen.tau))
    from_recording = inverse_dynamics(out.scenario.robot, graph_model(out), blind).tau
    plugin = next(m for m in out["torques"].models if m.name == "graph").tau
    scale = joint_load_scale(out.scenario.robot, out.recording)
    assert np.max(np.abs(from_recording - plugin) / scale) <= REL


def _with_mass(spec, body_name, factor):
    bodies = tuple(dataclasses.replace(b, mass=b.mass * factor) if b.name == body_name else b
                   for b in spec.bodies)
    return dataclasses.replace(spec, bodies=bodies)


@pytest.mark.parametrize("body", ["B2", "B4"])
def test_a_one_percent_mass_error_shows_at_exactly_the_joints_that_carry_it(run_scenario, body):
    """Model under test with m_k 1 % too large, against MuJoCo's recording of the true robot.
    Torque is linear in mass, so the graph model (and Pinocchio built from the same wrong spec)
    must be off by exactly 0.01 m_k u_J . ((r_k - O_J) x (a_k - g)) at a revolute joint J that
    carries B_k, 0.01 m_k u_J . (a_k - g) at a prismatic one, and by nothing elsewhere: the joints
    outboard of B_k, and O4, whose axis passes through B4's centre of mass."""
    out = run_scenario(SCENARIOS / "kr500_rail.toml")
    rec, spec, g = readings(out), out.scenario.robot, out.scenario.gravity_W
    wrong = _with_mass(spec, body, 1.01)
    graph = inverse_dynamics(wrong, build_graph_model(wrong, g), rec).tau
    pin = rnea_on_recording(wrong, g, rec).tau
    mj = rec.tau[:, [rec.joint_index(j) for j in spec.joint_names]]

    k = rec.body_index(body)
    dm = 0.01 * spec.body(body).mass
    expected = np.zeros_like(mj)
    for jj, joint in enumerate(spec.joints):
        if body not in {b.name for b in spec.outboard_bodies(joint.name)}:
            continue
        carried = joint if joint.child in rec.bodies else spec.outer_joints(joint.child)[0]
        c = rec.body_index(carried.child)
        child = spec.body(carried.child)
        A = rec.R_WB[:, c]
        O_J = rec.p_W[:, c] + np.einsum("nab,b->na", A, child.R_WB0.T @ (carried.p_W0 - child.p_W_com0))
        load = dm * (rec.a_W[:, k] - g)
        if joint.revolute:
            u = np.einsum("nab,b->na", A, child.R_WB0.T @ joint.axis_W0)
            expected[:, jj] = np.einsum("na,na->n", u, np.cross(rec.p_W[:, k] - O_J, load))
        else:
            expected[:, jj] = load @ joint.axis_W0
    scale = joint_load_scale(spec, rec)
    np.testing.assert_allclose((graph - mj) / scale, expected / scale, rtol=0, atol=REL)
    np.testing.assert_allclose((pin - mj) / scale, expected / scale, rtol=0, atol=REL)
    report = pair_metrics(graph, mj, scale, rec.t, spec.joint_names)
    assert report["max_rel_error"] > 1e-4  # caught
    per_joint = report["max_rel_error_per_joint"]
    affected = {j for j, e in per_joint.items() if e > REL}
    assert affected == {spec.joint_names[jj] for jj in range(len(spec.joints))
                        if np.max(np.abs(expected[:, jj]) / scale[jj]) > REL}
    assert report["max_rel_joint"] in affected


def test_the_mass_matrix_with_rotor_inertia_is_rneas_and_pinocchios_own():
    """M(q) with each joint's rotor inertia, checked two independent ways at random states of the UR5
    with drives (armature 0.35, 0.35, 0.2, 0.05, 0.05, 0.05 kg m^2): column k is RNEA's torque for
    q'' = e_k at rest less its torque at rest (exact: RNEA is linear in q''), and Pinocchio's own CRBA
    with `model.armature` set gives the same matrix. Round-off of either: about 1e-15 of |M|; 1e-12
    leaves a thousandfold margin and catches a rotor inertia put anywhere but on its own diagonal."""
    import pinocchio as pin

    from harness.engines.pinocchio import build_model, crba, rnea
    from harness.model import friction
    from harness.model.load import load_spec

    spec = load_spec(MODELS / "ur5_friction.toml")
    armature = friction.values(spec_frictions := tuple(j.friction for j in spec.joints))[:, 0]
    assert len(set(armature)) > 1 and len(spec_frictions) == 6  # distinct: a misplaced one shows
    pm = build_model(spec, np.array([0.0, 0.0, -9.81]))
    rng = np.random.default_rng(3)
    q = rng.uniform(-np.pi, np.pi, (20, 6))
    M = crba(pm, q)
    n = q.shape[1]
    zero = np.zeros_like(q)
    at_rest = rnea(pm, q, zero, zero).tau
    columns = np.stack([rnea(pm, q, zero, np.tile(np.eye(n)[k], (len(q), 1))).tau - at_rest for k in range(n)], axis=-1)
    scale = np.max(np.abs(M))
    np.testing.assert_allclose(M, columns, rtol=0, atol=1e-12 * scale)
    model = pm.model.copy()
    model.armature[[model.joints[j].idx_v for j in pm.joint_ids]] = armature
    data = model.createData()
    for k in range(len(q)):
        full = np.zeros(model.nq)
        full[pm.q_index] = q[k]
        M_pin = pin.crba(model, data, full)
        M_pin = np.triu(M_pin) + np.triu(M_pin, 1).T
        np.testing.assert_allclose(M[k], M_pin[np.ix_(pm.q_index, pm.q_index)], rtol=0, atol=1e-12 * scale)
