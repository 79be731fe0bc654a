"""The paper's scenario recorded in MuJoCo: the recording obeys the laws it must obey.

Every check here works from recording.csv as written by `harness run` (fixture `kr500_csv`) plus
the model's masses and inertias, except where a test says it compares with the engine's own
orientation matrices. Tolerances:
- 1e-9 relative for balance laws: both sides are double-precision evaluations of the same
  instant (measured: about 1e-15); anything above 1e-9 is a wrong frame, sign or point.
- 1e-9 rad or m for tracking the prescribed motion: RK4 at 0.5 ms with computed-torque drive
  tracks to about 3e-12 (measured); 1e-9 still catches any drive or integration fault.
"""

from __future__ import annotations

import numpy as np
import pytest

from harness.base.series import TimeSeries
from harness.model.load import load_spec
from harness.papers.graph_theory_2021.cardano import A_0i, cond_D
from harness.papers.graph_theory_2021.readings import Readings, exact
from tests.conftest import MODELS

REL = 1e-9


def _masses(scenario, rec: TimeSeries) -> np.ndarray:
    return np.array([scenario.robot.body(b).mass for b in rec.bodies])


def _outboard(scenario, rec: TimeSeries, joint: str) -> list[int]:
    return [rec.body_index(b.name) for b in scenario.robot.outboard_bodies(joint) if not b.massless]


def test_recording_has_one_row_per_output_step(kr500_csv):
    assert len(kr500_csv.t) == 101
    np.testing.assert_allclose(kr500_csv.t, np.linspace(0, 2, 101), rtol=0, atol=1e-15)
    assert kr500_csv.joints == ("rail", "O1", "O2", "O3", "O4", "O5", "O6")
    assert kr500_csv.bodies == ("B1", "B2", "B3", "B4", "B5", "B6")


def test_rail_position_is_t_squared(kr500_csv):
    """Rail at 2 m/s^2 from rest: x = t^2."""
    t = kr500_csv.t
    np.testing.assert_allclose(kr500_csv.q[:, 0], t**2, rtol=0, atol=1e-9)
    np.testing.assert_allclose(kr500_csv.qd[:, 0], 2 * t, rtol=0, atol=1e-9)
    np.testing.assert_allclose(kr500_csv.qdd[:, 0], 2.0, rtol=0, atol=4.4e-7)  # see below


def test_every_joint_follows_its_prescribed_motion(kr500_rail, kr500_csv):
    q, qd, qdd = kr500_rail.prescribed(kr500_csv.t)
    np.testing.assert_allclose(kr500_csv.q, q, rtol=0, atol=1e-9)
    np.testing.assert_allclose(kr500_csv.qd, qd, rtol=0, atol=1e-9)
    # q'' = q''_d + 2 w e' + w^2 e (the drive law): the 1e-9 bounds on e, e' bound it by
    # (w^2 + 2 w) 1e-9 = 4.4e-7 at w = 20 rad/s (measured: 3e-9)
    w = kr500_rail.simulation.tracking_bandwidth
    np.testing.assert_allclose(kr500_csv.qdd, qdd, rtol=0, atol=(w**2 + 2 * w) * 1e-9)
    # O1 and O2 at 9.5493 rad/s^2 from rest, O3..O6 held at zero
    t2 = kr500_csv.t**2
    np.testing.assert_allclose(kr500_csv.q[:, 1:3], 0.5 * 9.5493 * np.column_stack([t2, t2]), atol=1e-9)
    np.testing.assert_allclose(kr500_csv.q[:, 3:], 0.0, atol=1e-9)


@pytest.mark.parametrize("joint", ["rail", "O1", "O2", "O3", "O4", "O5", "O6"])
def test_joint_force_is_newtons_law_for_the_bodies_outboard(kr500_rail, kr500_csv, joint):
    """F_J = sum over outboard bodies of m_k (a_k - g), at every row, from the CSV alone."""
    rec = kr500_csv
    k = _outboard(kr500_rail, rec, joint)
    m = _masses(kr500_rail, rec)[k]
    expected = np.einsum("k,nkc->nc", m, rec.a_W[:, k] - kr500_rail.gravity_W)
    F = rec.F_W[:, rec.joint_index(joint)]
    err = np.linalg.norm(F - expected, axis=1) / np.linalg.norm(expected, axis=1)
    assert err.max() <= REL, f"worst row t = {rec.t[err.argmax()]} s: {err.max():.2e}"


