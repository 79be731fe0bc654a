"""A measured log of a closed chain: its actuated joints' channels read, the passive joints from the
loops at every row, the base parameters and friction identified through G^T Y, judged on a span the
fit never saw (harness/sources/log/closed.py, harness/identify/chain_law.py, docs/closed_chains.md).

Independent references: MuJoCo's own reading of the model file (its equality residual and constraint
Jacobian at the reconstructed states), a log made here from the rigid loops' exact torques (Pinocchio's
G^T rnea of a robot with friction at consistent states: no simulation, no noise), whose truth the
identification must find again, and the shipped bench log (MuJoCo, 1 % torque noise) against the robot
that made it."""

from __future__ import annotations

import json

import mujoco
import numpy as np
import pandas as pd
import pytest

from harness.base.tomlio import InputError
from harness.cli import main
from harness.engines import pinocchio as pin_engine
from harness.model import closure
from harness.model.load import load_spec, spec_from_data
from harness.runner.scenario import load_scenario

from .conftest import MODELS, NO_PREDICTION, ROOT, SCENARIOS, pinocchio_rnea, viscous_coulomb, write_frame

TRUTH = MODELS / "parallelogram_friction.toml"
RATE = 500.0  # Hz
DURATION = 8.0  # s
# per actuated joint (turret, shoulder, crank): (amplitude rad, angular frequency rad/s) of each sine,
# the crank's angle to the upper arm kept away from the parallelogram's folds
SINES = (((0.9, 1.3), (0.25, 3.7)), ((0.3, 1.7), (0.1, 4.1)), ((0.25, 2.1), (0.1, 3.3)))


def _actuated(t: np.ndarray, of=SINES):
    """(q_a, q'_a, q''_a), each (len(t), n_a), of sines `of` (SINES): a motion the test knows exactly."""
    q, qd, qdd = (np.zeros((len(t), len(of))) for _ in range(3))
    for k, sines in enumerate(of):
        for a, w in sines:
            q[:, k] += a * np.sin(w * t)
            qd[:, k] += a * w * np.cos(w * t)
            qdd[:, k] -= a * w * w * np.sin(w * t)
    return q, qd, qdd


@pytest.fixture(scope="module")
def exact(tmp_path_factory):
    """A log of the arm with friction (models/parallelogram_friction.toml) made from its rigid loops:
    every joint's state from the loops (closure.along), the actuated torques G^T rnea with every joint's
    law; the log holds t and the actuated joints' q, q', tau (no accelerations: the harness differences
    q'). Its folder, the truth's consistent motion and torques."""
    folder = tmp_path_factory.mktemp("exact_log")
    chain, states, tau_a = _exact_log(folder / "log.csv", TRUTH, SINES, RATE, DURATION)
    (folder / "s.toml").write_text(_scenario_text(folder / "log.csv", predicted=True))
    return folder, chain, states, tau_a


def _exact_log(path, truth, sines, rate: float, duration: float, noise: float = 0.0, cut=None, lag: float = 0.0):
    """The log of `truth` moved by `sines`, made from its rigid loops at `rate` for `duration` s, each
    actuated torque with `noise` times its RMS of seeded Gaussian noise and `lag` s behind the encoders,
    the rows of times in `cut` (a, b) dropped (a gap): the chain, every joint's exact states and the
    actuated torques."""
    spec = load_spec(truth)
    chain = closure.ClosedChain.of(spec)
    t = np.arange(0.0, duration, 1.0 / rate)
    q, qd, qdd = closure.along(chain, t, lambda times: _actuated(times, sines))
    lagged = closure.along(chain, t - lag, lambda times: _actuated(times, sines)) if lag else (q, qd, qdd)
    tau = pin_engine.rnea(pin_engine.build_model(spec, spec.gravity_W), *lagged).tau
    tau_a = closure.actuated_torques(closure.projection(chain, lagged[0]), tau)
    read = tau_a + noise * np.sqrt(np.mean(tau_a**2, axis=0)) * np.random.default_rng(7).standard_normal(tau_a.shape)
    act = list(chain.actuated)
    columns = {"t": t}
    for k in range(len(act)):
        columns |= {f"q{k + 1}": q[:, act[k]], f"qd{k + 1}": qd[:, act[k]], f"tau{k + 1}": read[:, k]}
    kept = np.ones(len(t), dtype=bool) if cut is None else (t < cut[0]) | (t > cut[1])
    write_frame(pd.DataFrame(columns)[kept], path)
    return chain, (q, qd, qdd), tau_a


