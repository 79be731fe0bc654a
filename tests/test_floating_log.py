"""A floating base's log (harness/sources/log/floating.py, harness/stages/floating_log.py): the base's pose and
twist and the feet's forces read as published, in either quaternion order and either axes, into the harness's
convention, conditioned with the joints, identified and judged.

Independent references: the bench's own recording of the standing robot (its base's pose, twist and the feet's
forces as MuJoCo gave them), from which each log is written here in another convention, and the robot that
made it (its floating-base inverse dynamics at the log's states)."""

from __future__ import annotations

import dataclasses
import json
import re

import numpy as np
import pandas as pd
import pytest

from harness.base.tomlio import InputError
from harness.cli import main
from harness.model.quaternion import to_matrix
from harness.runner.scenario import load_scenario
from harness.sources.bench import record
from harness.sources.log import load

from .conftest import ROOT, SCENARIOS, write_frame

BENCH = ROOT / "harness" / "data" / "logs" / "solo12_standing_bench"
FEET = ("FL_foot", "FR_foot", "HL_foot", "HR_foot")
FEET_BODIES = ("FL_LOWER_LEG", "FR_LOWER_LEG", "HL_LOWER_LEG", "HR_LOWER_LEG")
POINTS = {"FL_foot": (0.1946, 0.14695), "FR_foot": (0.1946, -0.14695), "HL_foot": (-0.1946, 0.14695),
          "HR_foot": (-0.1946, -0.14695)}


@pytest.fixture(scope="module")
def standing():
    """The shipped bench log's recipe for 1.5 s at 200 Hz, its front-left foot lifted from 0.5 s to 1.0 s
    (while the base leans back), recorded without noise."""
    sc = load_scenario(BENCH / "bench.toml")
    contacts = tuple(dataclasses.replace(c, lift=dataclasses.replace(c.lift, start=0.5, end=1.0))
                     if c.name == "FL_foot" else dataclasses.replace(c, lift=None) for c in sc.contacts)
    sc = dataclasses.replace(sc, duration=1.5, output_steps=300, contacts=contacts)
    return record(sc)


def _write(rec, path, order="xyzw", twist_axes="base", force_axes="world", flip=None, scale_row=None):
    """The recording as a log in the given conventions (module docstring)."""
    R = to_matrix(rec.base_pose[:, 3:])
    R_T = np.swapaxes(R, 1, 2)
    cols = {"t": rec.t}
    for k in range(len(rec.joints)):
        cols[f"q{k + 1}"], cols[f"qd{k + 1}"], cols[f"tau{k + 1}"] = rec.q[:, k], rec.qd[:, k], rec.tau[:, k]
    quat = rec.base_pose[:, 3:].copy()
    if flip is not None:
        quat[flip] *= -1.0
    if scale_row is not None:
        quat[scale_row] *= 1.01
    cols.update(zip(("px", "py", "pz"), rec.base_pose[:, :3].T, strict=True))
    cols.update(zip(("qw", "qx", "qy", "qz") if order == "wxyz" else ("qx", "qy", "qz", "qw"),
                    (quat if order == "wxyz" else quat[:, [1, 2, 3, 0]]).T, strict=True))
    twist = rec.base_twist_W if twist_axes == "world" else np.concatenate(
        [(R_T @ rec.base_twist_W[:, s, None])[..., 0] for s in (slice(0, 3), slice(3, 6))], axis=1)
    cols.update(zip(("vx", "vy", "vz", "wx", "wy", "wz"), twist.T, strict=True))
    for k, name in enumerate(rec.contacts):
        F = rec.contact_F_W[:, k] if force_axes == "world" else (R_T @ rec.contact_F_W[:, k, :, None])[..., 0]
        cols.update(zip((f"{name}_fx", f"{name}_fy", f"{name}_fz"), F.T, strict=True))
    write_frame(pd.DataFrame(cols), path)


def _scenario(tmp_path, log, order="xyzw", twist_axes="base", force_axes="world", extra_data="", extra="",
              predict=False) -> str:
    """A log scenario of the recording written by `_write`; no forward prediction unless `predict` (its own test's)."""
    contacts = "".join(f'''
[[data.contacts]]
name = "{name}"
body = "{name[:2]}_LOWER_LEG"
point = [{POINTS[name][0]}, {POINTS[name][1]}, -0.32]
force = ["{name}_fx", "{name}_fy", "{name}_fz"]
axes = "{force_axes}"
''' for name in FEET)
    quaternion = '["qw", "qx", "qy", "qz"]' if order == "wxyz" else '["qx", "qy", "qz", "qw"]'
    text = f'''
[scenario]
description = "a floating base's log"
model = "{SCENARIOS.parent / "models" / "solo12.toml"}"

[data]
file = "{log}"
columns = {{ t = "t", q = "q{{j}}", qd = "qd{{j}}", tau = "tau{{j}}" }}
units = {{ q = "rad", qd = "rad/s", tau = "N m" }}
truth = "{SCENARIOS.parent / "models" / "solo12.toml"}"
validation = {{ from = 0.7 }}
delay = "none"
{"" if predict else "prediction = { starts = 0 }"}
{extra_data}

[data.base]
position = ["px", "py", "pz"]
quaternion = {quaternion}
order = "{order}"
twist = ["vx", "vy", "vz", "wx", "wy", "wz"]
twist_axes = "{twist_axes}"
{contacts}
[floating_log]
rows = "all"
consistent = false

[[gates]]
metric = "floating_log.judged.least_squares.truth.max_rel_error"
limit = 1.0
{extra}'''
    path = tmp_path / "s.toml"
    path.write_text(text)
    return path


CONVENTIONS = [("xyzw", "base", "world"), ("wxyz", "world", "base")]


@pytest.mark.parametrize(("order", "twist_axes", "force_axes"), CONVENTIONS)
def test_a_floating_log_reads_as_the_bench_recorded_it_in_either_convention(standing, tmp_path, order, twist_axes,
                                                                           force_axes):
    """Written in either quaternion order, the twist and the feet's forces in world or base axes as declared,
    the log's training span holds the bench's pose, twist and forces at its rows to 1e-12 (of their size), and
    each foot's point where the bench's site was, to 1e-12 m; the base's acceleration is the twist's central
    difference (to 1e-3 of its largest, the difference's error at 200 Hz)."""
    rec = standing
    _write(rec, tmp_path / "log.csv", order, twist_axes, force_axes)
    sc = load_scenario(_scenario(tmp_path, tmp_path / "log.csv", order, twist_axes, force_axes))
    span = load(sc.data, sc.robot).training
    rows = np.searchsorted(rec.t, span.t - 1e-9)
    assert np.max(np.abs(rec.t[rows] - span.t)) < 1e-9
    assert np.max(np.abs(span.base_pose - rec.base_pose[rows])) <= 1e-12
    assert np.max(np.abs(span.base_twist_W - rec.base_twist_W[rows])) <= 1e-12 * np.max(np.abs(rec.base_twist_W))
    assert np.max(np.abs(span.contact_F_W - rec.contact_F_W[rows])) <= 1e-12 * np.max(np.abs(rec.contact_F_W))
    assert np.max(np.abs(span.contact_x_W - rec.contact_x_W[rows])) <= 1e-12
    assert np.max(np.abs(span.base_rate_W - rec.base_rate_W[rows])) <= 1e-3 * np.max(np.abs(rec.base_rate_W))


