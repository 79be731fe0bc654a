"""The identified model as exported (harness/model/export.py, harness/model/mjcf.py `write_mjcf`) reloads
to the identified model in every reader: the harness's own (`robot.toml`, and `robot.xml` through
`[mjcf]`), MuJoCo's compiler and Pinocchio's MJCF parser. The model: a [data] identification of a
bench log of the UR5 with drives (2 s at 200 Hz). Tolerances: 1e-9 relative, the issue's bar for
reload parity; every figure measured is round-off (1e-15 to 1e-13), since every number is written
at full precision. MJCF has no smooth Coulomb law and no offset: the torques are compared without
them, and what they change is stated in the file and in README.md."""

from __future__ import annotations

import dataclasses
import json

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from harness.api import load_scenario
from harness.cli import main
from harness.engines.pinocchio import build_model, rnea
from harness.model.inertia import kind_scale
from harness.model.load import load_spec
from harness.model.states import random_states
from tests.conftest import SCENARIOS, bench_log, log_scenario, mujoco_inverse

RELOAD_TOL = 1e-9


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    folder = tmp_path_factory.mktemp("export")
    sc = load_scenario(SCENARIOS / "ur5_friction.toml")
    bench_log(sc, folder, 2.0, 400)
    log_scenario(folder, SCENARIOS.parent / "models" / "ur5_friction.toml",
                 '[[gates]]\nmetric = "log_identification.validation_rel_error.consistent"\nlimit = 1e-2\n'
                 "[friction_law]\nchoose = false\n")  # the law's export is checked in test_friction_law.py
    assert main(["run", str(folder / "s.toml"), "--out", str(folder / "out"), "--quiet"]) == 0
    identified = folder / "out" / "identified"
    (folder / "mjcf.toml").write_text('[mjcf]\nfile = "out/identified/robot.xml"\n')  # beside the run's folder
    spec = load_spec(identified / "robot.toml")
    n = len(spec.joints)
    lo, hi = np.array([spec.limits[j] for j in spec.joint_names]).T
    states = random_states(np.maximum(lo, -np.pi), np.minimum(hi, np.pi), np.full(n, 2.0), np.full(n, 5.0), 100, 1)
    results = json.loads((folder / "out" / "results.json").read_text())
    return identified, spec, load_spec(folder / "mjcf.toml"), states, results


def _without_coulomb(spec):
    """The model with no Coulomb friction and no offset: what MJCF's other terms must reproduce."""
    return dataclasses.replace(spec, joints=tuple(
        dataclasses.replace(j, friction=dataclasses.replace(j.friction, coulomb=0.0, offset=0.0)) for j in spec.joints))


def _torques(spec, states, gravity_W):
    return rnea(build_model(_without_coulomb(spec), gravity_W), *states).tau


def test_the_mjcf_read_by_the_harness_gives_the_identified_parameters(exported):
    _, spec, from_mjcf, _, _ = exported
    assert from_mjcf.joint_names == spec.joint_names
    np.testing.assert_array_equal(from_mjcf.gravity_W, [0.0, 0.0, -9.80665])  # the file's, not MuJoCo's default
    ours, theirs = (build_model(s, np.zeros(3)) for s in (spec, from_mjcf))
    for k in range(len(spec.joints)):
        a = ours.model.inertias[ours.joint_ids[k]].toDynamicParameters()
        b = theirs.model.inertias[theirs.joint_ids[k]].toDynamicParameters()
        assert np.max(np.abs(a - b) / kind_scale(a)) <= RELOAD_TOL, spec.joint_names[k]
    for j, i in zip(spec.joints, from_mjcf.joints, strict=True):
        assert (i.friction.armature, i.friction.viscous, i.friction.coulomb) == pytest.approx(
            (j.friction.armature, j.friction.viscous, j.friction.coulomb), rel=RELOAD_TOL)
        assert spec.limits[j.name] == from_mjcf.limits[j.name]


def test_the_mjcf_read_by_the_harness_gives_the_identified_torques(exported):
    _, spec, from_mjcf, states, _ = exported
    g = np.array([0.0, 0.0, -9.80665])
    a, b = _torques(spec, states, g), _torques(from_mjcf, states, g)
    assert np.max(np.abs(a - b)) <= RELOAD_TOL * np.max(np.abs(a))


def test_mujoco_simulates_the_identified_model_from_the_mjcf(exported):
    """MuJoCo's inverse dynamics of robot.xml (its dry friction switched off) against the identified
    model's torques; MuJoCo's hinge coordinates are the harness's."""
    identified, spec, _, states, _ = exported
    model = mujoco.MjModel.from_xml_path(str(identified / "robot.xml"))
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_FRICTIONLOSS
    cols = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, j) for j in spec.joint_names]
    tau = mujoco_inverse(model, *states, cols)
    ref = _torques(spec, states, model.opt.gravity)
    assert np.max(np.abs(tau - ref)) <= RELOAD_TOL * np.max(np.abs(ref))
    effort = {j: v["effort"] for j, v in spec.drive_limits.items() if "effort" in v}
    for j, e in effort.items():
        a = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, j)
        assert list(model.actuator_forcerange[a]) == [-e, e]