def _scenario_text(log, extra_data: str = "", extra: str = "", model=MODELS / "parallelogram.toml",
                   truth=TRUTH, predicted: bool = False) -> str:
    """The scenario of a closed chain's log; the models forward-simulated only where `predicted` (a test
    of the prediction: the others read the fit, and the rollouts of a closed chain cost seconds)."""
    return f'''
[scenario]
description = "a closed chain's exact log"
model = "{model}"

[data]
file = "{log}"
columns = {{ t = "t", q = "q{{j}}", qd = "qd{{j}}", tau = "tau{{j}}" }}
units = {{ q = "rad", qd = "rad/s", tau = "N m" }}
truth = "{truth}"
validation = {{ from = 0.7 }}
{"" if predicted else NO_PREDICTION}
{extra_data}

[[gates]]
metric = "log_identification.consistent.inconsistent_links"
limit = 0
{extra}'''


def _run(path, out) -> tuple[int, dict]:
    code = main(["run", str(path), "--out", str(out), "--quiet"])
    results = out / "results.json"
    return code, json.loads(results.read_text()) if results.exists() else {}


@pytest.fixture(scope="module")
def exact_run(exact, tmp_path_factory):
    folder = exact[0]
    out = tmp_path_factory.mktemp("exact_run")
    code, results = _run(folder / "s.toml", out)
    return code, results, out


@pytest.mark.slow  # a closed chain's log identified whole (the module's exact_run: 4 s)
def test_the_passive_joints_close_the_loops_as_mujoco_reads_the_model(exact, exact_run):
    """data.csv (the conditioned log as the fit read it) holds every joint: at its rows MuJoCo's own
    equality residual is zero and its constraint Jacobian annihilates the velocities (to 1e-9 of the
    mechanism's size and of the velocities: the loops closed to 1e-12, the log's q' read from 17 digits)."""
    _, chain, _, _ = exact
    data = pd.read_csv(exact_run[2] / "data.csv")
    names = chain.spec.joint_names
    q, qd = data[[f"q_{j}" for j in names]].to_numpy(), data[[f"qd_{j}" for j in names]].to_numpy()
    model = mujoco.MjModel.from_xml_path(str(chain.spec.mjcf))
    d = mujoco.MjData(model)
    jid = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, j) for j in names]
    for k in range(0, len(q), 97):
        d.qpos[model.jnt_qposadr[jid]] = q[k]
        mujoco.mj_forward(model, d)
        rows = d.efc_type == mujoco.mjtConstraint.mjCNSTR_EQUALITY
        J = d.efc_J.reshape(d.nefc, model.nv)[rows][:, model.jnt_dofadr[jid]]
        assert np.abs(d.efc_pos[rows]).max() <= 1e-9 * chain.size
        assert np.abs(J @ qd[k]).max() <= 1e-9 * np.linalg.norm(J) * np.linalg.norm(qd[k])


@pytest.mark.slow  # reads exact_run (a closed chain's log identified whole)
def test_the_passive_joints_are_the_consistent_motion_the_log_was_made_from(exact, exact_run):
    """Every joint's q and q' at the conditioned rows equal the motion the log was made from (1e-10
    rad, 1e-9 rad/s), and q'' within 1e-3 of its largest (the harness differences q' at 500 Hz:
    second-order central differences of sines up to 4.1 rad/s, h^2 w^2 / 6 = 1e-5, the span's ends
    trimmed); the passive joints' torques are zero, and the report says where they came from."""
    _, chain, _, _ = exact
    data = pd.read_csv(exact_run[2] / "data.csv")
    t = data["t"].to_numpy()
    q, qd, qdd = closure.along(chain, t, _actuated)
    names = chain.spec.joint_names
    np.testing.assert_allclose(data[[f"q_{j}" for j in names]].to_numpy(), q, atol=1e-10, rtol=0)
    np.testing.assert_allclose(data[[f"qd_{j}" for j in names]].to_numpy(), qd, atol=1e-9, rtol=0)
    assert np.abs(data[[f"qdd_{j}" for j in names]].to_numpy() - qdd).max() <= 1e-3 * np.abs(qdd).max()
    passive = [names[k] for k in chain.passive]
    assert np.all(data[[f"tau_{j}" for j in passive]].to_numpy() == 0.0)
    assert f"Passive joints {', '.join(passive)}: the loops at every conditioned row" in \
        (exact_run[2] / "report.html").read_text()