def test_a_quaternion_whose_sign_flips_reads_as_one_orientation(standing, tmp_path):
    """q and -q are one orientation: rows 40-80 written with the other sign read as the log without the flip,
    bit for bit (had the flip been read, the filter and the differences would see a full turn there)."""
    rec = standing
    _write(rec, tmp_path / "a.csv")
    _write(rec, tmp_path / "b.csv", flip=slice(40, 80))
    spans = []
    for name in ("a", "b"):
        (tmp_path / name).mkdir()
        sc = load_scenario(_scenario(tmp_path / name, tmp_path / f"{name}.csv"))
        spans.append(load(sc.data, sc.robot).training)
    assert np.array_equal(spans[0].base_pose, spans[1].base_pose)
    assert np.array_equal(spans[0].base_rate_W, spans[1].base_rate_W)


def test_a_quaternion_that_is_not_unit_is_refused_naming_its_column_and_row(standing, tmp_path):
    _write(standing, tmp_path / "log.csv", scale_row=10)
    sc = load_scenario(_scenario(tmp_path, tmp_path / "log.csv"))
    with pytest.raises(InputError) as err:
        load(sc.data, sc.robot)
    assert err.value.key == "qx" and "row 12" in str(err.value) and "norm is 1.01" in str(err.value)


def _run(path, out) -> tuple[int, dict]:
    code = main(["run", str(path), "--out", str(out), "--quiet"])
    return code, json.loads((out / "results.json").read_text())


@pytest.mark.slow  # a floating log identified whole (1.7 s)
def test_an_exact_floating_log_identifies_the_robot_that_made_it(standing, tmp_path):
    """A noise-free log: the start check finds nothing; the model as given (the truth) is the log within 1e-3 of
    each row's size (2e-4 measured: the accelerations' central differences at 200 Hz); the least squares from
    the feet's forces and the joints' torques, 94 base parameters from 210 training rows of a 1.5 s log, predicts
    the validation span's base wrench and motor torques within 3e-2 of the truth's (6.0e-4 measured, each row
    weighted by its residual; 1.0e-2 weighted alike, where the short log's fit amplifies the differences' error
    fifty-fold; a force in the wrong axes or sign is off by its size).
    data.csv holds the base's and the contacts' columns beside the joints'. Forward-simulated from 20 states of the
    validation span under the log's torques and feet's forces (harness/engines/free_predict.py), the truth stays
    within 1e-4 m and 1e-3 rad of the log's base for 0.1 s (8e-6 m and 1.6e-4 rad measured: the 200 Hz
    channels' interpolation and the bench's soft feet); the same run with the feet's forces left out falls away,
    over 100 times as far."""
    from harness.engines.free_predict import predict
    from harness.model.floating import BaseMotion

    _write(standing, tmp_path / "log.csv")
    code, results = _run(_scenario(tmp_path, tmp_path / "log.csv", predict=True), tmp_path / "out")
    f = results["floating_log"]
    assert code == 0 and f["start"]["findings"] == 0
    assert f["judged"]["model_as_given"]["measured"]["max_rel_error"] <= 1e-3
    assert f["judged"]["least_squares"]["truth"]["max_rel_error"] <= 3e-2
    held = f["prediction"]["models"]["truth"]["h100ms"]
    assert f["prediction"]["starts"] == 20 and held["diverged"] == 0
    assert held["base_position_max_m"] <= 1e-4 and held["base_angle_max_rad"] <= 1e-3
    sc = load_scenario(BENCH / "bench.toml")
    base = BaseMotion.from_rows(standing.base_pose, standing.base_twist_W, standing.base_rate_W)
    starts = np.arange(0, 200, 40)
    falls = [predict(sc.robot, sc.gravity_W, standing.t, base, standing.q, standing.qd, standing.tau, FEET_BODIES,
                     F, standing.contact_M_W, standing.contact_x_W, starts, (0.1,))[0]
             for F in (standing.contact_F_W, np.zeros_like(standing.contact_F_W))]
    assert np.max(falls[1]) >= 100 * np.max(falls[0])
    header = (tmp_path / "out" / "data.csv").read_text().split("\n", 1)[0].split(",")  # both spans, as conditioned
    assert {"base[qw]", "contact[FL_foot][Fz]"} <= set(header)


def test_feet_s_forces_in_other_axes_than_declared_fail_the_start_check(standing, tmp_path):
    """The feet's forces written in base axes but declared in world axes: the model as given and the log's base
    rows disagree beyond the start check's limit, said, and the start gate fails (exit 1)."""
    _write(standing, tmp_path / "log.csv", force_axes="base")
    code, results = _run(_scenario(tmp_path, tmp_path / "log.csv", force_axes="world"), tmp_path / "out")
    assert code == 1
    start = results["floating_log"]["start"]
    assert start["findings"] >= 1 and "other axes than declared" in start["said"][0]


def test_a_joint_is_judged_on_its_motor_s_torque_and_the_base_on_its_force_and_moment():
    """The judging's scales: the base's force rows by the largest force, its moment rows by the largest moment
    (norms), a joint by its motor's largest |torque|, not by its whole row (which the foot's J^T F nearly
    cancels in a stance leg); a channel reading 0 throughout by the largest joint's."""
    from harness.stages.floating_log import scales

    whole = np.array([[3.0, 4.0, 0.0, 0.0, 0.0, 1.0, 0.01, 0.0], [0.0, 0.0, 1.0, 2.0, 0.0, 0.0, -0.02, 0.0]])
    tau = np.array([[0.5, 0.0], [-0.7, 0.0]])  # the second channel dead: judged on the largest joint's scale
    assert np.array_equal(scales(whole, tau), [5.0, 5.0, 5.0, 2.0, 2.0, 2.0, 0.7, 0.7])