@pytest.mark.parametrize("joint", ["rail", "O1", "O2", "O3", "O4", "O5", "O6"])
def test_joint_moment_is_eulers_law_for_the_bodies_outboard(kr500_rail, kr500_csv, joint):
    """M_J about O_J = sum_k (r_k - O_J) x m_k (a_k - g) + J_k omega'_k + omega_k x J_k omega_k,
    with J_k = A(0k) J_k^(k) A(0k)^T from the recorded Cardano angles (Eq. 30 in world form).
    The joint point O_J is where the inner end of the child sits: child CoM - A(0k) c."""
    rec, robot = kr500_csv, kr500_rail.robot
    j = robot.joint(joint)
    child = j.child if not robot.body(j.child).massless else robot.outer_joints(j.child)[0].child
    c = rec.body_index(child)
    c_B = robot.body(child).R_WB0.T @ (j.p_W0 - robot.body(child).p_W_com0)  # O_J in child frame
    O_J = rec.p_W[:, c] + np.einsum("nab,b->na", rec.R_WB[:, c], c_B)
    expected = np.zeros((len(rec.t), 3))
    for k in _outboard(kr500_rail, rec, joint):
        body = robot.body(rec.bodies[k])
        A = rec.R_WB[:, k]
        J_W = A @ body.I_B @ np.swapaxes(A, 1, 2)
        w, wd = rec.omega_W[:, k], rec.omegadot_W[:, k]
        expected += np.cross(rec.p_W[:, k] - O_J, body.mass * (rec.a_W[:, k] - kr500_rail.gravity_W))
        expected += np.einsum("nab,nb->na", J_W, wd) + np.cross(w, np.einsum("nab,nb->na", J_W, w))
    M = rec.M_W[:, rec.joint_index(joint)]
    err = np.linalg.norm(M - expected, axis=1) / np.linalg.norm(expected, axis=1)
    assert err.max() <= REL, f"worst row t = {rec.t[err.argmax()]} s: {err.max():.2e}"


def test_drive_is_the_wrench_component_along_the_joint_axis(kr500_rail, kr500_csv):
    """The recorded drive force/torque is what the joint transmits along its axis; the rest of
    the wrench is constraint reaction."""
    rec, robot = kr500_csv, kr500_rail.robot
    for j, joint in enumerate(robot.joints):
        child = robot.body(joint.child) if not robot.body(joint.child).massless else None
        if child is None:  # the carriage translates without turning: its axis stays put
            axis = np.broadcast_to(joint.axis_W0, (len(rec.t), 3))
        else:
            A = rec.R_WB[:, rec.body_index(child.name)]
            axis = np.einsum("nab,b->na", A, child.R_WB0.T @ joint.axis_W0)
        wrench = rec.M_W[:, j] if joint.revolute else rec.F_W[:, j]
        along = np.einsum("na,na->n", wrench, axis)
        scale = np.linalg.norm(wrench, axis=1)
        assert np.max(np.abs(along - rec.tau[:, j]) / scale) <= REL, joint.name


def test_cardano_angles_rebuild_the_engines_orientation(kr500_recording):
    """A(0i) from the recorded angles equals MuJoCo's body orientation at every row, including
    the rows at or near gimbal lock."""
    rec = kr500_recording
    np.testing.assert_allclose(A_0i(_readings(rec).theta), rec.R_WB, rtol=0, atol=1e-12)


def test_joint_points_from_both_bodies_coincide(kr500_rail, kr500_csv):
    """Rebuilding each body from its centre of mass and the e1 direction of its recorded Cardano
    angles, O_i = r_(i-1) + l_(i-1)/2 e1(i-1) = r_i - l_i/2 e1(i) (Eqs. 65-69), and O1 rides on the
    rail: O1 = (x_rail, 0, 0)."""
    rec, robot = kr500_csv, kr500_rail.robot
    e1 = rec.R_WB[..., 0]  # (n, nb, 3)
    half = np.array([robot.body(b).cylinder.length / 2 for b in rec.bodies])
    inner_end = rec.p_W - half[None, :, None] * e1
    outer_end = rec.p_W + half[None, :, None] * e1
    np.testing.assert_allclose(inner_end[:, 1:], outer_end[:, :-1], rtol=0, atol=1e-9)
    rail = np.column_stack([rec.q[:, 0], np.zeros(len(rec.t)), np.zeros(len(rec.t))])
    np.testing.assert_allclose(inner_end[:, 0], rail, rtol=0, atol=1e-9)


def test_b1_angles_are_continuous_through_gimbal_lock(kr500_csv):
    """B1 spins about the vertical: A(01) = Ry(-pi/2) Rx(q_O1), whose continuous Cardano angles are
    alpha = gamma = pi/2, beta = q_O1 - pi/2 (harness.papers.graph_theory_2021.cardano). B1 starts in lock at t = 0 and
    meets it again at every multiple of pi; the angles stay smooth through all of it."""
    theta = _readings(kr500_csv).theta[:, kr500_csv.body_index("B1")]
    q_O1 = kr500_csv.q[:, kr500_csv.joint_index("O1")]
    np.testing.assert_allclose(theta[:, 0], np.pi / 2, atol=1e-9)
    np.testing.assert_allclose(theta[:, 1], q_O1 - np.pi / 2, atol=1e-9)
    np.testing.assert_allclose(theta[:, 2], np.pi / 2, atol=1e-9)


