"""Refinement by simulation (harness/identify/refine.py, harness/stages/refinement.py) and the batched
rollouts it runs on (harness/engines/rollout.py, `rollouts`).

The rollouts are checked against an independent computation: MuJoCo's own mj_step (its RK4), one
start at a time, with the drive and the friction law applied at every stage by a control callback.
The batch takes the same stages in numpy with MuJoCo's accelerations of all rows in one call, so the
two must agree to round-off (1e-12 relative; measured equal to the last bit on these benches, the
accelerations being recovered from an Euler step of a power of two in seconds). The refinement is
checked on a bench log whose faults are known: torque channels 1 to 10 ms behind the encoders, and a
model whose friction law is five times too smooth."""

from __future__ import annotations

import dataclasses
import json

import mujoco
import numpy as np
import pandas as pd
import pytest

from harness.api import load_model, load_scenario
from harness.cli import main
from harness.engines.mujoco import build_spec
from harness.engines.rollout import ROWS_PER_THREAD, log_drives, rollouts, stage_times
from harness.model import drives as drive_law
from harness.stages.refinement import Candidate, choose, values
from tests.conftest import SCENARIOS, late_log, write_frame

STEPS = 60
TIMESTEP = 1e-3


@pytest.fixture(scope="module")
def ur5():
    return load_scenario(SCENARIOS / "ur5_friction.toml")


def _drives(B: int, n: int, seed: int) -> np.ndarray:
    """(B, 2 STEPS + 1, n): smooth torques at the stage times, a few N m."""
    rng = np.random.default_rng(seed)
    s = stage_times(STEPS, TIMESTEP)
    a, w = rng.normal(size=(B, 1, n)) * 5, rng.uniform(5, 20, size=(B, 1, n))
    return a * np.sin(w * s[None, :, None] + rng.uniform(0, 6, size=(B, 1, n)))


def _one_at_a_time(spec, gravity_W, frictions, q0, qd0, drive) -> tuple[np.ndarray, np.ndarray]:
    """mj_step, one start, the drive less the law's dry friction set at every RK4 stage."""
    model = build_spec(spec.with_frictions(frictions), gravity_W, "RK4", TIMESTEP).compile()
    data = mujoco.MjData(model)
    ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, j) for j in spec.joint_names]
    qadr, vadr = model.jnt_qposadr[ids], model.jnt_dofadr[ids]
    dry = drive_law.Dry(frictions, spec.transmission)
    f_v = np.array([f.viscous for f in frictions])
    viscous = np.diag(f_v) if spec.transmission is None else spec.transmission.N.T @ np.diag(f_v) @ spec.transmission.N

    def control(m, d):
        tau, v = drive[round(d.time / (TIMESTEP / 2))], d.qvel[vadr]
        # a load-dependent law's rigid-body torque: the drive less the rest of its friction
        d.qfrc_applied[vadr] = tau - (dry(v, tau - dry(v, load=False) - viscous @ v) if dry.needs_load else dry(v))

    data.qpos[qadr], data.qvel[vadr] = q0, qd0
    q, qd = [], []
    mujoco.set_mjcb_control(control)
    try:
        for _ in range(STEPS):
            mujoco.mj_step(model, data)
            q.append(data.qpos[qadr].copy())
            qd.append(data.qvel[vadr].copy())
    finally:
        mujoco.set_mjcb_control(None)
    return np.array(q), np.array(qd)