def test_the_judging_s_errors_are_every_row_s_and_the_base_s_and_the_motors_apart():
    """`_errors`: each row's error over its scale, the largest and where, the RMS of all, and of the base's six
    rows and the joints' apart, written out here for two samples of six base rows and two joints."""
    from harness.stages.floating_log import _errors

    reference = np.zeros((2, 8))
    predicted = np.array([[1.0, 0, 0, 0, 0, 0, 0.3, 0], [0, 0, 0, 2.0, 0, 0, 0, -0.4]])
    scale = np.array([2.0] * 6 + [1.0, 2.0])
    got = _errors(predicted, reference, scale, [f"r{k}" for k in range(8)])
    assert got["max_rel_error"] == 1.0 and got["max_rel_row"] == "r3"
    assert got["rms_rel_error"] == pytest.approx(np.sqrt((0.5**2 + 1.0**2 + 0.3**2 + 0.2**2) / 16), rel=1e-15)
    assert got["rms_rel_error_base"] == pytest.approx(np.sqrt((0.5**2 + 1.0**2) / 12), rel=1e-15)
    assert got["rms_rel_error_joints"] == pytest.approx(np.sqrt((0.3**2 + 0.2**2) / 4), rel=1e-15)


CONSTANT = np.array([0.025, -0.025, 0.025] * 4)  # N m/A at the motor, signed (a motor wired the other way)
GEAR = np.array([9.0, 9.0, -9.0] * 4)  # signed (a reversing gear)


BAD = [
    ("data.base.order", lambda s: s.replace('order = "xyzw"', 'order = "zyxw"'), "is not one of"),
    ("data.base.position", lambda s: s.replace('position = ["px", "py", "pz"]', 'position = ["px", "py"]'),
     "3 expected"),
    ("data.contacts[1].body", lambda s: s.replace('body = "FR_LOWER_LEG"', 'body = "FR_FOOT"'), "no moving body"),
    ("data.identify_torque_constants", lambda s: s.replace('tau = "N m" }', f'tau = "current" }}\ntorque_constant = '
                                                           f'{CONSTANT.tolist()}\ngear_ratio = {GEAR.tolist()}\n'
                                                           'identify_torque_constants = true').replace(
        'rows = "all"', 'rows = "base"'), 'rows = "all"'),
    ("data.contacts[0].rpy", lambda s: s.replace('axes = "world"', 'axes = "world"\nrpy = [0.1, 0.0, 0.0]', 1),
     'for axes = "body"'),
    ("data.contacts[0].axes", lambda s: s.replace('axes = "world"', 'axes = "sensor"', 1), "is not one of"),
    ("data.base.qw", None, "column missing"),
]


@pytest.mark.parametrize(("key", "edit", "said"), BAD, ids=[b[0] for b in BAD])
def test_a_floating_log_it_cannot_read_is_refused_in_one_line(standing, tmp_path, key, edit, said):
    _write(standing, tmp_path / "log.csv")
    path = _scenario(tmp_path, tmp_path / "log.csv")
    if edit is None:  # a column the log does not have
        pd.read_csv(tmp_path / "log.csv").drop(columns=["qw"]).to_csv(tmp_path / "log.csv", index=False)
    else:
        path.write_text(edit(path.read_text()))
    with pytest.raises(InputError) as err:
        load_scenario(path)
    assert (err.value.key == key or (key == "data.base.qw" and err.value.key == "qw")), str(err.value)
    assert said in str(err.value) and "\n" not in str(err.value)


def test_a_fixed_base_robot_s_log_has_no_base_to_read(tmp_path):
    text = (SCENARIOS / "ur5_bench_log.toml").read_text()
    text = text.replace('"../', f'"{SCENARIOS.parent}/')
    path = tmp_path / "s.toml"
    path.write_text(text + '\n[data.base]\nposition = ["a", "b", "c"]\n')
    with pytest.raises(InputError) as err:
        load_scenario(path)
    assert err.value.key == "data.base" and "no floating base" in str(err.value)


SHIPPED_TOL = 1e-8  # of a column's largest value: a processor's last bits carried through 10 s of contacts


@pytest.mark.slow  # the benches' 10 s: about 25 s for the quadruped, 55 s for the humanoid
@pytest.mark.parametrize("bench", [BENCH, BENCH.parent / "g1_standing_bench"], ids=["solo12", "g1"])
def test_the_shipped_log_is_its_bench_measured(tmp_path, bench):
    """harness/data/logs/solo12_standing_bench/log.csv (and g1_standing_bench's, the humanoid on its soles) is
    its bench.toml's recording, measured and written as the README says: remade here, the same columns and
    rows, every column within SHIPPED_TOL of its largest value. Not to the last bit: MuJoCo's arithmetic
    differs in its last bits between processors (its vector paths), and 10 s of contacts carry that to
    4.5e-10 of a sole's force (the shipped files made on an AMD EPYC, remade on an Intel Xeon); a change of
    the bench's model, motion or noise moves them by many orders more."""
    from harness.sources.bench import write_log
    from harness.sources.measurement import measure

    sc = load_scenario(bench / "bench.toml")
    write_log(measure(record(sc), sc.measurement), sc.robot.joint_names, tmp_path / "log.csv")
    made, shipped = (pd.read_csv(path) for path in (tmp_path / "log.csv", bench / "log.csv"))
    assert list(made.columns) == list(shipped.columns) and len(made) == len(shipped)
    scale = shipped.abs().max().replace(0.0, 1.0)
    worst = ((made - shipped).abs().max() / scale).sort_values()
    assert worst.iloc[-1] <= SHIPPED_TOL, worst.tail(3)


FRICTION = """[model]
name = "solo12_friction"
description = "Solo12 with drives on its knees"

[urdf]
robot = "solo12"
floating = true
""" + "".join(f"""
[joints.{leg}_KFE]
armature = 0.002
viscous = 0.01
coulomb = 0.03
offset = 0.01
coulomb_velocity = 0.05
""" for leg in ("FL", "FR", "HL", "HR"))


@pytest.mark.slow  # a floating log with drives identified whole (2.4 s)
def test_a_floating_log_of_a_robot_with_drives_is_judged_with_their_laws(tmp_path):
    """Solo12 with rotor inertia, viscous and Coulomb friction and an offset on its knees, standing on the bench
    (1 s): its exact log's model as given is the log within 1e-3 (3.0e-4 measured: its drives' laws are in its
    prediction; without them the knees are off by the laws' size), and the fit of the joints' rows with the
    drives' columns predicts the span it never saw within 3e-2 of the truth (1.7e-2 measured, 141 training rows
    for 94 base parameters and 16 drive terms)."""
    (tmp_path / "robot.toml").write_text(FRICTION)
    text = (BENCH / "bench.toml").read_text().replace('"../../models/solo12.toml"', f'"{tmp_path / "robot.toml"}"')
    text = text.replace('gate_sets = ["../../scenarios/', f'gate_sets = ["{SCENARIOS}/')
    (tmp_path / "bench.toml").write_text(text)
    sc = load_scenario(tmp_path / "bench.toml")
    contacts = tuple(dataclasses.replace(c, lift=None) for c in sc.contacts)
    rec = record(dataclasses.replace(sc, duration=1.0, output_steps=200, contacts=contacts))
    _write(rec, tmp_path / "log.csv")
    path = _scenario(tmp_path, tmp_path / "log.csv")
    path.write_text(path.read_text().replace(str(SCENARIOS.parent / "models" / "solo12.toml"),
                                             str(tmp_path / "robot.toml")))
    code, results = _run(path, tmp_path / "out")
    f = results["floating_log"]
    assert code == 0 and f["friction"] is True
    assert f["judged"]["model_as_given"]["measured"]["max_rel_error"] <= 1e-3
    assert f["judged"]["least_squares"]["truth"]["max_rel_error"] <= 3e-2


