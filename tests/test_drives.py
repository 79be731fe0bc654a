"""Drives (harness/model/drives.py): motors behind the joints through a transmission N, as a lab measures
an arm. Each claim is checked against physics or an independent computation:
- the transmission's maps are inverse to each other and conserve power (virtual work), to round-off;
- a diagonal N is each joint's own law reflected through its ratio (I r^2, f_v r^2, f_c |r|, f_o r,
  v_c / |r|): the same torques and mass matrix to 1e-12;
- a coupled drive in MuJoCo (a fixed tendon carrying the rotor's inertia and damping, the dry friction
  applied through N) and the law of drives.py in Pinocchio agree to 1e-9 of each joint's load (measured
  ~1e-13), and MuJoCo's mass matrix is CRBA's plus N^T diag(I_m) N to 1e-12;
- the MJCF the harness writes reloads as the same drives, and MuJoCo's own inverse dynamics of it agrees;
- a log of the motors (positions and torques in two files, no time column) reads as the joint-side log
  of the same motion, to round-off of the maps;
- a position repeated while the torques move is data; a whole row repeated is a logger's hold.
The arm: the example's two-link arm with motor 2 turning with 20 q1 - 30 q2 (coupled, of either sign)."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from harness.api import load_scenario
from harness.base.tomlio import InputError
from harness.cli import main
from harness.engines.pinocchio import build_model, crba, rnea
from harness.model.drives import Transmission
from harness.model.load import load_spec
from harness.sources.bench import record
from tests.conftest import ROOT, mujoco_inverse, pinocchio_rnea, two_link_bench, write_frame

URDF = ROOT / "examples" / "two_link_arm" / "two_link_arm.urdf"
N = np.array([[50.0, 0.0], [20.0, -30.0]])
OFFSET = [0.5, -2.0]
MOTORS = {"motor_1": dict(armature=2.1e-5, viscous=3.3e-4, coulomb=0.012, offset=0.002, coulomb_velocity=0.9),
          "motor_2": dict(armature=3.7e-5, viscous=1.9e-4, coulomb=0.021, offset=-0.003, coulomb_velocity=1.3)}
G = np.array([0.0, 0.0, -9.81])


def _drives_model(folder, motors=MOTORS, name="coupled") -> str:
    (folder / f"{name}.toml").write_text(
        f'[model]\nname = "{name}"\n[urdf]\nfile = "{URDF}"\n[drives]\ntransmission = {N.tolist()}\n'
        f"offset = {OFFSET}\n" + "".join(f"[drives.{m}]\n" + "".join(f"{k} = {v!r}\n" for k, v in law.items())
                                        for m, law in motors.items()))
    return f"{name}.toml"


def _states(count=200, seed=4):
    rng = np.random.default_rng(seed)
    return rng.uniform(-2, 2, (count, 2)), rng.uniform(-3, 3, (count, 2)), rng.uniform(-20, 20, (count, 2))


def test_a_transmission_is_inverted_exactly_and_conserves_power():
    rng = np.random.default_rng(1)
    t = Transmission(rng.normal(size=(4, 4)) * 40, rng.normal(size=4), tuple("abcd"))
    q, qd, tau_m = rng.normal(size=(3, 50, 4))
    np.testing.assert_allclose(t.joint_positions(t.motor_positions(q)), q, rtol=0, atol=1e-12)
    np.testing.assert_allclose(t.motor_torques(t.joint_torques(tau_m)), tau_m, rtol=1e-12, atol=1e-12)
    power_joints = np.sum(t.joint_torques(tau_m) * qd, axis=1)
    np.testing.assert_allclose(power_joints, np.sum(tau_m * t.motor_rates(qd), axis=1), rtol=1e-12)


def test_a_diagonal_transmission_is_each_joints_law_reflected_through_its_ratio(tmp_path):
    """Motor k with ratio r (of either sign) and law (I, f_v, f_c, f_o, v_c) is, at its joint, I r^2,
    f_v r^2, f_c |r| with v_c / |r|, and f_o r: the torques and mass matrices agree to 1e-12."""
    r = [50.0, -30.0]
    (tmp_path / "diag.toml").write_text(
        f'[model]\nname = "diag"\n[urdf]\nfile = "{URDF}"\n[drives]\ngear_ratio = {r}\n'
        + "".join(f"[drives.{m}]\n" + "".join(f"{k} = {v!r}\n" for k, v in law.items()) for m, law in MOTORS.items()))
    laws = list(MOTORS.values())
    (tmp_path / "joints.toml").write_text(f'[model]\nname = "joints"\n[urdf]\nfile = "{URDF}"\n' + "".join(
        f"[joints.{j}]\narmature = {law['armature'] * rk**2!r}\nviscous = {law['viscous'] * rk**2!r}\n"
        f"coulomb = {law['coulomb'] * abs(rk)!r}\ncoulomb_velocity = {law['coulomb_velocity'] / abs(rk)!r}\n"
        f"offset = {law['offset'] * rk!r}\n" for j, law, rk in zip(("shoulder", "elbow"), laws, r, strict=True)))
    a, b = (build_model(load_spec(tmp_path / f), G) for f in ("diag.toml", "joints.toml"))
    q, qd, qdd = _states()
    ta, tb = rnea(a, q, qd, qdd).tau, rnea(b, q, qd, qdd).tau
    np.testing.assert_allclose(ta, tb, rtol=0, atol=1e-12 * np.max(np.abs(tb)))
    np.testing.assert_allclose(crba(a, q), crba(b, q), rtol=1e-12, atol=0)


@pytest.fixture(scope="module")
def coupled_bench(tmp_path_factory):
    """The coupled arm recorded by the bench (3 s at 500 Hz, both joints on sinusoids), written as a log
    of the joints (joints.csv: t, q, tau) and as the motors' log a lab publishes (pos.csv: q_m = N q + o,
    cur.csv: N^-T tau, no time column), with a scenario of each (joints.toml, motors.toml)."""
    folder = tmp_path_factory.mktemp("coupled")
    sc = two_link_bench(folder, _drives_model(folder), 3.0, 1500)
    rec = record(sc)
    t = sc.robot.transmission
    pd.DataFrame({"t": rec.t, **{f"q{k + 1}": rec.q[:, k] for k in range(2)},
                  **{f"tau{k + 1}": rec.tau[:, k] for k in range(2)}}).to_csv(folder / "joints.csv", index=False,
                                                                             float_format="%.17g")
    q_m, tau_m = t.motor_positions(rec.q), t.motor_torques(rec.tau)
    pd.DataFrame({f"M{k + 1}": q_m[:, k] for k in range(2)}).to_csv(folder / "pos.csv", index=False,
                                                                    float_format="%.17g")
    pd.DataFrame({f"M{k + 1}": tau_m[:, k] for k in range(2)}).to_csv(folder / "cur.csv", index=False,
                                                                      float_format="%.17g")
    _log_scenario(folder, 'file = "joints.csv"\ncolumns = { t = "t", q = "q{j}", tau = "tau{j}" }\n', "joints")
    _log_scenario(folder, 'file = "pos.csv"\ntorque_file = "cur.csv"\ncolumns = { q = "M{j}", tau = "M{j}" }\n'
                          f'sample_rate = {float(1 / (rec.t[1] - rec.t[0]))!r}\nside = "motor"\n', "motors")
    return folder, sc


def test_the_torques_alone_are_rneas_torques_with_drives_to_the_bit(tmp_path):
    """joint_torques (the torques without the joint wrenches, which the closed chain's forward runs ask
    thousands of times) is rnea's tau bit for bit, drives, coupling and dry friction included."""
    from harness.engines.pinocchio import joint_torques

    pm = build_model(load_spec(tmp_path / _drives_model(tmp_path)), G)
    q, qd, qdd = _states()
    assert np.array_equal(joint_torques(pm, q, qd, qdd), rnea(pm, q, qd, qdd).tau)