def test_rows_near_gimbal_lock_are_flagged(kr500_csv):
    """B1 is flagged at t = 0 and on both rows around every time O1 passes a multiple of pi
    (t_k = sqrt(2 k pi / 9.5493)); the arm B2..B6 never comes near lock (cos beta >= 0.866)."""
    rec = kr500_csv
    view = _readings(rec)
    b1 = view.gimbal[:, rec.body_index("B1")]
    assert b1[0]
    dt = rec.t[1] - rec.t[0]
    t_k = np.sqrt(2 * np.pi * np.arange(1, 7) / 9.5493)
    assert t_k[-1] < rec.t[-1] < np.sqrt(2 * np.pi * 7 / 9.5493)
    for tk in t_k:
        before = int(np.floor(tk / dt))
        assert b1[before] and b1[before + 1], f"lock at t = {tk:.4f} s not flagged"
    assert not view.gimbal[:, 1:].any()
    assert np.cos(view.theta[:, 1:, 1]).min() >= 0.866
    assert np.all(cond_D(view.theta[:, 1:]) < 10)


def test_csv_round_trip_is_exact(kr500_recording, kr500_csv):
    for name in ("t", "q", "qd", "qdd", "tau", "F_W", "M_W", "p_W", "v_W", "R_WB", "a_W", "omega_W", "omegadot_W"):
        np.testing.assert_array_equal(getattr(kr500_csv, name), getattr(kr500_recording, name), name)


def _readings(rec: TimeSeries) -> Readings:
    """The graph-theory study's readings of a kr500 recording: its Cardano angles and gimbal flags."""
    return exact(rec, load_spec(MODELS / "kr500.toml").inner_joint_arms_B())


def test_the_bodies_cardano_angles_are_written_beside_the_recording_and_reproduce_its_orientations(kr500_run,
                                                                                                   kr500_csv):
    """cardano.csv holds, row by row as recording.csv, every body's angles (alpha, beta, gamma) of Eq. 29:
    A(0i) of the angles read back is the recorded orientation R_WB to 1e-12 (two double-precision
    evaluations of the same rotation: measured 4e-16), gimbal lock of B1 at t = 0 included, and the
    column names are the documented ones."""
    import pandas as pd

    angles = pd.read_csv(kr500_run / "cardano.csv")
    names = ["t", *(f"{b}_{a}" for b in kr500_csv.bodies for a in ("alpha", "beta", "gamma"))]
    assert list(angles.columns) == names
    np.testing.assert_array_equal(angles["t"].to_numpy(), kr500_csv.t)
    theta = angles[names[1:]].to_numpy().reshape(len(angles), len(kr500_csv.bodies), 3)
    np.testing.assert_allclose(A_0i(theta), kr500_csv.R_WB, rtol=0, atol=1e-12)


def test_the_csv_writer_writes_the_bytes_of_numpys_and_pandas_writers_every_double_read_back_equal():
    """harness/base/csvtext.py against the two writers it stands for, on the values that tell printf
    formats apart: subnormals, -0, infinities, NaN (pandas' empty cell, numpy's "nan"), an integer and a
    boolean column ("%d"); and every float read back is the double written."""
    import io

    import pandas as pd

    from harness.base.csvtext import csv_text

    rng = np.random.default_rng(7)
    x = rng.standard_normal(64) * np.logspace(-310, 300, 64)
    x[[3, 9, 20]] = (-0.0, np.inf, -np.inf)
    y = rng.standard_normal(64)
    y[[0, 5, 63]] = np.nan
    floats = {"t": np.arange(64) * 1e-3, "x": x, "y": y}
    assert csv_text(floats, missing="") == pd.DataFrame(floats).to_csv(index=False, float_format="%.17g")
    with_ints = {**floats, "k": np.arange(64), "held": np.arange(64) % 3 == 0}
    expected = io.StringIO()
    expected.write(",".join(with_ints) + "\n")
    np.savetxt(expected, np.column_stack(list(with_ints.values())).astype(float), delimiter=",",
               fmt=["%.17g"] * 3 + ["%d"] * 2)
    text = csv_text(with_ints)
    assert text == expected.getvalue()
    back = pd.read_csv(io.StringIO(text))
    for name in floats:
        np.testing.assert_array_equal(back[name].to_numpy(), floats[name])  # NaN where NaN, else bit-equal
    assert list(back["held"]) == [int(h) for h in with_ints["held"]]