def _as_published(log: pd.DataFrame, folder, shape: str) -> tuple[str, str]:
    """The log written as a lab's tools publish it, and the [data] lines that read it: motor currents with
    signed constants and gears; three files, each with its own time column (the efforts' stamped 0.1 ms
    late, nearest within half a step); or the torques in a file of their own."""
    joints = [f"tau{k + 1}" for k in range(12)]
    base = [c for c in log.columns if not re.fullmatch(r"t|(q|qd|tau)\d+", c)]  # the base's and the feet's
    if shape == "currents":
        currents = log.copy()
        currents[joints] = log[joints].to_numpy() / (CONSTANT * GEAR)
        write_frame(currents, folder / "log.csv")
        return ('units = { q = "rad", qd = "rad/s", tau = "N m" }',
                f'units = {{ q = "rad", qd = "rad/s", tau = "current" }}\ntorque_constant = {CONSTANT.tolist()}\n'
                f'gear_ratio = {GEAR.tolist()}')
    positions = ["t", *(f"q{k + 1}" for k in range(12)), *(c for c in base if c[0] in "pq")]
    velocities = ["t", *(f"qd{k + 1}" for k in range(12)), *(c for c in base if c[0] in "vw")]
    efforts = ["t", *joints, *(c for c in base if c.endswith(("_fx", "_fy", "_fz")))]
    assert sorted({*positions, *velocities, *efforts}) == sorted(log.columns)
    if shape == "three files":
        late = log.assign(t=log["t"] + 1e-4)
        for name, frame, cols in (("pose", log, positions), ("twist", log, velocities), ("effort", late, efforts)):
            write_frame(frame[cols], folder / f"{name}.csv")
        return 'file = "log.csv"', 'file = ["pose.csv", "twist.csv", "effort.csv"]'
    write_frame(log[[c for c in log.columns if c not in joints]], folder / "states.csv")
    write_frame(log[["t", *joints]], folder / "torques.csv")
    return 'file = "log.csv"', 'file = "states.csv"\ntorque_file = "torques.csv"'


@pytest.mark.parametrize("shape", ["currents", "three files", "torque file"])
def test_a_floating_log_s_joint_channels_read_as_an_arm_s(standing, tmp_path, shape):
    """The log's joint channels in the shapes an arm's log may take (`_as_published`): the conditioned training
    span is the plain log's, every channel (joints, base, contacts) to the bit where only the files differ and to
    1e-15 of the torques' size through the currents' constants (tau = i k_t r, the division and product's
    round-off); a run of the currents' log identifies what the plain log's does, to 1e-9."""
    _write(standing, tmp_path / "log.csv")
    plain_path = _scenario(tmp_path, tmp_path / "log.csv")
    plain = load_scenario(plain_path)
    (tmp_path / "p").mkdir()
    old, new = _as_published(pd.read_csv(tmp_path / "log.csv"), tmp_path / "p", shape)
    path = _scenario(tmp_path / "p", "log.csv")  # the file beside the scenario
    assert old in path.read_text()
    path.write_text(path.read_text().replace(old, new))
    published = load_scenario(path)
    a, b = (load(sc.data, sc.robot).training for sc in (plain, published))
    for field in ("t", "q", "qd", "qdd", "base_pose", "base_twist_W", "base_rate_W", "contact_F_W", "contact_x_W"):
        assert np.array_equal(getattr(a, field), getattr(b, field)), field
    if shape == "three files":  # said
        assert "effort.csv joined to pose.csv on 't': 301 of 301 rows to the nearest" in b.meta["warnings"][0]
    tolerance = 1e-15 * np.max(np.abs(a.tau)) if shape == "currents" else 0.0
    assert np.max(np.abs(a.tau - b.tau)) <= tolerance
    if shape == "currents":
        (_, plain_results), (code, results) = (_run(p, p.parent / "out") for p in (plain_path, path))
        assert code == 0
        fits = [r["floating_log"]["judged"]["least_squares"]["truth"]["max_rel_error"]
                for r in (plain_results, results)]
        assert fits[1] == pytest.approx(fits[0], rel=1e-9)


DRIVES = """[model]
name = "solo12_drives"
description = "Solo12 with drives: gear 9, the front-left knee's motor also turning with its hip"

[urdf]
robot = "solo12"
floating = true

[drives]
gear_ratio = [9, 9, 9, 9, 9, 9, 9, 9, -9, 9, 9, 9]
coupling = [{ motor = "motor_9", joint = "FL_HFE", ratio = 9 }]
joint_offset = [0.0, 0.0, 0.0, 0.0, 0.3, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
"""


def test_a_floating_robot_s_motor_side_log_reads_as_its_joint_side_log(standing, tmp_path):
    """A legged robot with drives (gear ratios of either sign, a knee's motor turning with its hip, a joint's
    offset) logged at its motors (q_m = N q + o, q'_m = N q', tau_m = N^-T tau, `side = "motor"`), its base's and
    feet's columns as they are: the conditioned training span is the joint-side log's, every joint channel to
    1e-12 of its size (N^-1 and N^T's round-off), the feet's points (the kinematics at those joint positions) to
    1e-12 m, the base's and the feet's forces to the bit."""
    from harness.model.load import load_spec

    (tmp_path / "drives.toml").write_text(DRIVES)
    t = load_spec(tmp_path / "drives.toml").transmission
    _write(standing, tmp_path / "log.csv")
    joints = pd.read_csv(tmp_path / "log.csv")
    motors = joints.copy()
    cols = {kind: [f"{kind}{k + 1}" for k in range(12)] for kind in ("q", "qd", "tau")}
    for kind, to_motor in (("q", t.motor_positions), ("qd", t.motor_rates), ("tau", t.motor_torques)):
        motors[cols[kind]] = to_motor(joints[cols[kind]].to_numpy())
    write_frame(motors, tmp_path / "motors.csv")
    read = []
    for name, side in (("log.csv", ""), ("motors.csv", 'side = "motor"')):
        folder = tmp_path / name[:-4]
        folder.mkdir()
        path = _scenario(folder, tmp_path / name, extra_data=side)
        path.write_text(path.read_text().replace(str(SCENARIOS.parent / "models" / "solo12.toml"),
                                                 str(tmp_path / "drives.toml")))
        sc = load_scenario(path)
        read.append(load(sc.data, sc.robot).training)
    a, b = read
    assert not np.allclose(motors[cols["q"]].to_numpy(), joints[cols["q"]].to_numpy())  # the log is the motors'
    for field in ("q", "qd", "qdd", "tau", "contact_x_W"):
        x, y = getattr(a, field), getattr(b, field)
        assert np.max(np.abs(x - y)) <= 1e-12 * np.max(np.abs(x)), field
    for field in ("t", "base_pose", "base_twist_W", "base_rate_W", "contact_F_W"):
        assert np.array_equal(getattr(a, field), getattr(b, field)), field