def test_a_coupled_drive_in_mujoco_is_the_law_of_drives_in_pinocchio(coupled_bench):
    """The bench's torques (MuJoCo: tendons and the dry friction through N) against Pinocchio's RNEA with
    drives.torque, every step, to 1e-9 of each joint's load; MuJoCo's mass matrix with the tendons'
    armature against CRBA plus N^T diag(I_m) N at every 100th row, to 1e-12 of its largest entry."""
    import mujoco

    import harness
    from harness.engines.mujoco import build_model as build_mujoco

    folder, sc = coupled_bench
    result = harness.run(folder / "bench.toml")
    assert result.passed, result.results["torques"]["pinocchio_vs_mujoco"]
    rec = result.recording
    m = build_mujoco(sc.robot, sc.gravity_W, sc.simulation)
    d = mujoco.MjData(m)
    pm = build_model(sc.robot, sc.gravity_W)
    for k in range(0, len(rec.t), 100):
        d.qpos[:] = rec.q[k]
        mujoco.mj_forward(m, d)
        M = np.zeros((m.nv, m.nv))
        mujoco.mj_fullM(m, d, M)
        expected = crba(pm, rec.q[k:k + 1])[0]
        np.testing.assert_allclose(M, expected, rtol=0, atol=1e-12 * np.max(np.abs(expected)))