def test_batched_rollouts_are_mj_step_one_start_at_a_time(ur5):
    spec, n = ur5.robot, len(ur5.robot.joints)
    rng = np.random.default_rng(1)
    q0, qd0 = rng.normal(size=(3, n)) * 0.5, rng.normal(size=(3, n)) * 0.3
    drives = _drives(3, n, 2)
    law = tuple(spec.frictions)
    q, qd = rollouts(spec, ur5.gravity_W, [law] * 3, q0, qd0, drives, TIMESTEP)
    assert q.shape == qd.shape == (3, STEPS, n)
    for b in range(3):
        q_ref, qd_ref = _one_at_a_time(spec, ur5.gravity_W, law, q0[b], qd0[b], drives[b])
        np.testing.assert_allclose(q[b], q_ref, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(qd[b], qd_ref, rtol=1e-12, atol=1e-12)


def test_each_rollout_of_a_batch_runs_under_its_own_law(ur5):
    """Two laws that differ in every drive term (rotor inertia and viscous friction are MuJoCo's, the
    dry part the callback's): in one batch each rollout is what it is alone."""
    spec, n = ur5.robot, len(ur5.robot.joints)
    other = tuple(dataclasses.replace(f, armature=2 * f.armature + 0.1, viscous=0.5 * f.viscous, coulomb=3.0,
                                      coulomb_velocity=0.05, offset=-f.offset) for f in spec.frictions)
    rng = np.random.default_rng(3)
    q0, qd0 = rng.normal(size=(2, n)) * 0.5, rng.normal(size=(2, n)) * 0.3
    drives = _drives(2, n, 4)
    q, qd = rollouts(spec, ur5.gravity_W, [tuple(spec.frictions), other], q0, qd0, drives, TIMESTEP)
    q_ref, qd_ref = _one_at_a_time(spec, ur5.gravity_W, other, q0[1], qd0[1], drives[1])
    np.testing.assert_allclose(q[1], q_ref, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(qd[1], qd_ref, rtol=1e-12, atol=1e-12)
    assert np.max(np.abs(q[0] - q[1])) > 1e-4  # the laws differ enough to tell


@pytest.fixture(scope="module")
def tx40():
    return load_model(SCENARIOS.parent / "models" / "tx40.toml")


def test_every_family_of_law_and_a_coupled_drive_roll_out_as_mj_step_does(ur5, tx40):
    """Rows under Stribeck, load-dependent and asymmetric laws in one batch, and the TX40's coupled wrist
    (its motors' laws through N, their inertia and damping on MuJoCo's tendons), each against mj_step."""
    for spec, gravity_W, scale in ((ur5.robot, ur5.gravity_W, 1.0), (tx40, np.array([0.0, 0.0, -9.81]), 0.05)):
        n = len(spec.joints)
        # a rotor inertia on each motor (the TX40's file states none, and its hand's link alone is light)
        base = tuple(dataclasses.replace(f, armature=f.armature or 1e-4) for f in spec.frictions)
        laws = [base] + [tuple(dataclasses.replace(f, coulomb=1.0 + k, coulomb_velocity=0.02 * (k + 1), **extra)
                               for f in base)
                         for k, extra in enumerate(({"stribeck": 0.8, "stribeck_velocity": 0.1},
                                                    {"load_coulomb": 0.05},
                                                    {"viscous_asymmetry": 0.01, "coulomb_asymmetry": 0.3}))]
        rng = np.random.default_rng(7)
        q0, qd0 = rng.normal(size=(4, n)) * 0.5, rng.normal(size=(4, n)) * 0.3
        drives = scale * _drives(4, n, 8)  # the TX40's wrist motors: a few tenths of N m
        q, qd = rollouts(spec, gravity_W, laws, q0, qd0, drives, TIMESTEP)
        for b, law in enumerate(laws):
            q_ref, qd_ref = _one_at_a_time(spec, gravity_W, law, q0[b], qd0[b], drives[b])
            np.testing.assert_allclose(q[b], q_ref, rtol=1e-12, atol=1e-12)
            np.testing.assert_allclose(qd[b], qd_ref, rtol=1e-12, atol=1e-12)
            assert np.all(np.abs(q[b]) < 10)  # a motion, not a divergence


def test_a_rollout_is_the_same_on_the_pool_of_threads_as_alone(ur5):
    """A batch large enough for MuJoCo's threads gives each row what the calling thread gives it alone,
    a third of its rows diverging on the threads (MuJoCo warns from them) and cut there."""
    spec, n = ur5.robot, len(ur5.robot.joints)
    B = 2 * ROWS_PER_THREAD + 3
    rng = np.random.default_rng(9)
    q0, qd0 = rng.normal(size=(B, n)) * 0.5, rng.normal(size=(B, n)) * 0.3
    drives = _drives(B, n, 10)
    drives[1::3, 20:] = 1e30
    law = tuple(spec.frictions)
    q, qd = rollouts(spec, ur5.gravity_W, [law] * B, q0, qd0, drives, TIMESTEP)
    assert np.all(np.isnan(q[1::3, -1])) and np.all(np.isfinite(q[0::3])) and np.all(np.isfinite(q[2::3]))
    for b in (0, ROWS_PER_THREAD + 1, B - 1):
        alone, alone_d = rollouts(spec, ur5.gravity_W, [law], q0[b:b + 1], qd0[b:b + 1], drives[b:b + 1], TIMESTEP)
        np.testing.assert_array_equal(q[b], alone[0])
        np.testing.assert_array_equal(qd[b], alone_d[0])


def test_a_diverged_rollout_is_nan_from_its_step_on_and_leaves_the_others_alone(ur5):
    spec, n = ur5.robot, len(ur5.robot.joints)
    q0, qd0 = np.zeros((2, n)), np.zeros((2, n))
    drives = _drives(2, n, 5)
    drives[1, 20:] = 1e30  # MuJoCo resets a state past its bound: the rollout is lost from there
    q, _ = rollouts(spec, ur5.gravity_W, [tuple(spec.frictions)] * 2, q0, qd0, drives, TIMESTEP)
    alone, _ = rollouts(spec, ur5.gravity_W, [tuple(spec.frictions)], q0[:1], qd0[:1], drives[:1], TIMESTEP)
    np.testing.assert_array_equal(q[0], alone[0])
    lost = np.flatnonzero(np.isnan(q[1]).any(axis=1))
    assert len(lost) and lost[0] >= 9 and np.all(np.isnan(q[1, lost[0]:]))
    assert np.all(np.isfinite(q[1, : lost[0]]))


def test_a_late_channel_is_read_later():
    t = np.arange(0, 1, 0.01)
    tau = np.column_stack([np.sin(t), np.cos(t)])
    d = log_drives(t, tau, np.array([0.2]), 10, TIMESTEP, np.array([0.0, 0.005]))
    s = 0.2 + stage_times(10, TIMESTEP)
    np.testing.assert_allclose(d[0, :, 0], np.interp(s, t, tau[:, 0]), rtol=0, atol=0)
    np.testing.assert_allclose(d[0, :, 1], np.interp(s + 0.005, t, tau[:, 1]), rtol=0, atol=0)


def _candidate(label: str, cost: float, torque: float) -> Candidate:
    return Candidate(label, np.zeros((1, 10)), (), (), np.zeros(1), cost, torque)


def test_the_model_kept_predicts_best_among_those_that_fit_the_torques_as_well():
    consistent = _candidate("consistent", 1.0, 0.0100)
    better_motion_worse_torques = _candidate("a", 0.5, 0.0102)  # 2 % worse torques: beyond the 1 % slack
    better_both = _candidate("b", 0.8, 0.0100)
    chosen, reason = choose([consistent, better_motion_worse_torques, better_both])
    assert chosen == 2 and "'b'" in reason
    chosen, reason = choose([consistent, better_motion_worse_torques])
    assert chosen == 0 and "no candidate" in reason


def test_each_adjusted_value_is_read_from_its_own_joint():
    """A joint with nothing to adjust (a sharp sign, v_c = 0, and no delay asked for) has no slot: the
    slots after it still read their own joint's law, not the next one's."""
    from harness.model.friction import JointFriction

    frictions = (JointFriction(coulomb_velocity=0.01), JointFriction(coulomb_velocity=0.0),
                 JointFriction(coulomb_velocity=0.03))
    c = Candidate("c", np.zeros((3, 10)), frictions, (), np.array([1e-3, 2e-3, 3e-3]), 1.0, 0.01)
    assert values(((0, "coulomb_velocity"), (2, "coulomb_velocity"), (2, "delay")), c) == [0.01, 0.03, 3e-3]


LAGS = np.array([1.0, 2.5, 4.0, 6.0, 8.0, 10.0]) * 1e-3


@pytest.fixture(scope="module")
def late_log_wrong_law(tmp_path_factory, ur5):
    """An 8 s noise-free bench log at 500 Hz of the UR5 with drives, its torque channels LAGS behind
    the encoders, and a model file with the UR5's drives but each smoothing velocity 0.1 rad/s (the
    robot's: 0.02)."""
    import tomli_w

    from harness.base.tomlio import read_toml

    folder = tmp_path_factory.mktemp("late_wrong")
    write_frame(late_log(ur5, LAGS), folder / "log.csv")
    model = read_toml(SCENARIOS.parent / "models" / "ur5_friction.toml")
    for joint in model["joints"].values():
        joint["coulomb_velocity"] = 0.1
    model["model"]["name"] = "ur5_too_smooth"
    (folder / "model.toml").write_text(tomli_w.dumps(model))
    return folder


GATE = '[[gates]]\nmetric = "refinement.validation.torque_rel_error_change"\nlimit = 0\n'
SCENARIO = ('[scenario]\nmodel = "model.toml"\n[data]\nfile = "log.csv"\n'
            'columns = { t = "t", q = "q{j}", qd = "qd{j}", tau = "tau{j}" }\n'
            'units = { q = "rad", qd = "rad/s", tau = "N m" }\nvalidation = { from = 0.7 }\n')


@pytest.mark.slow  # two passes of rollouts: about 30 s
def test_refinement_finds_the_late_channels_the_linear_fit_cannot(late_log_wrong_law):
    """The linear fit reads the torques as logged, and its friction law is chosen from them (the
    model's own, 0.1 rad/s, is five times too smooth); the refinement adjusts the smoothing
    velocities and the channels' delays from the motion. On the validation span it never reads, the
    refined model's torque error must be at most a quarter of the consistent fit's (measured 1.12 % ->
    0.143 %) and its drift in simulation at most a quarter at every horizon (measured 9 to 12 times
    less); every delay within 2 ms of the true lag (measured: within 1.2 ms; the lags are 1 to 10 ms)
    and every smoothing velocity within 30 % of the robot's 0.02 rad/s (measured: within 14 %). The
    log is noise-free: what is left is the optimiser's, stopped at its evaluations (10 per pass)."""
    folder = late_log_wrong_law
    (folder / "s.toml").write_text(SCENARIO + '[refinement]\nadjust = ["coulomb_velocity", "delay"]\n' + GATE)
    assert main(["run", str(folder / "s.toml"), "--out", str(folder / "out"), "--quiet"]) == 0
    rf = json.loads((folder / "out" / "results.json").read_text())["refinement"]
    assert rf["accepted"] and rf["kept"] != "consistent"
    v = rf["validation"]
    assert v["torque_rel_error"]["refined"] <= 0.25 * v["torque_rel_error"]["consistent"], v["torque_rel_error"]
    pm = v["prediction"]["models"]
    for h in ("h20ms", "h50ms", "h100ms", "h200ms"):
        assert pm["refined"][h]["diverged"] == 0
        assert pm["refined"][h]["q_rms"] <= 0.25 * pm["consistent"][h]["q_rms"], h
    joints = load_scenario(folder / "s.toml").robot.joint_names
    found = np.array([rf["parameters"][f"{j}.delay"]["refined"] for j in joints])
    assert np.max(np.abs(found - LAGS)) <= 2e-3, found
    v_c = np.array([rf["parameters"][f"{j}.coulomb_velocity"]["refined"] for j in joints])
    assert np.max(np.abs(v_c / 0.02 - 1)) <= 0.3, v_c
    assert rf["rollouts"] == sum(p["rollouts"] for p in rf["passes"]) > 0 and rf["seconds"] > 0


@pytest.mark.parametrize(("table", "key", "words"), [
    ("adjust = []", "adjust", "non-empty"),
    ('adjust = ["armature"]', "adjust", "armature"),
    ("sample = 0.5", "sample", "longer than the horizon"),
    ("horizon = 5.0", "horizon", "at most 2 s"),
    ("passes = 0", "passes", ""),
    ("speed = 1", "speed", ""),
])
def test_a_bad_refinement_table_is_refused_in_one_line_naming_the_key(tmp_path, capsys, table, key, words):
    pd.DataFrame({"t": [0.0, 0.01], **{f"{c}{k}": [0.0, 0.0] for c in ("q", "qd", "tau") for k in range(1, 7)}}
                 ).to_csv(tmp_path / "log.csv", index=False)
    (tmp_path / "s.toml").write_text(SCENARIO.replace('"model.toml"', f'"{SCENARIOS.parent / "models" / "ur5.toml"}"')
                                     + f"[refinement]\n{table}\n" + GATE)
    assert main(["run", str(tmp_path / "s.toml"), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and key in err and words in err, err
    assert not (tmp_path / "out").exists()


def test_a_refinement_without_a_log_is_refused(tmp_path, capsys):
    import shutil

    for folder in ("scenarios", "models"):
        shutil.copytree(SCENARIOS.parent / folder, tmp_path / folder)
    path = tmp_path / "scenarios" / "ur5_friction.toml"
    path.write_text(path.read_text() + "\n[refinement]\n")
    assert main(["run", str(path), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert "refinement" in err and "[data]" in err and "\n" not in err