def test_the_feet_s_forces_alone_are_judged_on_the_motors_torques_too(standing, tmp_path):
    """`rows = "base"`: the least squares reads the feet's forces alone (no joint torque); its base parameters
    hold on the joints' rows too (tests/test_floating.py), so its verdict judges every row, the motors' torques
    included. On the exact 1.5 s log (210 training rows) the base rows see the legs' parameters too weakly for
    the accelerations' differences (2e-4): the motors' torques come out far off (over 100 % of their largest at
    worst, against 1e-2 with the joints' torques read), and the verdict says so (its worst row a joint's, the
    gate of 100 % failed, exit 1) rather than judging the base rows alone."""
    _write(standing, tmp_path / "log.csv")
    path = _scenario(tmp_path, tmp_path / "log.csv")
    path.write_text(path.read_text().replace('rows = "all"', 'rows = "base"'))
    code, results = _run(path, tmp_path / "out")
    f = results["floating_log"]
    least_squares = f["judged"]["least_squares"]["truth"]
    assert code == 1 and f["rows"] == "base" and f["base_parameters"] == 94
    assert least_squares["max_rel_row"] in results["data"]["joints"] and least_squares["max_rel_error"] > 1.0


SENSOR_RPY = (0.3, -0.2, 0.5)


def _sensor_axes(rec, body: str, rpy) -> np.ndarray:
    """(N, 3, 3) a force sensor's axes in the world at the recording's rows, fixed in `body` with the axes
    `rpy` (a URDF origin's) at q = 0 where the file draws the robot: Pinocchio's placement of the body's joint
    frame at each state, less its placement at that reference (the robot's file pose), times the sensor's."""
    import pinocchio as pin

    from harness.engines.pinocchio import build_model
    from harness.model.urdf import rpy_matrix

    sc = load_scenario(BENCH / "bench.toml")
    pm = build_model(sc.robot, np.zeros(3), floating=True)
    joint = pm.model.getJointId(sc.robot.inner_joint(body).name)
    data = pm.model.createData()
    fb = sc.robot.floating

    def placed(p, quat_wxyz, q):
        qq = np.zeros(pm.model.nq)
        qq[:3], qq[3:7] = p, np.r_[quat_wxyz[1:], quat_wxyz[0]]
        qq[pm.q_index] = q
        pin.forwardKinematics(pm.model, data, qq)
        return data.oMi[joint].rotation.copy()

    reference = placed(fb.p_WF0, pin.Quaternion(fb.R_WF0).coeffs()[[3, 0, 1, 2]], np.zeros(len(rec.joints)))
    return np.stack([placed(rec.base_pose[i, :3], rec.base_pose[i, 3:], rec.q[i]) @ reference.T @ rpy_matrix(rpy)
                     for i in range(len(rec.t))])


def test_a_foot_s_force_in_its_sensor_s_axes_reads_as_the_bench_recorded_it(standing, tmp_path):
    """Two feet's forces written in a force sensor's axes on their lower legs (`axes = "body"`; one sensor
    turned by `rpy`, the other with the default, the world's axes at q = 0), turned by Pinocchio's placement
    of the leg at each row (`_sensor_axes`): read back, every foot's force is the bench's in world axes to 1e-12
    of its size."""
    rec = standing
    _write(rec, tmp_path / "log.csv")
    log = pd.read_csv(tmp_path / "log.csv")
    for name, rpy in (("FL_foot", SENSOR_RPY), ("FR_foot", (0.0, 0.0, 0.0))):
        k = rec.contacts.index(name)
        R = _sensor_axes(rec, f"{name[:2]}_LOWER_LEG", rpy)
        F_S = (np.swapaxes(R, 1, 2) @ rec.contact_F_W[:, k, :, None])[..., 0]
        log[[f"{name}_fx", f"{name}_fy", f"{name}_fz"]] = F_S
    write_frame(log, tmp_path / "log.csv")
    path = _scenario(tmp_path, tmp_path / "log.csv")
    text = path.read_text()
    for name, extra in (("FL_foot", f'axes = "body"\nrpy = {list(SENSOR_RPY)}'), ("FR_foot", 'axes = "body"')):
        block = text.index(f'name = "{name}"')
        text = text[:block] + text[block:].replace('axes = "world"', extra, 1)
    path.write_text(text)
    sc = load_scenario(path)
    span = load(sc.data, sc.robot).training
    rows = np.searchsorted(rec.t, span.t - 1e-9)
    assert np.max(np.abs(span.contact_F_W - rec.contact_F_W[rows])) <= 1e-12 * np.max(np.abs(rec.contact_F_W))


LAG = 0.01  # s: two samples of the 200 Hz log