def test_the_drives_written_as_mjcf_reload_as_the_same_drives_and_mujoco_agrees(tmp_path):
    """write_mjcf: a fixed tendon per motor (N's row as coefficients, the rotor's armature and damping,
    its Coulomb friction as frictionloss) and a motor on it. Read back through the harness, the same
    transmission and laws (v_c aside: MJCF's dry friction is a sign; MJCF has no torque offset), RNEA's
    torques to 1e-12; MuJoCo's mj_inverse of the file (its frictionloss left out, as MuJoCo solves it as a
    constraint) is RNEA's without the Coulomb and offset terms, to 1e-9 of the largest torque."""
    import mujoco

    from harness.model.mjcf import write_mjcf

    sharp = {m: {**law, "coulomb_velocity": 0.0, "offset": 0.0} for m, law in MOTORS.items()}
    spec = load_spec(tmp_path / _drives_model(tmp_path, sharp))
    (tmp_path / "robot.xml").write_text(write_mjcf(spec, G))
    (tmp_path / "reloaded.toml").write_text('[mjcf]\nfile = "robot.xml"\n')
    back = load_spec(tmp_path / "reloaded.toml")
    np.testing.assert_array_equal(back.transmission.N, spec.transmission.N)
    for a, b in zip(spec.frictions, back.frictions, strict=True):
        assert (a.armature, a.viscous, a.coulomb) == pytest.approx((b.armature, b.viscous, b.coulomb), rel=1e-15)
    q, qd, qdd = _states(50)
    np.testing.assert_allclose(rnea(build_model(back, G), q, qd, qdd).tau, rnea(build_model(spec, G), q, qd, qdd).tau,
                               rtol=0, atol=1e-12 * 50)
    no_coulomb = spec.with_frictions(tuple(dataclasses_replace(f, coulomb=0.0) for f in spec.frictions))
    expected = rnea(build_model(no_coulomb, G), q, qd, qdd).tau
    model = mujoco.MjModel.from_xml_path(str(tmp_path / "robot.xml"))
    model.tendon_frictionloss[:] = 0.0
    got = mujoco_inverse(model, q, qd, qdd)
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-9 * np.max(np.abs(expected)))


def dataclasses_replace(obj, **changes):
    import dataclasses

    return dataclasses.replace(obj, **changes)


def _log_scenario(folder, data: str, name: str = "s") -> None:
    (folder / f"{name}.toml").write_text(
        f'[scenario]\nmodel = "coupled.toml"\n[data]\n{data}units = {{ q = "rad", tau = "N m" }}\ncutoff = 20.0\n'
        'validation = { from = 0.7 }\n'
        '[[gates]]\nmetric = "log_identification.validation_rel_error.consistent"\nlimit = 0.05\n')


def test_a_motor_side_log_with_velocities_reads_as_the_joints_log_to_round_off(tmp_path):
    """A log with velocity columns written at the joints (t, q, q', tau) and at the motors (q_m = N q + o,
    q'_m = N q', tau_m = N^-T tau): read, the motors' log is the joints' to round-off, its velocities
    mapped back by N^-1 (a motor's velocity read as a joint's rate, N q'_m, is N^2 q': 2,500 q' on the
    first joint here)."""
    from harness.api import load_scenario
    from harness.sources.log.read import read_raw

    model = load_spec(tmp_path / _drives_model(tmp_path))
    t = np.arange(500) * 0.002
    q = np.stack([0.4 * np.sin(1.3 * t), 0.3 * np.cos(2.1 * t)], axis=1)
    qd = np.stack([0.52 * np.cos(1.3 * t), -0.63 * np.sin(2.1 * t)], axis=1)
    tau = np.stack([12 + 3 * np.sin(2 * t), -4 + np.cos(3 * t)], axis=1)
    tr = model.transmission
    q_m, qd_m, tau_m = tr.motor_positions(q), tr.motor_rates(qd), tr.motor_torques(tau)
    for name, (a, b, c) in (("joints", (q, qd, tau)), ("motors", (q_m, qd_m, tau_m))):
        pd.DataFrame({"t": t, **{f"q{k + 1}": a[:, k] for k in range(2)}, **{f"qd{k + 1}": b[:, k] for k in range(2)},
                      **{f"tau{k + 1}": c[:, k] for k in range(2)}}).to_csv(tmp_path / f"{name}.csv", index=False,
                                                                           float_format="%.17g")
        side = 'side = "motor"\n' if name == "motors" else ""
        _log_scenario(tmp_path, f'file = "{name}.csv"\ncolumns = {{ t = "t", q = "q{{j}}", qd = "qd{{j}}", '
                                f'tau = "tau{{j}}" }}\n{side}', name)
    read = {name: read_raw(sc.data, sc.robot) for name, sc in
            ((n, load_scenario(tmp_path / f"{n}.toml")) for n in ("joints", "motors"))}
    for kind in ("q", "qd", "tau"):
        a, b = getattr(read["joints"], kind), getattr(read["motors"], kind)
        assert np.max(np.abs(a - b)) <= 1e-12 * np.max(np.abs(a)), kind


def test_a_log_of_the_motors_in_two_files_without_a_time_column_is_the_joints_log(coupled_bench):
    """The bench's recording written twice: at the joints (t, q, tau), and at the motors as a lab
    publishes it (positions q_m = N q + o in one file, torques N^-T tau in another, no time column:
    `sample_rate`). Read, checked, conditioned and split, the two training spans agree to 1e-9 of each
    quantity's size (the maps' round-off, then the same conditioning)."""
    folder, _ = coupled_bench
    from harness.sources.log import load

    a, b = (load((s := load_scenario(folder / f"{name}.toml")).data, s.robot) for name in ("joints", "motors"))
    for k in ("t", "q", "qd", "qdd", "tau"):
        x, y = getattr(a.training, k), getattr(b.training, k)
        np.testing.assert_allclose(y, x, rtol=0, atol=1e-9 * np.max(np.abs(x)), err_msg=k)