@pytest.mark.slow  # reads exact_run (a closed chain's log identified whole)
def test_an_exact_closed_chain_log_is_identified_to_its_truth(exact_run):
    """From exact torques (no noise, rigid loops), the fit through G^T Y predicts the truth's torques
    on the span it never saw within 1e-4 (the differenced accelerations' error, 1e-5 of the largest);
    the law search finds the truth's smoothing velocity, 0.02 rad/s, within 5 %; the model as given (no
    friction) is tens of percent off."""
    code, results, _ = exact_run
    assert code == 0
    li = results["log_identification"]
    assert li["torque_joints"] == ["turret", "shoulder", "crank"]
    truth = li["truth"]["validation_rel_error"]
    assert truth["least squares"] <= 1e-4 and truth["consistent"] <= 1e-4
    assert truth["model as given"] >= 0.1
    velocities = set(li["friction_law"]["coulomb_velocity"].values())
    assert len(velocities) == 1 and abs(velocities.pop() / 0.02 - 1) <= 0.05
    assert li["friction_law"]["chosen"] and li["consistent"]["inconsistent_links"] == 0


@pytest.mark.slow  # reads exact_run (a closed chain's log identified whole)
def test_the_models_are_forward_simulated_from_the_log_s_states_with_their_loops(exact_run):
    """From 20 states of the span no fit saw, under the log's actuated torques: the truth (the robot
    that made the log) follows the motion within 2e-6 rad at 0.2 s (the torques are read between
    samples 2 ms apart by linear interpolation, h^2 tau'' / 8: about 1e-5 of them, 5e-7 rad after 0.2 s;
    measured 5.1e-7), the consistent fit within 1e-5 rad (1.1e-6), the model as given (no friction)
    drifts by more than 1e-3 rad (3.3e-2); no run left the loops."""
    _, results, _ = exact_run
    p = results["log_identification"]["prediction"]
    assert p["starts"] == 20 and "closed-chain" in p["definition"]
    at = {name: runs["h200ms"] for name, runs in p["models"].items()}
    assert at["truth"]["q_rms"] < 2e-6 and at["consistent"]["q_rms"] < 1e-5
    assert at["model as given"]["q_rms"] > 1e-3
    assert all(h["diverged"] == 0 for runs in p["models"].values() for h in runs.values())


@pytest.mark.slow  # reads exact_run (a closed chain's log identified whole)
def test_the_identified_closed_chain_is_exported_as_mjcf_with_its_loop(exact_run):
    """identified/robot.xml reads back as the same closed chain (its connect loop, its three actuated
    joints) with the identified inertials: its G^T rnea equals the consistent fit's torques."""
    _, results, out = exact_run
    assert "identified/robot.xml" in results["log_identification"]["export"]
    spec = spec_from_data({"mjcf": {"file": "robot.xml"}}, out / "identified" / "m.toml")
    original = load_spec(MODELS / "parallelogram.toml")
    assert [lp.name for lp in spec.loops] == [lp.name for lp in original.loops]
    assert spec.actuated == original.actuated
    masses = {b.name: b.mass for b in spec.bodies}
    identified = results["log_identification"]["consistent"]["links"]
    joints = {j.name: j.child for j in original.joints}
    for joint, link in identified.items():
        assert masses[joints[joint]] == pytest.approx(link["identified"]["m"], rel=1e-12)


def _refused(tmp_path, log, extra_data: str = "", extra: str = "") -> InputError:
    (tmp_path / "s.toml").write_text(_scenario_text(log, extra_data, extra))
    with pytest.raises(InputError) as err:
        load_scenario(tmp_path / "s.toml")
    return err.value


REFUSED = {  # what a closed chain's log path does not read yet: its key, and why
    "the motor side": ('side = "motor"', "", "data.side", "actuated joints"),
    "a refinement": ("", '[refinement]\nadjust = ["delay"]', "refinement", "open tree"),
    "a method beside the fit": ("", '[[identification]]\nname = "f"\nplugin = "figaroh"', "identification",
                                "open tree"),
    "friction law families": ("", '[friction_law]\nfamilies = ["stribeck"]', "friction_law.families",
                              "viscous and Coulomb"),
    "a counterbalanced channel": ('counterbalanced = ["ACTUATED"]', "", "data.counterbalanced", "with gravity"),
}


@pytest.mark.parametrize("case", REFUSED)
def test_what_a_closed_chain_s_log_cannot_read_yet_is_refused_naming_the_key(exact, tmp_path, case):
    extra_data, extra, key, message = REFUSED[case]
    text = _scenario_text(exact[0] / "log.csv", "", extra)
    from harness.model.load import load_spec

    actuated = load_spec(MODELS / "parallelogram.toml").actuated
    text = text.replace("validation = { from = 0.7 }",
                        f"validation = {{ from = 0.7 }}\n{extra_data.replace('ACTUATED', actuated[-1])}")
    (tmp_path / "s.toml").write_text(text)
    with pytest.raises(InputError) as err:
        load_scenario(tmp_path / "s.toml")
    assert err.value.key == key and message in str(err.value) and "closed chain" in str(err.value)