@pytest.mark.parametrize("mode", ["estimate", "correct"])
def test_torque_channels_that_lag_the_encoders_are_found_and_corrected_as_an_arm_s(standing, tmp_path, mode):
    """Every joint's torque written LAG late (two samples: tau_logged(t) = tau(t - LAG)), the feet's forces on
    the encoders' clock: each channel's delay is found at LAG within 1.5e-3 s (the motor's torque read d later
    plus the contacts' J^T F, fitted by the joint's rows of the floating regressor, on the unfiltered log's grid
    of whole 5 ms samples, refined between them by a parabola: 9.8 to 11.0 ms measured). Corrected, the least
    squares predicts the span it never saw within 5e-2 of the truth (1.6e-2 measured; 6.0e-4 for the log on
    time: the delays read by linear interpolation between samples 5 ms apart), and the span judged is corrected
    as the training span was; estimated and left in, the lagging channels leave it over 10 % off (26 % measured,
    their rows weighted by their residual at 1e-8 of the finest row's: without the weights, 124 %)."""
    _write(standing, tmp_path / "log.csv")
    log = pd.read_csv(tmp_path / "log.csv")
    joints = [f"tau{k + 1}" for k in range(12)]
    rows = round(LAG / 0.005)
    log[joints] = np.concatenate([np.repeat(log[joints].to_numpy()[:1], rows, axis=0),
                                  log[joints].to_numpy()[:-rows]])
    write_frame(log, tmp_path / "log.csv")
    path = _scenario(tmp_path, tmp_path / "log.csv")
    path.write_text(path.read_text().replace('delay = "none"', f'delay = "{mode}"'))
    code, results = _run(path, tmp_path / "out")
    f = results["floating_log"]
    per_joint = f["delays"]["per_joint"]
    assert f["delays"]["estimated"] and f["delays"]["corrected"] == (mode == "correct")
    assert all(d["found"] and abs(d["delay_s"] - LAG) <= 1.5e-3 for d in per_joint.values()), per_joint
    error = f["judged"]["least_squares"]["truth"]["max_rel_error"]
    assert (code, error <= 5e-2) == (0, True) if mode == "correct" else error > 1e-1
    # the span judged read as the fit read its own: the model as given (the truth) against the log within 5e-2
    # corrected (1.5e-2 measured: the delays between samples), 16 % with the lag left in
    given = f["judged"]["model_as_given"]["measured"]["max_rel_error"]
    assert given <= 5e-2 if mode == "correct" else given > 1e-1
    report = (tmp_path / "out" / "report.html").read_text()
    assert "delays behind the encoders</h3>" in report and ("Corrected." if mode == "correct" else "Not corrected.") \
        in report


def test_a_floating_log_is_judged_on_another_log_of_the_same_robot(standing, tmp_path):
    """`validation = { file = ... }`: the recording's first 1.05 s as the log, its last 0.45 s as another log in
    the same columns (its own times): the training span is the first file's alone, the span judged the second
    file's, base, contacts and joints read as the first's, and the least squares predicts it within 3e-2 of the
    truth (4.5e-3 measured), as it does the last 30 % of the one log
    (test_an_exact_floating_log_identifies_the_robot_that_made_it); data.csv holds the base's and the contacts'
    columns as conditioned beside the joints'."""
    _write(standing, tmp_path / "whole.csv")
    whole = pd.read_csv(tmp_path / "whole.csv")
    cut = int(np.searchsorted(whole["t"].to_numpy(), 1.05))
    write_frame(whole.iloc[:cut], tmp_path / "log.csv")
    write_frame(whole.iloc[cut:], tmp_path / "other.csv")
    path = _scenario(tmp_path, tmp_path / "log.csv")
    path.write_text(path.read_text().replace("validation = { from = 0.7 }",
                                             f'validation = {{ file = "{tmp_path / "other.csv"}" }}'))
    sc = load_scenario(path)
    split = load(sc.data, sc.robot)
    assert split.training.t[-1] < 1.05 <= split.validation.t[0] and split.validation.contact_F_W.shape[1] == 4
    code, results = _run(path, tmp_path / "out")
    f = results["floating_log"]
    assert code == 0 and f["span"] == "validation"
    assert f["judged"]["least_squares"]["truth"]["max_rel_error"] <= 3e-2
    header = (tmp_path / "out" / "data.csv").read_text().split("\n", 1)[0].split(",")  # the log as conditioned
    assert {"base[qw]", "base[wdz]", "contact[FL_foot][Fz]", "contact[HR_foot][x]"} <= set(header)


@pytest.mark.slow  # a floating log identified whole (1.2 s); the kernel is tests/test_log_unmeasured.py's
def test_joints_without_a_torque_channel_keep_their_motion_and_leave_their_rows_unread(standing, tmp_path):
    """`[data] unmeasured`: two joints' torque columns absent from the log (FL_HAA's and HR_KFE's): their motion
    stays in every row, their own rows are neither read nor judged (results.json lists them), and from the feet's
    forces and the other ten torques the least squares predicts the span it never saw within 3e-2 of the truth
    (7.6e-4 measured), as with every channel (test_an_exact_floating_log_identifies_the_robot_that_made_it).
    Read as measured zeros instead (the channels taken as logged at 0 N m), the two rows' residual is their
    whole torque: weighted by it (`estimator = "wls"`, the default) they weigh least of all rows (6e-14 and 8e-15
    of the largest, on an exact log whose other rows' residuals are the differences' alone), the fit stays within
    3e-2 (1.2e-3) and the judging finds one of them the log's worst row (its torque 79 % of the largest joint's
    where the log reads 0: a dead channel is judged on that scale); weighted alike
    (`estimator = "ols"`) they leave the fit far off (4.6)."""
    _write(standing, tmp_path / "log.csv")
    log = pd.read_csv(tmp_path / "log.csv")
    write_frame(log.drop(columns=["tau1", "tau12"]), tmp_path / "absent.csv")
    write_frame(log.assign(tau1=0.0, tau12=0.0), tmp_path / "zero.csv")
    figures = {}
    for name, log_file, extra, estimator in (("absent", "absent", 'unmeasured = ["FL_HAA", "HR_KFE"]', "wls"),
                                             ("zero", "zero", "", "wls"), ("zero alike", "zero", "", "ols")):
        (tmp_path / name).mkdir()
        path = _scenario(tmp_path / name, tmp_path / f"{log_file}.csv", extra_data=extra)
        text = path.read_text().replace("consistent = false", f'consistent = false\nestimator = "{estimator}"')
        path.write_text(text)
        code, results = _run(path, tmp_path / name / "out")
        f = results["floating_log"]
        figures[name] = f["judged"]["least_squares"]["truth"]
        if name == "absent":
            assert code == 0 and f["unmeasured"] == ["FL_HAA", "HR_KFE"]
            assert all(f["judged"][m]["measured"]["max_rel_row"] not in f["unmeasured"] for m in f["judged"])
        if name == "zero":
            weights = {r: v["weight"] for r, v in f["estimator"]["rows"].items()}
            assert sorted(weights, key=weights.get)[:2] == ["HR_KFE", "FL_HAA"], weights
            measured = f["judged"]["least_squares"]["measured"]
            assert measured["max_rel_row"] in ("FL_HAA", "HR_KFE") and measured["max_rel_error"] >= 0.5
    assert max(figures["absent"]["max_rel_error"], figures["zero"]["max_rel_error"]) <= 3e-2
    assert figures["zero alike"]["max_rel_error"] > 1.0


