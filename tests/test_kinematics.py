"""The batched forward kinematics of a tree (harness/model/kinematics.py), hand-written for speed
(every step an operation on (N,) arrays), against Pinocchio's forwardKinematics state by state:
each body's orientation, centre-of-mass position, velocity and classical acceleration, angular
velocity and acceleration, and each joint's axis and point. Both are double-precision recursions
over the same tree: they agree to about 1e-15 of the quantities' size; 1e-12 is the tolerance."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from harness.engines.pinocchio import build_model
from harness.model.kinematics import forward_kinematics
from harness.model.load import load_spec
from tests.conftest import DATA, MODELS

ROBOTS = [MODELS / "kr500.toml", MODELS / "ur5.toml", MODELS / "panda.toml", MODELS / "planar6_proposed.toml",
          DATA / "models" / "branch.toml"]


@pytest.mark.parametrize("path", ROBOTS, ids=lambda p: p.stem)
def test_the_batched_kinematics_is_pinocchios_state_by_state(path):
    spec = load_spec(path)
    pm = build_model(spec, np.zeros(3))
    model, data = pm.model, pm.model.createData()
    rng = np.random.default_rng(5)
    N, n = 25, len(spec.joints)
    q, qd, qdd = rng.uniform(-1.5, 1.5, (N, n)), rng.standard_normal((N, n)), rng.standard_normal((N, n))
    kin = forward_kinematics(spec, q, qd, qdd)
    frame = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
    owner = {j.child: pm.joint_ids[k] for k, j in enumerate(spec.joints)}
    for s in range(N):
        full = [np.zeros(model.nq) for _ in range(3)]
        for x, v in zip(full, (q[s], qd[s], qdd[s]), strict=True):
            x[pm.q_index] = v
        pin.forwardKinematics(model, data, *full)
        for b, name in enumerate(kin.bodies):
            body = spec.body(name)
            jid = owner[name]
            oMi = data.oMi[jid]
            w = pin.getVelocity(model, data, jid, frame).angular
            wd = pin.getAcceleration(model, data, jid, frame).angular
            a_O = pin.getClassicalAcceleration(model, data, jid, frame).linear
            v_O = pin.getVelocity(model, data, jid, frame).linear
            r = oMi.rotation @ (body.p_W_com0 - spec.inner_joint(name).p_W0)  # joint origin to the centre of mass
            expected = {
                "R_WB": oMi.rotation @ body.R_WB0,
                "p_W_com": oMi.translation + r,
                "v_W_com": v_O + np.cross(w, r),
                "a_W_com": a_O + np.cross(wd, r) + np.cross(w, np.cross(w, r)),
                "omega_W": w,
                "omegadot_W": wd,
            }
            for key, value in expected.items():
                got = getattr(kin, key)[s, b]
                scale = max(1.0, float(np.max(np.abs(value))))
                np.testing.assert_allclose(got, value, rtol=0, atol=1e-12 * scale, err_msg=f"{name} {key}")
        for k, joint in enumerate(spec.joints):
            jid = pm.joint_ids[k]
            fixed = data.oMi[model.parents[jid]] * model.jointPlacements[jid]  # the joint's frame on its inner body
            np.testing.assert_allclose(kin.axis_W[s, k], data.oMi[jid].rotation @ joint.axis_W0, rtol=0, atol=1e-12)
            np.testing.assert_allclose(kin.p_W_joint[s, k], fixed.translation, rtol=0,
                                       atol=1e-12 * max(1.0, float(np.max(np.abs(fixed.translation)))))