def test_a_log_with_a_column_per_joint_is_told_the_chain_logs_its_actuated_joints(exact, tmp_path):
    """The log's fourth joint's columns: the model's actuated joints are three."""
    log = pd.read_csv(exact[0] / "log.csv")
    log["q4"], log["qd4"], log["tau4"] = 0.0, 0.0, 0.0
    log.to_csv(tmp_path / "log.csv", index=False)
    err = _refused(tmp_path, tmp_path / "log.csv")
    assert err.key == "q4" and "actuated joints" in str(err) and "turret, shoulder, crank" in str(err)


def test_a_log_whose_actuated_joints_the_loops_cannot_follow_is_bad_input(exact, tmp_path, capsys):
    """The crank driven through the parallelogram's fold (its angle to the upper arm through pi/2, beyond
    its limits, whose check is turned off): exit 2, one line naming the file and its columns, no output folder."""
    log = pd.read_csv(exact[0] / "log.csv")
    log["q3"] = log["q3"] + 1.2 + 0.8 * np.sin(log["t"])
    log["qd3"] = log["qd3"] + 0.8 * np.cos(log["t"])
    log.to_csv(tmp_path / "log.csv", index=False)
    (tmp_path / "s.toml").write_text(_scenario_text(tmp_path / "log.csv", "limits_check = false"))
    out = tmp_path / "out"
    assert main(["run", str(tmp_path / "s.toml"), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "log.csv" in err[0] and "columns" in err[0] and "cannot be followed" in err[0]
    assert not out.exists()


@pytest.mark.slow  # a built-in scenario whole (its gates run in .ci/run; this reads beyond them)
def test_the_shipped_bench_log_is_identified_within_its_noise(tmp_path):
    """scenarios/parallelogram_bench_log.toml: MuJoCo's soft loops, 1 % torque noise. On the span the
    fit never saw, the consistent fit is within 0.3 % of the truth's torques, where the measured
    torques are 1 % off (the noise); the scenario's gates pass."""
    code, results = _run(SCENARIOS / "parallelogram_bench_log.toml", tmp_path / "out")
    assert code == 0
    truth = results["log_identification"]["truth"]["validation_rel_error"]
    assert truth["consistent"] <= 0.003 and truth["least squares"] <= 0.003
    assert 0.008 <= truth["measured"] <= 0.012


@pytest.mark.slow  # a 12 s simulation of the arm at 0.25 ms
def test_the_closed_chain_bench_log_is_what_its_recipe_makes(tmp_path):
    """harness/data/logs/parallelogram_bench/log.csv is the bench of its bench.toml, its actuated
    joints' channels measured: remade here, the same numbers to 1e-9 of each column's largest value
    (another CPU may round MuJoCo's last bits otherwise; the noise is seeded). Relative to the column,
    as every error here (harness/base/numerics.py): a velocity through zero, -2.5e-4 rad/s where its column
    reaches 0.95, differs by 1.3e-12 between an Intel Xeon and an AMD EPYC: 1.4e-12 of the column, 5e-9
    of itself."""
    from harness.sources.bench import record, write_log
    from harness.sources.measurement import measure

    folder = ROOT / "harness" / "data" / "logs" / "parallelogram_bench"
    sc = load_scenario(folder / "bench.toml")
    write_log(measure(record(sc), sc.measurement), list(sc.robot.actuated), tmp_path / "log.csv")
    made, shipped = pd.read_csv(tmp_path / "log.csv"), pd.read_csv(folder / "log.csv")
    assert list(made.columns) == list(shipped.columns) and made.shape == shipped.shape == (2401, 10)
    scale = np.max(np.abs(shipped.to_numpy()), axis=0)
    assert np.all(np.abs(made.to_numpy() - shipped.to_numpy()) <= 1e-9 * scale)


def test_an_unmeasured_actuated_channel_leaves_its_row_and_its_drive_terms_out_of_the_fit():
    """The crank's channel unmeasured: at 30 random consistent states of the arm with friction, the rows
    of the turret's and the shoulder's channels times the model's own parameters are G^T of Pinocchio's
    rnea plus every joint's drive terms (computed here from the model file), G's columns of those two
    actuated joints, to 1e-12 of the largest torque. The crank's own drive terms reach no measured
    channel (its row of G is the identity's: not measured, none of its four terms a base parameter); the
    passive joints' reach them through G (measured)."""
    from harness.identify.torque_id import drive_columns
    from harness.stages.log_model import log_model

    spec = load_spec(TRUTH)
    model = log_model(spec, spec.gravity_W, ("crank",))
    assert model.torque_joints == ["turret", "shoulder"]
    chain = model.chain
    m = closure.random_within_limits(chain, spec.limits, 30, seed=4)
    pm = model.pm
    tau = pinocchio_rnea(pm, m.q, m.qd, m.qdd) + viscous_coulomb(spec.frictions, m.qd, m.qdd)
    act = [spec.joint_names.index(j) for j in spec.actuated]
    G = m.G[:, :, [0, 1]]  # the turret's and the shoulder's columns
    assert np.array_equal(m.G[:, act, :], np.broadcast_to(np.eye(3), (30, 3, 3)))
    expected = np.einsum("nja,nj->na", G, tau)
    got = (model.rows(pm, m.q, m.qd, m.qdd) @ model.x_model).reshape(30, 2)
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12 * np.abs(expected).max())
    np.testing.assert_allclose(model.torques(pm, m.q, m.qd, m.qdd), expected, rtol=0,
                               atol=1e-12 * np.abs(expected).max())
    assert model.measured.tolist() == [j != "crank" for j in spec.joint_names]
    crank = set(range(*drive_columns(5, spec.joint_names.index("crank")).indices(14 * 5)))
    assert not crank & set(model.base.independent.tolist())


@pytest.fixture(scope="module")
def unmeasured_runs(exact, tmp_path_factory):
    """The exact log with the crank's channel absent, and with it reading 0 on every row, each declared
    unmeasured: their runs' exit status, results and folder."""
    folder = tmp_path_factory.mktemp("unmeasured_chain")
    log = pd.read_csv(exact[0] / "log.csv")
    write_frame(log.drop(columns=["tau3"]), folder / "absent.csv")
    write_frame(log.assign(tau3=0.0), folder / "dead.csv")
    runs = {}
    for name, tau in (("absent", '["tau1", "tau2"]'), ("dead", '"tau{j}"')):
        text = _scenario_text(folder / f"{name}.csv", 'unmeasured = ["crank"]', predicted=True)
        (folder / f"{name}.toml").write_text(text.replace('tau = "tau{j}"', f"tau = {tau}"))
        runs[name] = (*_run(folder / f"{name}.toml", folder / name), folder / name)
    return runs


@pytest.mark.slow  # two closed-chain log runs (2 s)
def test_a_closed_chain_log_without_a_channel_is_identified_from_the_others(unmeasured_runs, exact_run):
    """Declared unmeasured (the column absent, or reading 0: the same fit, to the bit), the fit through
    the turret's and the shoulder's rows of G^T Y predicts the truth's torques of those two channels on
    the span it never saw within 1e-4 (6.0e-5 measured; 2.7e-5 with every channel), the smoothing velocity
    0.02 rad/s within 5 % (every joint's but the crank's); the crank's friction and rotor inertia are the
    model's (none: they reach no measured channel), the passive joints' identified through G as with
    every channel (within 1 % of that fit's); no forward run, said; the report names the joint."""
    absent, dead = (unmeasured_runs[name] for name in ("absent", "dead"))
    assert absent[0] == dead[0] == 0
    li, other = absent[1]["log_identification"], dead[1]["log_identification"]
    assert li["least_squares"]["base"] == other["least_squares"]["base"]
    assert li["consistent"]["friction"] == other["consistent"]["friction"]
    assert li["torque_joints"] == ["turret", "shoulder"] and li["unmeasured"]["joints"] == ["crank"]
    truth = li["truth"]["validation_rel_error"]
    assert truth["least squares"] <= 1e-4 and truth["consistent"] <= 1e-4
    velocities = {v for j, v in li["friction_law"]["coulomb_velocity"].items() if j != "crank"}
    assert len(velocities) == 1 and abs(velocities.pop() / 0.02 - 1) <= 0.05
    model = load_spec(MODELS / "parallelogram.toml")
    crank = li["consistent"]["friction"]["crank"]
    own = model.joint("crank").friction
    assert (crank["armature"], crank["viscous"], crank["coulomb"], crank["offset"]) == (
        own.armature, own.viscous, own.coulomb, own.offset)
    every = exact_run[1]["log_identification"]["consistent"]["friction"]
    for joint in ("elbow", "rod"):
        assert abs(li["consistent"]["friction"][joint]["viscous"] / every[joint]["viscous"] - 1) <= 0.01, joint
    assert "crank" in li["prediction"]["note"] and not li["prediction"]["models"]
    assert "Unmeasured joints crank" in (absent[2] / "report.html").read_text()