def test_a_position_repeated_while_the_torques_move_is_data_and_a_whole_row_repeated_is_a_hold(coupled_bench,
                                                                                               tmp_path):
    """A quantised encoder repeats a position while the torques move on: that row is kept; a logger
    that holds its last sample repeats the whole row: that row is dropped, and said."""
    from harness.sources.log.checks import check
    from harness.sources.log.read import read_raw

    folder, _ = coupled_bench
    df = pd.read_csv(folder / "joints.csv")
    folder = tmp_path
    (folder / "coupled.toml").write_text((coupled_bench[0] / "coupled.toml").read_text())
    _log_scenario(folder, 'file = "joints.csv"\ncolumns = { t = "t", q = "q{j}", tau = "tau{j}" }\n', "joints")
    df.loc[200:204, ["q1", "q2"]] = df.loc[199, ["q1", "q2"]].to_numpy()  # positions held, torques moving
    df.loc[400:402, df.columns[1:]] = df.loc[399, df.columns[1:]].to_numpy()  # the whole row held
    write_frame(df, folder / "joints.csv")
    s = load_scenario(folder / "joints.toml")
    c = check(read_raw(s.data, s.robot), s.robot, s.data)
    assert c.record["repeated_rows_dropped"] == 3 and c.record["repeated_positions_kept"] == 5
    assert any("sample and hold" in w for w in c.warnings)


