"""Torque channels that measure nothing, found where a lab's log has them (harness/sources/log/checks.py,
harness/stages/log_judge.py): a channel reading exactly 0 on most rows, said by the checks; a channel
that does not follow the model's torque, said by the start check; neither refused nor hidden."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from harness.model.load import load_spec
from harness.sources.log.checks import DEAD_SHARE, check
from harness.sources.log.raw import RawLog
from harness.stages.log_judge import SIZED, UNRELATED, start
from tests.conftest import SCENARIOS

ROWS = 2000


def _motion(rng) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t = np.arange(ROWS) * 0.005
    q = 0.5 * np.sin(np.outer(t, [0.7, 1.1, 1.3, 1.7, 1.9, 2.3]) + np.arange(6))
    tau = 10.0 * np.cos(np.outer(t, [0.9, 1.2, 1.4, 1.6, 2.0, 2.2])) + 0.1 * rng.standard_normal((ROWS, 6))
    return t, q, tau


def test_a_channel_that_reads_zero_on_most_rows_is_counted_and_said():
    """The wrist 3's channel 0 on 90 % of its rows (as a mobile manipulator's wrist channels are), the
    elbow's on 40 %: the first named with its share in one line, every channel's share kept."""
    robot = load_spec(SCENARIOS.parent / "models" / "ur5.toml")
    rng = np.random.default_rng(3)
    t, q, tau = _motion(rng)
    tau[rng.random(ROWS) < 0.9, 5] = 0.0
    tau[rng.random(ROWS) < 0.4, 2] = 0.0
    checked = check(RawLog(t, tuple(robot.joint_names), q, None, tau, Path("log.csv")), robot)
    share = checked.record["torque_zero_share"]
    assert checked.record["torque_channels_zero"] == ["wrist_3_joint"]
    assert share["wrist_3_joint"] >= DEAD_SHARE > share["elbow_joint"] > 0.3
    said = [w for w in checked.warnings if "read exactly 0 on most rows" in w]
    assert len(said) == 1 and f"wrist_3_joint {100 * share['wrist_3_joint']:.0f} %" in said[0]


def test_a_channel_that_does_not_follow_the_models_torque_is_said_by_the_start_check():
    """The log's elbow channel white noise of its RMS (cosine with the model's torque about 0), a joint the
    model hardly loads (1e-3 of the largest RMS) with an unrelated channel too: the elbow alone named,
    under UNRELATED; the other says nothing under SIZED of the largest torque."""
    rng = np.random.default_rng(4)
    _, _, model = _motion(rng)
    model[:, 4] *= 1e-4
    log = model * 1.02
    log[:, 2] = np.sqrt(np.mean(model[:, 2] ** 2)) * rng.standard_normal(ROWS)
    log[:, 4] = rng.standard_normal(ROWS)
    joints = [f"j{k}" for k in range(6)]
    found = start(model, log, joints)
    assert found.unrelated == ("j2",) and abs(found.per_joint["j2"]["cosine"]) < UNRELATED
    assert np.sqrt(np.mean(model[:, 4] ** 2)) < SIZED * np.sqrt(np.mean(model**2, axis=0)).max()
    assert any("do not follow the model's torque" in line and "j2 (" in line for line in found.said())


def test_a_channel_off_by_a_factor_with_or_without_gravity_is_not_called_counterbalanced():
    """Currents read as torques (every channel 0.02 of the model's, whose torques are partly gravity): the
    start check reads them without gravity too, where they have the model's shape (cosine about 0.9) but
    are still off by a factor, so the likely cause stays a reading's, not a counterbalanced joint; a
    channel that matches a gravity-dominated model less its gravity (joint 1) is one, and only it."""
    rng = np.random.default_rng(6)
    _, _, motion = _motion(rng)
    gravity = 3.0 + 0.5 * np.cos(np.linspace(0.0, 6.0, ROWS))[:, None] * np.ones((1, 6))
    model = motion + gravity
    joints = [f"j{k}" for k in range(6)]
    read_wrongly = start(model, 0.02 * model, joints, lambda: motion)
    assert read_wrongly.findings and all("counterbalanced" not in f["likely"] for f in read_wrongly.findings)
    assert not any(v.get("counterbalanced") for v in read_wrongly.per_joint.values())
    heavy = motion + 40.0  # gravity that dominates the model's torques
    log = heavy.copy()
    log[:, 1] = motion[:, 1]  # joint 1's gravity held by a spring
    balanced = start(heavy, log, joints, lambda: motion)
    assert [j for j, v in balanced.per_joint.items() if v.get("counterbalanced") == "likely"] == ["j1"]


def test_a_counterbalanced_channels_rows_and_torques_are_its_joints_less_its_gravity():
    """The shoulder lift declared counterbalanced: at 30 random states of the UR5 with drives, its channel's
    torque is pinocchio.rnea's plus its drive terms less pinocchio.computeGeneralizedGravity's, every
    other channel the torque itself (1e-12 of the largest); the regressor's rows times the model's
    parameters give the same (the fit's and the friction law search's), and the structural base spans
    those rows (its rank theirs)."""
    import pinocchio as pin

    from harness.stages.log_model import log_model

    robot = load_spec(SCENARIOS.parent / "models" / "ur5_friction.toml")
    model = log_model(robot, np.array([0.0, 0.0, -9.81]), counterbalanced=("shoulder_lift_joint",))
    rng = np.random.default_rng(8)
    q, qd, qdd = rng.uniform(-np.pi, np.pi, (30, 6)), rng.standard_normal((30, 6)), rng.standard_normal((30, 6))
    pm, data = model.pm, model.pm.model.createData()
    expected = np.empty((30, 6))
    for i in range(30):
        full, v, a = (np.zeros(pm.model.nq) for _ in range(3))
        full[pm.q_index], v[pm.q_index], a[pm.q_index] = q[i], qd[i], qdd[i]  # one coordinate per hinge
        tau = pin.rnea(pm.model, data, full, v, a)[pm.q_index]
        tau[1] -= pin.computeGeneralizedGravity(pm.model, data, full)[pm.q_index][1]
        for k, f in enumerate(robot.frictions):
            tau[k] += (f.armature * qdd[i, k] + f.viscous * qd[i, k]
                       + f.coulomb * np.tanh(qd[i, k] / f.coulomb_velocity) + f.offset)
        expected[i] = tau
    atol = 1e-12 * np.abs(expected).max()
    np.testing.assert_allclose(model.torques(pm, q, qd, qdd), expected, rtol=0, atol=atol)
    W = model.rows(pm, q, qd, qdd)
    np.testing.assert_allclose((W @ model.x_model).reshape(30, 6), expected, rtol=0, atol=atol)
    np.testing.assert_allclose(model.joint_rows(pm, q, qd, qdd) @ model.x_model, expected, rtol=0, atol=atol)  # the
    # friction law search's rows
    rank = np.linalg.matrix_rank(W)
    assert np.linalg.matrix_rank(W[:, model.base.independent]) == len(model.base.independent) == rank
