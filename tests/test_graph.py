"""The paper's graph-theory model (sections 2.1, 2.2) against the paper and the reference engine."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from harness.engines.mujoco import build_model
from harness.papers.graph_theory_2021.cardano import GIMBAL_COND_D, D, D_dot, angles_from_rotation
from harness.papers.graph_theory_2021.dynamics import angle_rates, body_series
from harness.papers.graph_theory_2021.topology import build_topology
from tests.conftest import DATA, SCENARIOS, graph_model, pinocchio_rnea, readings

# Eqs. 7 and 16 as printed for the 6R robot (the extraction lost the signs of S; S_e keeps them):
# O_i ends at B_i (-1) and O_(i+1) starts at B_i (+1).
PAPER_S = np.array([
    [-1, 1, 0, 0, 0, 0],
    [0, -1, 1, 0, 0, 0],
    [0, 0, -1, 1, 0, 0],
    [0, 0, 0, -1, 1, 0],
    [0, 0, 0, 0, -1, 1],
    [0, 0, 0, 0, 0, -1],
])


def test_kr500_incidence_and_force_element_matrices_are_the_papers(kr500_rail):
    top = build_topology(kr500_rail.robot)
    assert top.bodies == ("B1", "B2", "B3", "B4", "B5", "B6")
    assert top.joints == ("O1", "O2", "O3", "O4", "O5", "O6")
    np.testing.assert_array_equal(top.S, PAPER_S)
    np.testing.assert_array_equal(top.S_e, PAPER_S)


def test_kr500_body_joint_vectors_are_half_lengths_along_e1(kr500_rail):
    """Eq. 11: every non-zero C_ij is (l_i / 2) e1(i): body components (l_i / 2, 0, 0)."""
    top = build_topology(kr500_rail.robot)
    C = top.C_B()
    for i, body in enumerate(top.bodies):
        half = kr500_rail.robot.body(body).cylinder.length / 2
        for k in range(top.n):
            expected = [half, 0, 0] if PAPER_S[i, k] else [0, 0, 0]
            np.testing.assert_allclose(C[i, k], expected, atol=1e-15)


def test_branched_tree_incidence():
    """A tree with a branch: T2 and T3 both hang on T1. Every joint ends at exactly one body and
    starts at its inner body unless that is the ground."""
    from harness.runner.scenario import load_scenario

    top = build_topology(load_scenario(DATA / "scenarios" / "branch_sines.toml").robot)
    assert top.bodies == ("T1", "T2", "T3", "T4") and top.joints == ("J1", "J2", "J3", "J4")
    np.testing.assert_array_equal(top.S, [[-1, 1, 1, 0], [0, -1, 0, 0], [0, 0, -1, 1], [0, 0, 0, -1]])


def _engine_angles(scenario, t, reference):
    """Cardano angles of every body at times t, from MuJoCo's kinematics of the prescribed joint
    positions, continuous with `reference` (N, n, 3)."""
    model = build_model(scenario.robot, scenario.gravity_W, scenario.simulation)
    data = mujoco.MjData(model)
    q, _, _ = scenario.prescribed(t)
    qadr = [model.joint(j).qposadr[0] for j in scenario.robot.joint_names]
    bodies = [b.name for b in scenario.robot.massive_bodies]
    R = np.empty((len(t), len(bodies), 3, 3))
    for k in range(len(t)):
        data.qpos[qadr] = q[k]
        mujoco.mj_kinematics(model, data)
        R[k] = [data.body(b).xmat.reshape(3, 3) for b in bodies]
    return np.stack([[angles_from_rotation(R[k, i][None], reference[k, i])[0] for i in range(len(bodies))]
                     for k in range(len(t))])


@pytest.mark.parametrize("scenario_path", [SCENARIOS / "kr500_rail.toml",
                                           DATA / "scenarios" / "branch_sines.toml"],
                         ids=["kr500_rail", "branch_sines"])
def test_angle_rates_through_D_match_finite_differences_of_the_engines_orientation(
        run_scenario, scenario_path):
    """theta' = D^-1 omega^(i) and theta'' = D^-1 (omega'^(i) - D' theta') (Eqs. 33-34), from the
    recorded omega and omega', against five-point central differences of the angles of MuJoCo's
    orientation at t +- h, t +- 2h. With h = 1e-3 s and body rates up to w ~ 20 rad/s the
    truncation is about h^4 w^6 / 90 ~ 1e-6 rad/s^2 and the round-off 30 eps |theta| / (12 h^2)
    ~ 1e-8: 1e-6 of the largest value is a bound with room, and far below any error in D."""
    out = run_scenario(scenario_path)
    s = body_series(readings(out), graph_model(out).topology)
    theta_dot, theta_ddot, cond = angle_rates(s.theta, s.omega_B, s.omegadot_B)
    h = 1e-3
    f = {k: _engine_angles(out.scenario, s.t + k * h, s.theta) for k in (-2, -1, 1, 2)}
    f[0] = s.theta
    ok = cond <= GIMBAL_COND_D
    fd_dot = (-f[2] + 8 * f[1] - 8 * f[-1] + f[-2]) / (12 * h)
    fd_ddot = (-f[2] + 16 * f[1] - 30 * f[0] + 16 * f[-1] - f[-2]) / (12 * h**2)
    np.testing.assert_allclose(theta_dot[ok], fd_dot[ok], rtol=0, atol=1e-6 * np.max(np.abs(theta_dot[ok])))
    np.testing.assert_allclose(theta_ddot[ok], fd_ddot[ok], rtol=0,
                               atol=1e-6 * np.max(np.abs(theta_ddot[ok])))
    # and D, D' themselves reproduce omega and omega' from those differences
    omega = np.einsum("...ab,...b->...a", D(s.theta), fd_dot)
    np.testing.assert_allclose(omega[ok], s.omega_B[ok], rtol=0, atol=1e-6 * np.max(np.abs(s.omega_B)))
    omegadot = (np.einsum("...ab,...b->...a", D(s.theta), fd_ddot)
                + np.einsum("...ab,...b->...a", D_dot(s.theta, fd_dot), fd_dot))
    np.testing.assert_allclose(omegadot[ok], s.omegadot_B[ok], rtol=0,
                               atol=1e-6 * np.max(np.abs(s.omegadot_B)))


@pytest.mark.parametrize("scenario_path", [SCENARIOS / "kr500_rail.toml",
                                           DATA / "scenarios" / "branch_sines.toml"],
                         ids=["kr500_rail", "branch_sines"])
def test_unconstrained_dynamics_residual_vanishes_on_the_recording(run_scenario, scenario_path):
    """Eq. 36, A q'' - B = 0, at every row where D is well conditioned: at most 1e-9 of |B|
    (measured: about 2e-12, the cancellation of joint forces of 1e6 N into body resultants)."""
    res = run_scenario(scenario_path)["graph"].residual
    assert np.nanmax(np.where(res.evaluated, res.translational, np.nan)) <= 1e-9
    assert np.nanmax(np.where(res.evaluated, res.rotational, np.nan)) <= 1e-9


def test_rows_near_gimbal_lock_are_listed_with_cond_D(run_scenario):
    """kr500: the only rows not evaluated are B1's first ones, where cond(D) > 100; B1 starts in
    lock (cond(D) ~ 1e16 at t = 0)."""
    out = run_scenario(SCENARIOS / "kr500_rail.toml")
    res = out["graph"].residual
    skipped = np.argwhere(~res.evaluated)
    assert set(skipped[:, 1]) == {0}  # B1 only
    np.testing.assert_allclose(res.t[skipped[:, 0]], [0.0, 0.02, 0.04, 0.06], atol=1e-12)
    assert np.all(res.cond_D[~res.evaluated] > GIMBAL_COND_D)
    assert res.cond_D[0, 0] > 1e15
    assert np.all(res.cond_D[res.evaluated] <= GIMBAL_COND_D)


def test_torques_from_joint_coordinates_in_blocks_are_pinocchios_state_by_state(kr500_rail):
    """The graph model from (q, q', q'') alone evaluates BLOCK states at a time (bounded scratch memory):
    over two and a half blocks, including a last partial one, every state's torques equal Pinocchio's
    rnea of the same state to 1e-12 of the largest torque (round-off: measured about 1e-15)."""
    from harness.engines.pinocchio import build_model
    from harness.papers.graph_theory_2021.inverse import BLOCK
    from harness.papers.graph_theory_2021.model import make

    spec = kr500_rail.robot
    n, states = len(spec.joints), BLOCK * 5 // 2
    rng = np.random.default_rng(11)
    q, qd, qdd = rng.uniform(-1, 1, (states, n)), rng.uniform(-1, 1, (states, n)), rng.uniform(-2, 2, (states, n))
    tau = make(spec, kr500_rail.gravity_W).solve(q, qd, qdd).tau
    ref = pinocchio_rnea(build_model(spec, kr500_rail.gravity_W), q, qd, qdd)
    assert np.max(np.abs(tau - ref)) <= 1e-12 * np.max(np.abs(ref))


def test_blocks_of_states_written_into_the_same_arrays_are_each_evaluated_alone(kr500_rail):
    """The blocks of one call share their kinematics' arrays: the joint wrenches and torques of the
    first block and of the last, shorter one equal those of the same states evaluated alone,
    bit for bit (the same operations on the same numbers)."""
    from harness.papers.graph_theory_2021.inverse import BLOCK
    from harness.papers.graph_theory_2021.model import make

    graph = make(kr500_rail.robot, kr500_rail.gravity_W)
    n, states = len(kr500_rail.robot.joints), BLOCK * 5 // 2
    rng = np.random.default_rng(12)
    q, qd, qdd = (rng.uniform(-1, 1, (states, n)) for _ in range(3))
    whole = graph.solve(q, qd, qdd)
    for rows in (slice(0, BLOCK), slice(2 * BLOCK, states)):
        alone = graph.solve(q[rows], qd[rows], qdd[rows])
        for key in ("tau", "F_W", "M_W"):
            np.testing.assert_array_equal(getattr(whole, key)[rows], getattr(alone, key), err_msg=key)