@pytest.mark.parametrize("edit, key, words", [
    ('side = "motor"', "data.side", "states none ([drives])"),
    ("sample_rate = 500.0", "data.sample_rate", "time column"),
])
def test_a_bad_motor_side_log_table_is_refused_in_one_line(coupled_bench, tmp_path, capsys, edit, key, words):
    folder, _ = coupled_bench
    (tmp_path / "plain.toml").write_text(f'[model]\nname = "plain"\n[urdf]\nfile = "{URDF}"\n')
    model = "plain.toml" if "side" in edit else str(folder / "coupled.toml")
    (tmp_path / "s.toml").write_text(
        f'[scenario]\nmodel = "{model}"\n[data]\nfile = "{folder / "joints.csv"}"\n'
        f'columns = {{ t = "t", q = "q{{j}}", tau = "tau{{j}}" }}\n{edit}\n'
        '[[gates]]\nmetric = "log_identification.validation_rel_error.consistent"\nlimit = 0.05\n')
    assert main(["run", str(tmp_path / "s.toml"), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and key in err and words in err and not (tmp_path / "out").exists()


@pytest.mark.parametrize("drives, key, words", [
    ("gear_ratio = [50, 0]", "drives.gear_ratio", "not invertible (condition number inf): entry 2 (motor 'motor_2', "
                                                  "joint 'elbow') is 0"),
    ('gear_ratio = [50, 30]\ncoupling = [{ motor = "motor_2", joint = "elbow", ratio = 3 }]',
     "drives.coupling[0].joint", "own joint"),
    ('gear_ratio = [50, 30]\ncoupling = [{ motor = "motor_1", joint = "elbow", ratio = 30 }, '
     '{ motor = "motor_2", joint = "shoulder", ratio = 50 }]', "drives.coupling[0]",
     "ratio 30 of motor 'motor_1' on joint 'elbow' makes it so (without it N is invertible)"),
    ("transmission = [[1, 2], [2, 4]]", "drives.transmission", "the rows of motors 'motor_1', 'motor_2' are linearly "
                                                               "dependent"),
    ("transmission = [[1, 2], [0, 0]]", "drives.transmission.1", "motor 'motor_2' turns with no joint"),
    ("transmission = [[1, 0], [2, 0]]", "drives.transmission", "no motor turns joint 'elbow'"),
    ("gear_ratio = [50, 30]\nmotors = [\"a\"]", "drives.motors", "one distinct name"),
])
def test_a_bad_drives_table_is_refused_in_one_line_naming_the_key(tmp_path, capsys, drives, key, words):
    """A transmission N that is not invertible is refused naming what makes it so: a gear ratio of 0, a
    coupling without which N is invertible, a motor's row or a joint's column of zeros, the dependent rows."""
    (tmp_path / "m.toml").write_text(f'[model]\nname = "m"\n[urdf]\nfile = "{URDF}"\n[drives]\n{drives}\n')
    from harness.base.tomlio import InputError

    with pytest.raises(InputError) as e:
        load_spec(tmp_path / "m.toml")
    assert e.value.key == key and words in e.value.message


def test_joint_friction_beside_drives_is_refused(tmp_path):
    from harness.base.tomlio import InputError

    (tmp_path / "m.toml").write_text(f'[model]\nname = "m"\n[urdf]\nfile = "{URDF}"\n[joints.elbow]\nviscous = 1.0\n'
                                     '[drives]\ngear_ratio = [50, 30]\n')
    with pytest.raises(InputError, match="the motors carry it"):
        load_spec(tmp_path / "m.toml")


def test_the_identified_model_of_a_motor_side_log_predicts_what_the_run_judged(coupled_bench):
    """harness.identified_model(the run's folder): `joint_names` and `inverse_dynamics`, the exported
    model with its coupled drives, predicts at the validation span's states the torques the run's
    report plots for the consistent fit, to 1e-9 of the largest; and so does its least-squares fit
    (`fit="least squares"`, identified/least_squares.toml: the parameters results.json gives, to the
    last bit, on the regressor's columns it names)."""
    import harness

    folder, _ = coupled_bench
    assert main(["run", str(folder / "motors.toml"), "--out", str(folder / "out"), "--quiet"]) == 0
    results = json.loads((folder / "out" / "results.json").read_text())
    series = results["log_identification"]["series"]
    data = pd.read_csv(folder / "out" / "data.csv")
    rows = np.searchsorted(data["t"].to_numpy(), series["t"])
    model = harness.identified_model(folder / "out")
    assert model.joint_names == ["shoulder", "elbow"] and model.spec.transmission is not None
    states = [data[[f"{k}_{j}" for j in model.joint_names]].to_numpy()[rows] for k in ("q", "qd", "qdd")]
    predicted = model.inverse_dynamics(*states)
    judged = np.column_stack([series["consistent"][j] for j in model.joint_names])
    np.testing.assert_allclose(predicted, judged, rtol=0, atol=1e-9 * np.max(np.abs(judged)))
    assert (folder / "out" / "identified" / "drives.toml").is_file()
    ls = harness.identified_model(folder / "out", fit="least squares")  # identified/least_squares.toml
    judged = np.column_stack([series["least squares"][j] for j in ls.joint_names])
    np.testing.assert_allclose(ls.inverse_dynamics(*states), judged, rtol=0, atol=1e-9 * np.max(np.abs(judged)))
    base = results["log_identification"]["least_squares"]["base"]
    assert [p["expression"] for p in base] == ls.fit.expressions
    assert [p["identified"] for p in base] == ls.fit.beta.tolist()  # every float to the last bit


# --- a coupled wrist on a bench with truth ------------------------------------------------------------

TX40 = ROOT / "harness" / "data" / "models" / "tx40.toml"
# each motor's law at the motor (rotor inertia, viscous, Coulomb over v_c, offset), of the size of the
# TX40's published drive parameters reflected through its gears, every value distinct
TX40_MOTORS = {
    "motor_1": dict(armature=3.5e-4, viscous=7.9e-3, coulomb=0.22, offset=0.012, coulomb_velocity=0.64),
    "motor_2": dict(armature=3.3e-4, viscous=5.4e-3, coulomb=0.26, offset=0.043, coulomb_velocity=0.64),
    "motor_3": dict(armature=4.9e-5, viscous=9.7e-4, coulomb=0.14, offset=0.007, coulomb_velocity=0.9),
    "motor_4": dict(armature=1.4e-5, viscous=4.8e-4, coulomb=0.052, offset=-0.002, coulomb_velocity=0.96),
    "motor_5": dict(armature=2.3e-5, viscous=9.2e-4, coulomb=0.067, offset=-0.0006, coulomb_velocity=0.9),
    "motor_6": dict(armature=1.0e-5, viscous=6.1e-4, coulomb=0.061, offset=0.004, coulomb_velocity=0.64),
}
ENCODER_STEP = 2 * np.pi / 2**16  # rad at the motor: a 16-bit encoder (the TX40's own: 3.2e-5 to 9.5e-5)
TORQUE_CONSTANT = [0.41, 0.43, 0.37, 0.22, 0.24, 0.21]  # N m/A
CURRENT_NOISE = 0.01  # of each motor's RMS current


@pytest.fixture(scope="module")
def wrist_bench(tmp_path_factory):
    """The TX40 with its coupled wrist (models/tx40.toml's drives) and known motor laws, simulated by the
    bench (MuJoCo, a tendon per motor; RK4, 0.5 ms) on three sinusoids a joint for 12 s at 1 kHz, and
    published as a lab's motor-side log: the motor angles through a 16-bit encoder (pos.csv), the motor
    currents tau_m / k_t with 1 % noise (cur.csv, seed 7), no time column. The scenario reads it with the
    drives' structure and no law given, nothing of its conditioning given, the truth named."""
    import tomllib

    folder = tmp_path_factory.mktemp("wrist")
    drives = tomllib.loads(TX40.read_text())["drives"]
    head = (f'[urdf]\nfile = "{TX40.parent / tomllib.loads(TX40.read_text())["urdf"]["file"]}"\n[drives]\n'
            f"gear_ratio = {drives['gear_ratio']}\njoint_offset = {drives['joint_offset']}\n"
            'coupling = [{ motor = "motor_6", joint = "joint_5", ratio = 32 }]\n')
    for name, keys in (("truth", None), ("given", ("coulomb_velocity",))):
        (folder / f"{name}.toml").write_text(f'[model]\nname = "{name}"\n' + head + "".join(
            f"[drives.{m}]\n" + "".join(f"{k} = {v!r}\n" for k, v in law.items() if keys is None or k in keys)
            for m, law in TX40_MOTORS.items()))
    rng = np.random.default_rng(7)
    motion = "".join(
        f'[motion.joint_{j + 1}]\ntype = "sinusoids"\noffset = {offset}\n'
        f"sin = {np.column_stack([rng.uniform(0.15, 0.45, 3), rng.uniform(1.0, 4.5, 3)]).tolist()}\n"
        for j, offset in enumerate((0.0, 0.3, -0.4, 0.0, 0.5, 0.0)))
    (folder / "bench.toml").write_text(
        '[scenario]\nmodel = "truth.toml"\ngravity = [0.0, 0.0, -9.80665]\nduration = 12.0\noutput_steps = 12000\n'
        '[simulation]\nintegrator = "RK4"\ntimestep = 0.0005\n' + motion
        + '[[gates]]\nmetric = "torques.pinocchio_vs_mujoco.max_rel_error"\nlimit = 1e-9\n')
    sc = load_scenario(folder / "bench.toml")
    rec = record(sc)
    t = sc.robot.transmission
    tau_m = t.motor_torques(rec.tau)
    current = (tau_m + CURRENT_NOISE * np.sqrt(np.mean(tau_m**2, axis=0)) * rng.standard_normal(tau_m.shape)) \
        / np.asarray(TORQUE_CONSTANT)
    columns = [f"Joint_{k + 1}" for k in range(6)]
    pd.DataFrame(np.round(t.motor_positions(rec.q) / ENCODER_STEP) * ENCODER_STEP, columns=columns).to_csv(
        folder / "pos.csv", index=False, float_format="%.17g")
    write_frame(pd.DataFrame(current, columns=columns), folder / "cur.csv")
    (folder / "log.toml").write_text(
        '[scenario]\nmodel = "given.toml"\n[data]\nfile = "pos.csv"\ntorque_file = "cur.csv"\n'
        'columns = { q = "Joint_{j}", tau = "Joint_{j}" }\nsample_rate = 1000.0\nside = "motor"\n'
        f'units = {{ q = "rad", tau = "current" }}\ntorque_constant = {TORQUE_CONSTANT}\ntruth = "truth.toml"\n'
        'validation = { from = 0.7 }\n'
        '[[gates]]\nmetric = "log_identification.truth.validation_rel_error.consistent"\nlimit = 0.02\n')
    status = main(["run", str(folder / "log.toml"), "--out", str(folder / "out"), "--quiet"])
    return status, json.loads((folder / "out" / "results.json").read_text()), rec, sc


@pytest.mark.slow  # a few seconds: a bench recording and a whole pipeline
def test_a_coupled_wrist_read_at_its_motors_comes_back_as_close_to_its_truth_as_its_data(wrist_bench):
    """Held out, the identified model is no further from the truth's torques than the conditioned
    measurements themselves are (their 1 % current noise, and the encoder's steps, through the filter
    the data chose), and its error against the measurements is that noise: between 1/2 and 3/2 of the
    measurements' own error against the truth. The log was read as published: two files, no time,
    motor 6 mapped onto joints 5 and 6, a cut-off chosen for the quantised encoder."""
    status, results, _, _ = wrist_bench
    li, data = results["log_identification"], results["data"]["conditioning"]
    truth = li["truth"]["validation_rel_error"]
    assert status == 0 and truth["consistent"] <= truth["measured"]
    assert 0.5 * truth["measured"] <= li["validation_rel_error"]["consistent"] <= 1.5 * truth["measured"]
    read = data["steps"][0]
    assert read["side"] == "motor" and read["to_joints"]["coupled"] == {"motor_6": ["joint_5", "joint_6"]}
    assert read["time"].startswith("row k at k / 1000")
    assert data["defaults"]["cutoff_hz"] > 3 * max(data["defaults"]["motion_band_hz"])


@pytest.mark.slow  # a few seconds: a bench recording and a whole pipeline
def test_each_motors_law_comes_back_through_the_coupling(wrist_bench):
    """Each motor's friction, the terms every motion excites, within 3 % of the truth's (viscous and
    Coulomb: measured 0.1 to 1.1 %), its offset within 3 % of its Coulomb torque; and each motor's whole
    law at the validation states within 2 % of that motor's RMS torque. The rotor inertias of motors 1
    and 2 are judged with their links, not alone: joint 1 turns about the base's vertical, so I_zz1 +
    32^2 I_m1 multiplies q1'' and nothing else, and motor 2's enters a base parameter with link 2's
    inertia about its axis (the run's base parameters list both): no data can split them, and the
    held-out torques against the truth judge the sums. The law is written out here:
    I_m q_m'' + f_v q_m' + f_c tanh(q_m' / v_c) + f_o, q_m = N q + o."""
    _, results, rec, sc = wrist_bench
    found = results["log_identification"]["consistent"]["friction"]
    combined = [b["expression"] for b in results["log_identification"]["least_squares"]["base"]]
    for motor in ("motor_1", "motor_2"):
        assert any(f"{motor}.armature" in e and e.strip() != f"{motor}.armature" for e in combined), motor
    t = sc.robot.transmission
    held = rec.t >= 0.7 * rec.t[-1]
    qd_m, qdd_m = t.motor_rates(rec.qd[held]), t.motor_rates(rec.qdd[held])
    tau_m = t.motor_torques(rec.tau[held])
    for k, (motor, law) in enumerate(TX40_MOTORS.items()):
        got = found[motor]
        for term in ("viscous", "coulomb"):
            assert got[term] == pytest.approx(law[term], rel=0.03), (motor, term)
        assert abs(got["offset"] - law["offset"]) <= 0.03 * law["coulomb"], motor

        own_inertia = motor not in ("motor_1", "motor_2")
        error = ((got["armature"] - law["armature"]) * own_inertia * qdd_m[:, k]
                 + (got["viscous"] - law["viscous"]) * qd_m[:, k]
                 + (got["coulomb"] - law["coulomb"]) * np.tanh(qd_m[:, k] / law["coulomb_velocity"])
                 + got["offset"] - law["offset"])
        assert np.sqrt(np.mean(error**2)) <= 0.02 * np.sqrt(np.mean(tau_m[:, k] ** 2)), motor


@pytest.mark.parametrize(("unmeasured", "reached"), [("elbow", [True, True]), ("shoulder", [False, True])])
def test_a_coupled_arm_without_a_joints_channel_reads_the_other_and_keeps_the_law_of_a_motor_that_reaches_none(
        tmp_path, unmeasured, reached):
    """Motor 2 turns with 20 q1 - 30 q2, so its torque reaches both joints; motor 1's the shoulder's alone.
    With one joint's channel unmeasured, at 200 random states the other joint's rows times the model's own
    parameters are Pinocchio's rnea (rigid) plus N^T of the motors' laws at q'_m = N q' (computed here from
    the test's laws), to 1e-12 of the largest torque; a motor's four drive terms are among the base
    parameters only where it reaches the measured joint (reached), the others' none."""
    from harness.identify.torque_id import drive_columns
    from harness.stages.log_model import log_model

    spec = load_spec(tmp_path / _drives_model(tmp_path))
    model = log_model(spec, G, (unmeasured,))
    k = 1 - spec.joint_names.index(unmeasured)  # the measured joint
    assert model.torque_joints == [spec.joint_names[k]] and model.drives_reached.tolist() == reached
    q, qd, qdd = _states()
    pm = model.pm
    rigid = pinocchio_rnea(pm, q, qd, qdd)
    qd_m, qdd_m = qd @ N.T, qdd @ N.T
    laws = list(MOTORS.values())
    tau_m = np.column_stack([law["armature"] * qdd_m[:, m] + law["viscous"] * qd_m[:, m]
                             + law["coulomb"] * np.tanh(qd_m[:, m] / law["coulomb_velocity"]) + law["offset"]
                             for m, law in enumerate(laws)])
    expected = (rigid + tau_m @ N)[:, k]
    got = model.rows(pm, q, qd, qdd) @ model.x_model
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12 * np.abs(expected).max())
    independent = set(model.base.independent.tolist())
    for m, reaches in enumerate(reached):
        assert bool(set(range(*drive_columns(2, m).indices(28))) & independent) == reaches, m


def test_a_coupled_arms_log_without_a_channel_identifies_what_reaches_the_other(coupled_bench):
    """The bench log at the joints with the elbow's column absent, or the shoulder's reading 0, each
    declared unmeasured: the consistent fit predicts the truth's held-out torque of the measured joint
    within 1 % (the elbow left out: 0.32 %, both motors' laws through the shoulder's row alone; the
    shoulder left out: 9.2e-5; 1.2e-4 with both channels); the shoulder left out, motor 1 (which moves it
    alone) keeps the model's law exactly, motor 2's Coulomb term comes back within 1 %."""
    folder = coupled_bench[0]
    log = pd.read_csv(folder / "joints.csv")
    write_frame(log.drop(columns=["tau2"]), folder / "no_elbow.csv")
    write_frame(log.assign(tau1=0.0), folder / "no_shoulder.csv")
    results = {}
    for joint, tau in (("elbow", '["tau1"]'), ("shoulder", '"tau{j}"')):
        _log_scenario(folder, f'file = "no_{joint}.csv"\ncolumns = {{ t = "t", q = "q{{j}}", tau = {tau} }}\n'
                              f'truth = "coupled.toml"\nunmeasured = ["{joint}"]\n', f"no_{joint}")
        assert main(["run", str(folder / f"no_{joint}.toml"), "--out", str(folder / f"no_{joint}"), "--quiet"]) == 0
        results[joint] = json.loads((folder / f"no_{joint}" / "results.json").read_text())["log_identification"]
    for joint, li in results.items():
        assert li["unmeasured"]["joints"] == [joint] and li["truth"]["validation_rel_error"]["consistent"] <= 1e-2
    friction = results["shoulder"]["consistent"]["friction"]
    assert {key: friction["motor_1"][key] for key in MOTORS["motor_1"]} == MOTORS["motor_1"]
    assert abs(friction["motor_2"]["coulomb"] / MOTORS["motor_2"]["coulomb"] - 1) <= 0.01


def test_a_law_search_without_a_joints_channel_weighs_each_motor_on_the_measured_rows_alone(tmp_path):
    """The friction law search (harness/identify/friction_law.py) on exact torques of the coupled arm (its
    own laws, 3 s of sinusoids at 200 Hz) with the elbow unmeasured (its rows and torque zero): at the
    model's laws, which made the torques, each fold is predicted by the fit on the others to round-off
    (under 1e-9). Motor 2's columns counted on the elbow's rows too would predict torque where the log
    holds none."""
    from harness.engines.pinocchio import rnea
    from harness.identify import friction_law
    from harness.stages.log_model import log_model

    spec = load_spec(tmp_path / _drives_model(tmp_path))
    model = log_model(spec, G, ("elbow",))
    t = np.arange(600) / 200.0
    sines = ((-0.3, ((0.9, 2.1), (0.3, 5.3))), (0.0, ((1.0, 3.0), (0.2, 6.7))))
    q = np.column_stack([o + sum(a * np.sin(w * t) for a, w in s) for o, s in sines])
    qd = np.column_stack([sum(a * w * np.cos(w * t) for a, w in s) for _, s in sines])
    qdd = np.column_stack([-sum(a * w * w * np.sin(w * t) for a, w in s) for _, s in sines])
    W = model.joint_rows(model.pm, q, qd, qdd).reshape(len(t) * 2, -1)
    tau = rnea(model.pm, q, qd, qdd).tau * model.measured
    choice = friction_law.choose(W, model.base.independent, model.link_part, tau, qd, t, spec.frictions,
                                 friction_law.FrictionLawConfig(families=("viscous_coulomb",)), 0.0,
                                 spec.transmission, None, model.measured)
    assert choice.model_error <= 1e-9, choice.model_error


def test_a_motor_side_log_without_a_motors_channel_is_the_joint_side_log_without_the_joints_it_turns(coupled_bench):
    """Motor 1 turns the shoulder alone, motor 2 both joints. The motors' log without motor 1's channel (its
    torque file holds motor 2's column alone), declared unmeasured: the shoulder's torque (N^T tau_m needs
    motor 1's) is unmeasured, and the fit is
    the joint-side log's with the shoulder's channel left out (the truth's held-out error the same to 1e-6
    of itself: the logs differ by the maps' round-off); motor 1's law is the model's. Motor 2 unmeasured
    leaves no joint to read: refused in one line; a joint named on a motor-side log: refused naming the
    motors."""
    folder = coupled_bench[0]
    write_frame(pd.read_csv(folder / "cur.csv")[["M2"]], folder / "cur_m2.csv")
    pd.read_csv(folder / "joints.csv").assign(tau1=0.0).to_csv(folder / "joints_dead.csv", index=False,
                                                                 float_format="%.17g")
    t = pd.read_csv(folder / "joints.csv")["t"].to_numpy()
    rate = float(1 / (t[1] - t[0]))  # as the fixture's motors' log states it
    motors = (f'file = "pos.csv"\ntorque_file = "cur_m2.csv"\ncolumns = {{ q = "M{{j}}", tau = ["M2"] }}\n'
              f'sample_rate = {rate!r}\nside = "motor"\ntruth = "coupled.toml"\n')
    joints = 'file = "joints_dead.csv"\ncolumns = { t = "t", q = "q{j}", tau = "tau{j}" }\ntruth = "coupled.toml"\n'
    results = {}
    for name, data, unmeasured in (("motor_side", motors, "motor_1"), ("joint_side", joints, "shoulder")):
        _log_scenario(folder, data + f'unmeasured = ["{unmeasured}"]\n', name)
        assert main(["run", str(folder / f"{name}.toml"), "--out", str(folder / name), "--quiet"]) == 0
        results[name] = json.loads((folder / name / "results.json").read_text())["log_identification"]
    at_motors, at_joints = results["motor_side"], results["joint_side"]
    assert at_motors["torque_joints"] == at_joints["torque_joints"] == ["elbow"]
    assert at_motors["unmeasured"]["joints"] == ["shoulder"] and at_motors["unmeasured"]["motors"] == ["motor_1"]
    errors = [r["truth"]["validation_rel_error"]["consistent"] for r in (at_motors, at_joints)]
    assert abs(errors[0] / errors[1] - 1) <= 1e-6, errors
    friction = at_motors["consistent"]["friction"]["motor_1"]
    assert {key: friction[key] for key in MOTORS["motor_1"]} == MOTORS["motor_1"]
    for unmeasured, said in (("motor_2", "turn every joint"), ("shoulder", "is not one of motor_1, motor_2")):
        _log_scenario(folder, motors + f'unmeasured = ["{unmeasured}"]\n', "refused")
        with pytest.raises(InputError) as err:
            load_scenario(folder / "refused.toml")
        assert err.value.key == "data.unmeasured" and said in str(err.value), str(err.value)