def test_a_sensor_s_axes_follow_its_body_on_a_base_the_file_draws_turned(tmp_path):
    """contact_axes on a robot whose base the file draws turned (tests/test_floating.py's trunk, euler 0.3 -0.2
    0.4) and whose sensor's body is two joints out (the shin): at random base orientations and joint angles,
    the sensor's axes are MuJoCo's own body orientation of the file at the state, less its orientation at the
    file's pose, times the sensor's axes there, to 1e-12 (its model of the file: an independent reading)."""
    import mujoco

    from harness.model import floating
    from harness.model.contacts import contact_axes
    from harness.model.urdf import rpy_matrix
    from harness.sources.log.floating import LogContact

    from .test_floating import DOG, _mjcf

    spec = _mjcf(tmp_path, DOG)
    model = mujoco.MjModel.from_xml_string(DOG)
    data = mujoco.MjData(model)
    shin = model.body("shin").id
    mujoco.mj_kinematics(model, data)
    at_file = data.xmat[shin].reshape(3, 3).copy()
    R_W0 = rpy_matrix(np.array(SENSOR_RPY))
    rng = np.random.default_rng(3)
    base = floating.random_base_motion(20, seed=5)
    q = rng.uniform(-1.0, 1.0, (20, len(spec.joints)))
    got = contact_axes(spec, (LogContact("sensor", "shin", np.zeros(3), ("a", "b", "c"), None, "body", R_W0),),
                       base.R_WB, q)[:, 0]
    for i in range(20):
        data.qpos[:3], data.qpos[3:7] = 0.0, base.quat_wxyz[i]
        for k, name in enumerate(spec.joint_names):
            data.qpos[model.joint(name).qposadr[0]] = q[i, k]
        mujoco.mj_kinematics(model, data)
        expected = data.xmat[shin].reshape(3, 3) @ at_file.T @ R_W0
        assert np.abs(got[i] - expected).max() <= 1e-12


def _write_bag(path, log: pd.DataFrame, kind: str, late_ns: int, missing: int | None = None) -> list[str]:
    """The log as a lab's ROS bag (rosbags' writer): sensor_msgs/JointState on /joint_states (named joints, in
    another order than the model's), nav_msgs/Odometry on /odom (the twist in the child frame, the base's; one
    message more, a second after the last joint state, and the one of row `missing` left out), and a
    geometry_msgs/WrenchStamped per foot on /<foot>/wrench, stamped `late_ns` after the joint states (another
    sensor's clock). The joints' names, in the model's order."""
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.rosbag2 import Writer as Writer2
    from rosbags.typesys import Stores, get_typestore

    from harness.runner.scenario import load_scenario as load

    names = load(BENCH / "bench.toml").robot.joint_names
    store = get_typestore(Stores.ROS1_NOETIC if kind == "ros1" else Stores.ROS2_HUMBLE)
    T = store.types
    js, odo, ws = "sensor_msgs/msg/JointState", "nav_msgs/msg/Odometry", "geometry_msgs/msg/WrenchStamped"
    vec, quat = T["geometry_msgs/msg/Vector3"], T["geometry_msgs/msg/Quaternion"]
    serialize = store.serialize_ros1 if kind == "ros1" else store.serialize_cdr

    def header(ns: int, frame: str):
        stamp = T["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9)
        return T["std_msgs/msg/Header"](**({"seq": 0} if kind == "ros1" else {}), stamp=stamp, frame_id=frame)

    order = names[::-1]  # the driver's own order
    at = [names.index(j) for j in order]
    writer = Writer1(path) if kind == "ros1" else Writer2(path, version=9)
    with writer:
        joints = writer.add_connection("/joint_states", js, typestore=store)
        base = writer.add_connection("/odom", odo, typestore=store)
        feet = {f: writer.add_connection(f"/{f}/wrench", ws, typestore=store) for f in FEET}
        rows = pd.concat([log, log.iloc[-1:].assign(t=log["t"].iloc[-1] + 1.0)]).reset_index(drop=True)
        for k, row in rows.iterrows():
            ns = round(row["t"] * 1e9)
            q, qd, tau = (np.array([row[f"{c}{i + 1}"] for i in at]) for c in ("q", "qd", "tau"))
            if k < len(log):  # the odometry's extra message last
                writer.write(joints, ns, serialize(T[js](header=header(ns, ""), name=order, position=q, velocity=qd,
                                                         effort=tau), js))
            pose = T["geometry_msgs/msg/Pose"](position=T["geometry_msgs/msg/Point"](x=row["px"], y=row["py"],
                                                                                      z=row["pz"]),
                                               orientation=quat(x=row["qx"], y=row["qy"], z=row["qz"], w=row["qw"]))
            twist = T["geometry_msgs/msg/Twist"](linear=vec(x=row["vx"], y=row["vy"], z=row["vz"]),
                                                 angular=vec(x=row["wx"], y=row["wy"], z=row["wz"]))
            msg = T[odo](header=header(ns, "world"), child_frame_id="base_link",
                         pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36)),
                         twist=T["geometry_msgs/msg/TwistWithCovariance"](twist=twist, covariance=np.zeros(36)))
            if k != missing:
                writer.write(base, ns, serialize(msg, odo))
            for f, connection in feet.items() if k < len(log) else ():
                wrench = T["geometry_msgs/msg/Wrench"](force=vec(x=row[f"{f}_fx"], y=row[f"{f}_fy"], z=row[f"{f}_fz"]),
                                                       torque=vec(x=0.0, y=0.0, z=0.0))
                writer.write(connection, ns + late_ns, serialize(T[ws](header=header(ns + late_ns, "world"),
                                                                      wrench=wrench), ws))
    return names


def _from_bag(text: str, log: str, bag: str) -> str:
    """A CSV log's scenario (`_scenario`) made the same log's from its bag (`_write_bag`): the joint states' topic,
    the base's odometry topic (its twist in base axes) and each foot's wrench topic."""
    text = text.replace(f'file = "{log}"\ncolumns = {{ t = "t", q = "q{{j}}", qd = "qd{{j}}", tau = "tau{{j}}" }}',
                        f'bag = "{bag}"\ntopic = "/joint_states"')
    text = re.sub(r'\[data\.base\].*?(?=\[\[data\.contacts\]\])',
                  '[data.base]\ntopic = "/odom"\ntwist_axes = "base"\n\n', text, flags=re.DOTALL)
    return re.sub(r'force = \["(\w+)_fx", "\w+", "\w+"\]', r'topic = "/\1/wrench"', text)


