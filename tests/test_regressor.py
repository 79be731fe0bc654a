"""The batched joint-torque regressor (harness/model/regressor.py) against Pinocchio's own, sample by
sample, and against Pinocchio's RNEA; the identification's layouts of it (harness/identify/torque_id.py)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import harness.identify.torque_id
from harness.engines.pinocchio import build_model, rnea
from harness.identify.torque_id import regressor, regressor_by_joint, true_parameters
from harness.model.load import load_spec
from harness.model.regressor import joint_torque_regressor, supports
from tests.conftest import DATA, MODELS

# a chain on a rail with a massless carriage (kr500), a 7-joint arm, a 6-joint arm, and a branched
# tree with a prismatic joint between massive bodies and tilted axes
ROBOTS = {"kr500": MODELS / "kr500.toml", "panda_arm": MODELS / "panda_arm.toml", "ur5": MODELS / "ur5.toml",
          "branch": DATA / "models" / "branch.toml"}
GRAVITY = np.array([0.3, -0.2, -9.81])  # tilted: every component of the gravity columns shows


def _states(nq: int, samples: int, seed: int = 0) -> tuple[np.ndarray, ...]:
    rng = np.random.default_rng(seed)
    return tuple(rng.uniform(-2.0, 2.0, (samples, nq)) for _ in range(3))


@pytest.mark.parametrize("robot", list(ROBOTS))
def test_the_batched_regressor_is_pinocchios_sample_by_sample(robot):
    """500 random states (positions, rates and accelerations within +-2 in SI units): every entry
    within 1e-13 of the largest (measured 6e-16: the same products, summed in another order)."""
    pm = build_model(load_spec(ROBOTS[robot]), GRAVITY)
    model, data = pm.model, pm.model.createData()
    assert supports(model)
    q, qd, qdd = _states(model.nq, 500)
    ours = joint_torque_regressor(model, q, qd, qdd)  # (nv, p, N)
    for k in range(len(q)):
        expected = pin.computeJointTorqueRegressor(model, data, q[k], qd[k], qdd[k])
        np.testing.assert_allclose(ours[:, :, k], expected, rtol=0, atol=1e-13 * np.abs(expected).max())


@pytest.mark.parametrize("robot", list(ROBOTS))
def test_regressor_times_the_parameters_is_pinocchios_rnea(robot):
    """W(q, q', q'') theta, friction and rotor inertia included, equals the torques of Pinocchio's
    RNEA plus the drives' law (harness/model/friction.py) within 1e-12 of the largest torque."""
    spec = load_spec(ROBOTS[robot])
    pm = build_model(spec, GRAVITY)
    q, qd, qdd = _states(len(spec.joint_names), 300, seed=1)
    tau = rnea(pm, q, qd, qdd).tau
    predicted = (regressor(pm, q, qd, qdd, True) @ true_parameters(pm, True)).reshape(tau.shape)
    np.testing.assert_allclose(predicted, tau, rtol=0, atol=1e-12 * np.abs(tau).max())


def test_the_two_layouts_and_pinocchios_loop_give_one_regressor(monkeypatch):
    """regressor_by_joint (joint, column, sample) holds regressor's rows (sample, joint) transposed;
    a reused `out` written again gives the same entries; a model the batched path does not read
    goes through Pinocchio's call sample by sample, with the same result (1e-13 of the largest)."""
    spec = load_spec(ROBOTS["branch"])
    pm = build_model(spec, GRAVITY)
    q, qd, qdd = _states(len(spec.joint_names), 64, seed=2)
    n = len(spec.joint_names)
    by_joint = regressor_by_joint(pm, q, qd, qdd, True)
    stacked = regressor(pm, q, qd, qdd, True)
    np.testing.assert_array_equal(by_joint.transpose(2, 0, 1).reshape(len(q) * n, -1), stacked)
    out = np.zeros_like(by_joint)
    regressor_by_joint(pm, *_states(n, 64, seed=3), True, out=out)
    np.testing.assert_array_equal(regressor_by_joint(pm, q, qd, qdd, True, out=out), by_joint)
    monkeypatch.setattr(harness.identify.torque_id, "batched_supports", lambda model: False)
    looped = regressor_by_joint(pm, q, qd, qdd, True)
    np.testing.assert_allclose(looped, by_joint, rtol=0, atol=1e-13 * np.abs(by_joint).max())


@pytest.mark.parametrize("robot", list(ROBOTS))
def test_the_regressor_made_a_chunk_of_samples_at_a_time_is_the_whole_bit_for_bit(robot, monkeypatch):
    """regressor() makes its rows SAMPLES_AT_A_TIME samples at a time (a long log's regressor is not
    made twice over, once joint by joint and once transposed): each sample's rows are computed alone,
    so the chunks (here 37 samples, the last one short) give the whole's rows bit for bit."""
    spec = load_spec(ROBOTS[robot])
    pm = build_model(spec, GRAVITY)
    n = len(spec.joint_names)
    q, qd, qdd = _states(pm.model.nq, 200, seed=4)
    q, qd, qdd = q[:, :n], qd[:, :n], qdd[:, :n]
    whole = regressor_by_joint(pm, q, qd, qdd, True).transpose(2, 0, 1).reshape(len(q) * n, -1)
    monkeypatch.setattr(harness.identify.torque_id, "SAMPLES_AT_A_TIME", 37)
    np.testing.assert_array_equal(regressor(pm, q, qd, qdd, True), whole)