def test_pinocchios_mjcf_parser_reads_the_identified_model(exported):
    """Pinocchio's own parser: its RNEA (with the armature it reads) plus the damping it reads, at the
    file's gravity (the parser keeps its default)."""
    identified, spec, _, states, _ = exported
    model = pin.buildModelFromMJCF(str(identified / "robot.xml"))
    model.gravity.linear = np.array([0.0, 0.0, -9.80665])
    data = model.createData()
    idx = [model.joints[model.getJointId(j)].idx_v for j in spec.joint_names]
    q, qd, qdd = states
    tau = np.array([pin.rnea(model, data, q[k], qd[k], qdd[k]) for k in range(len(q))])[:, idx]
    tau += np.asarray(model.damping)[idx] * qd
    ref = _torques(spec, states, np.array([0.0, 0.0, -9.80665]))
    assert np.max(np.abs(tau - ref)) <= RELOAD_TOL * np.max(np.abs(ref))


def test_the_export_says_what_each_file_holds_and_what_the_mjcf_changes(exported):
    identified, spec, _, _, results = exported
    readme = (identified / "README.md").read_text()
    for name in ("robot.urdf", "robot.xml", "joints.toml", "robot.toml"):
        assert f"`{name}`" in readme
    assert "Read alone it loses" in readme
    stated = results["log_identification"]["export_mjcf_friction"]
    for j in spec.joint_names:
        assert f"`{j}`: RMS {stated[j]['rms']:.3g}, largest {stated[j]['largest']:.3g}" in readme
    assert "frictionloss" in (identified / "robot.xml").read_text().split("<mujoco")[0]  # the heading comment


def test_identified_model_reads_a_runs_folder_and_refuses_one_that_mixes_two_runs(exported, tmp_path):
    """harness.identified_model(DIR): the model the run exported, from the run's folder or its identified/
    folder; a folder holding another run's file (TX40's drives.toml left beside a UR5's model), a file
    changed since the run wrote it, or a results.json of another run beside it, is refused naming the file
    (InputError), never read as a model."""
    import shutil

    from harness.api import identified_model
    from harness.base.tomlio import InputError

    identified, spec, *_ = exported
    assert identified_model(identified.parent).joint_names == spec.joint_names
    assert identified_model(identified).joint_names == spec.joint_names
    out = tmp_path / "out"
    shutil.copytree(identified.parent, out)
    (out / "identified" / "drives.toml").write_text('motors = ["m1"]\n')
    with pytest.raises(InputError, match=r"identified/drives.toml: not written by run [0-9a-f]{32} \(run of 's'\)"):
        identified_model(out)
    (out / "identified" / "drives.toml").unlink()
    model = out / "identified" / "robot.toml"
    model.write_text(model.read_text().replace("armature = ", "armature = 1", 1))
    with pytest.raises(InputError, match=r"identified/robot.toml: changed since run"):
        identified_model(out)
    shutil.copy(identified / "robot.toml", model)
    results = json.loads((out / "results.json").read_text())
    results["run"]["id"] = "0" * 32
    (out / "results.json").write_text(json.dumps(results))
    with pytest.raises(InputError, match=r"results.json: run.id: '0{32}', where identified/ is run '[0-9a-f]{32}'"):
        identified_model(out / "identified")


def test_the_model_file_states_the_gravity_the_fit_used_and_a_scenario_on_it_takes_it(exported, tmp_path):
    """robot.toml's [model] gravity is log_identification.gravity.used to the last bit (tomli-w writes every
    float exactly), as robot.xml's <option gravity> is; a scenario on robot.toml that states no gravity of its
    own simulates at it, and one that states its own keeps that."""
    identified, spec, mjcf_spec, _, results = exported
    used = np.array(results["log_identification"]["gravity"]["used"])
    assert np.array_equal(spec.gravity_W, used) and np.array_equal(mjcf_spec.gravity_W, used)
    model = (identified / "robot.toml").as_posix()
    base = {"scenario": {"model": model, "duration": 0.1, "output_steps": 10},
            "motion": {j: {"type": "locked"} for j in spec.joint_names},
            "gates": [{"metric": "recording.rows", "limit": 100}]}
    assert np.array_equal(load_scenario(base, folder=tmp_path).gravity_W, used)
    base["scenario"]["gravity"] = [0.0, 0.0, -9.0]
    assert np.array_equal(load_scenario(base, folder=tmp_path).gravity_W, [0.0, 0.0, -9.0])