@pytest.mark.slow  # a floating log written to a bag and identified (1 to 1.5 s each)
@pytest.mark.parametrize("kind", ["ros2", "ros1"])
def test_a_floating_log_in_a_ros_bag_reads_as_its_csv(standing, tmp_path, kind):
    """The log as a ROS bag (`_write_bag`: joint states, the base's odometry with one message more and row 150's
    left out, each foot's wrench 0.1 ms later): `[data] bag` with `[data.base] topic` and each contact's `topic`,
    joined on the stamps to the joint states' (the feet's to the nearest, the joint state without an odometry
    dropped, both said), reads as the same log written as a CSV with the stamps' times, that row left out: the
    conditioned training span's every channel to the bit."""
    _write(standing, tmp_path / "log.csv")
    log = pd.read_csv(tmp_path / "log.csv")
    ns = np.round(log["t"].to_numpy() * 1e9).astype(np.int64)
    log["t"] = ns // 10**9 + (ns % 10**9) * 1e-9  # the stamps' times, as a bag's reader adds them
    write_frame(log.drop(index=150), tmp_path / "log.csv")
    plain = load_scenario(_scenario(tmp_path, tmp_path / "log.csv"))
    (tmp_path / "b").mkdir()
    _write_bag(tmp_path / "b" / ("run.bag" if kind == "ros1" else "run"), log, kind, 100_000, missing=150)
    (tmp_path / "b" / "s.toml").write_text(_from_bag(_scenario(tmp_path / "b", "x").read_text(), "x",
                                                     "run.bag" if kind == "ros1" else "run"))
    published = load_scenario(tmp_path / "b" / "s.toml")
    a, b = (load(sc.data, sc.robot).training for sc in (plain, published))
    for field in ("t", "q", "qd", "qdd", "tau", "base_pose", "base_twist_W", "base_rate_W", "contact_F_W",
                  "contact_x_W"):
        assert np.array_equal(getattr(a, field), getattr(b, field)), field
    said = b.meta["warnings"]
    assert any("/FL_foot/wrench joined to the joint states on 'header.stamp': 300 of 300 rows to the nearest" in w
               for w in said), said
    assert any("1 of 301 rows of the joint states have no row of /odom within half a step" in w for w in said), said


def test_a_floating_log_s_topics_badly_given_are_refused_in_one_line(standing, tmp_path, capsys):
    """A bag's base and contacts are topics, a CSV's columns, each refused in the other's place; a topic the bag
    lacks, or of another message type, is refused at load naming the scenario's key and what the bag has."""
    _write(standing, tmp_path / "log.csv")
    _write_bag(tmp_path / "run", pd.read_csv(tmp_path / "log.csv").iloc[:40], "ros2", 0)
    csv = _scenario(tmp_path, "log.csv").read_text()
    bag = _from_bag(csv, "log.csv", "run")
    cases = [
        (csv.replace('twist_axes = "base"', 'twist_axes = "base"\ntopic = "/odom"'), "data.base.topic",
         "read from a ROS bag"),
        (bag.replace('topic = "/odom"', 'position = ["px", "py", "pz"]'), "data.base.topic", "missing"),
        (bag.replace('topic = "/odom"', 'topic = "/odom"\norder = "xyzw"'), "data.base.order", "carry it"),
        (bag.replace('topic = "/FL_foot/wrench"', 'topic = "/FL_foot/wrench"\nforce = ["a", "b", "c"]'),
         "data.contacts[0].force", "carry it"),
        (bag.replace('topic = "/odom"', 'topic = "/imu"'), "data.base.topic", "no topic '/imu' in the bag"),
        (bag.replace('topic = "/odom"', 'topic = "/FL_foot/wrench"'), "data.base.topic", "not nav_msgs/Odometry"),
        (bag.replace('topic = "/HR_foot/wrench"', 'topic = "/odom"'), "data.contacts[3].topic",
         "not geometry_msgs/WrenchStamped"),
    ]
    for text, key, said in cases:
        (tmp_path / "bad.toml").write_text(text)
        assert main(["run", str(tmp_path / "bad.toml"), "--out", str(tmp_path / "bad"), "--quiet"]) == 2, key
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and key in err[0] and said in err[0], err
        assert not (tmp_path / "bad").exists()


def test_a_floating_log_s_torque_constants_are_fixed_by_the_feet_s_forces(standing, tmp_path):
    """Motor currents declared with constants off by -20 % to +30 % (`identify_torque_constants = true`): each
    joint's factor (the torque its motor gives over the torque its currents give at the declared constant) is
    identified with the base parameters from the feet's forces and the joints' rows, the feet's forces in
    newtons fixing the scale that an arm's currents leave free (it needs a payload), within 2e-3 of the truth's
    (4e-4 measured on the exact log: the accelerations' differences), each inside its 95 % interval; the fit
    predicts the unseen span as the log with the right constants does (within 3e-2 of the truth; 6.7e-4
    measured, 6.0e-4 with the right constants), where the declared constants read as they are leave it over 10 %
    off (150 %). The span judged is read at the constants found (the truth is the log there within 1e-2). The
    report shows the constants' table."""
    _write(standing, tmp_path / "log.csv")
    log = pd.read_csv(tmp_path / "log.csv")
    joints = [f"tau{k + 1}" for k in range(12)]
    off = np.array([1.3, 0.8, 1.1, 0.9, 1.2, 1.0, 0.85, 1.25, 1.05, 0.95, 1.15, 0.8])
    log[joints] = log[joints].to_numpy() / (CONSTANT * GEAR)
    write_frame(log, tmp_path / "log.csv")
    currents = (f'units = {{ q = "rad", qd = "rad/s", tau = "current" }}\n'
                f'torque_constant = {(CONSTANT * off).tolist()}\ngear_ratio = {GEAR.tolist()}')
    figures = {}
    for name, extra in (("identified", "\nidentify_torque_constants = true"), ("declared", "")):
        (tmp_path / name).mkdir()
        path = _scenario(tmp_path / name, tmp_path / "log.csv")
        path.write_text(path.read_text().replace('units = { q = "rad", qd = "rad/s", tau = "N m" }', currents + extra))
        code, results = _run(path, tmp_path / name / "out")
        f = results["floating_log"]
        figures[name] = f["judged"]["least_squares"]["truth"]["max_rel_error"]
        if name == "identified":
            assert code == 0
            per_joint = f["torque_constants"]["per_joint"]
            factor = np.array([per_joint[j]["factor"] for j in load_scenario(path).robot.joint_names])
            np.testing.assert_allclose(factor, 1.0 / off, rtol=2e-3)
            identified = np.array([per_joint[j]["identified"] for j in per_joint])
            np.testing.assert_allclose(identified, CONSTANT, rtol=2e-3)
            assert all(v["ci95"][0] < v["identified"] < v["ci95"][1] for v in per_joint.values())
            assert "Torque constants (motor currents)" in (tmp_path / name / "out" / "report.html").read_text()
            # the span judged read at the constants found on the training span: the truth is the log there
            assert f["judged"]["model_as_given"]["measured"]["max_rel_error"] <= 1e-2
        else:
            assert f["torque_constants"] is None
    assert figures["identified"] <= 3e-2 < 0.1 < figures["declared"]
