"""A passive ball joint's chart turned to the motion (harness/model/charts.py).

Independent references: the tree's forward kinematics (the same ball in two charts puts every body in
the same place); the planar four-bar of hinges alone (harness/data/models/fourbar.xml), whose coupler
hinge is the ball's one rotation when the coupler hangs from the crank on a ball instead; a brute-force
search over random charts; rotations about one axis, which a chart with its first or last axis on it
holds at beta = 0. Tolerances: 1e-12 between two computations of one pose (round-off of a few
products of rotations), 1e-9 rad between two models of one mechanism each closed by Newton's method to
closure.CLOSED = 1e-12 of its size (0.35 m).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from harness.model import charts, closure
from harness.model.kinematics import forward_kinematics
from harness.model.load import load_spec, spec_from_data

from .conftest import BUILTIN, DATA, MODELS
from .test_closed_chain_log import _scenario_text

SPATIAL = DATA / "models" / "spatial_ballbar.toml"


def _crank(t: np.ndarray) -> np.ndarray:
    """The built-in fourbar scenario's crank motion (1.5 turns over 2 s), from q = 0."""
    return (1.5 * np.sin(2.0 * t) + 0.5 * np.cos(5.0 * t) - 0.5)[:, None]


@pytest.fixture(scope="module")
def ballbar():
    """The built-in planar four-bar with its coupler on a ball at the crank (tests/data/models/ballbar.xml):
    the same mechanism, the ball turning about y alone, its file chart's middle axis."""
    path = DATA / "models" / "ballbar.xml"
    return closure.ClosedChain.of(spec_from_data({"mjcf": {"file": path.name}}, path.with_suffix(".toml")))


def test_a_ball_in_another_chart_puts_every_body_where_it_was():
    """R_W = W R(theta) W^T: the spatial four-bar's ball at random angles, its hinges turned to a random
    chart W' and their angles read there (charts.angles), gives every body the same pose."""
    spec = load_spec(SPATIAL)
    (ball,) = charts.balls(spec)
    rng = np.random.default_rng(3)
    q = rng.uniform(-1.2, 1.2, (40, len(spec.joints)))
    W = ball.W @ Rotation.random(random_state=4).as_matrix()
    other = charts.turned(spec, ball, W)
    q_other = q.copy()
    q_other[:, [spec.joint_names.index(h) for h in ball.hinges]] = charts.angles(W, charts.rotations_W(spec, ball, q))
    zero = np.zeros_like(q)
    before = forward_kinematics(spec, q, zero, zero, velocities=False, accelerations=False)
    after = forward_kinematics(other, q_other, zero, zero, velocities=False, accelerations=False)
    massive = [k for k, b in enumerate(spec.bodies) if not b.massless]
    assert np.max(np.abs(after.R_WB[:, massive] - before.R_WB[:, massive])) < 1e-12
    assert np.max(np.abs(after.p_W_com[:, massive] - before.p_W_com[:, massive])) < 1e-12
    assert np.allclose(charts.rotations_W(other, charts.balls(other)[0], q_other), charts.rotations_W(spec, ball, q),
                       rtol=0, atol=1e-12)


def test_rotations_about_one_axis_get_a_chart_with_that_axis_first_or_last():
    """A ball turning about one axis k through a full turn: in a chart whose middle axis is k it meets
    the lock (beta = +-pi/2 at a quarter turn); the chart found holds beta = 0 throughout."""
    k = np.array([0.3, -0.8, 0.52])
    k /= np.linalg.norm(k)
    R_W = Rotation.from_rotvec(np.linspace(0.0, 2 * np.pi, 361)[:, None] * k).as_matrix()
    across = np.linalg.svd(k[None])[2][1:]
    W0 = np.column_stack([across[0], k, np.cross(across[0], k)])
    assert np.min(charts.cos_beta(W0, R_W)) < 1e-6
    W = charts.chart_for(R_W, W0)
    assert np.allclose(W.T @ W, np.eye(3), atol=1e-12) and np.linalg.det(W) > 0
    assert np.min(charts.cos_beta(W, R_W)) > 1 - 1e-9


def test_the_chart_found_is_no_worse_than_the_best_of_a_thousand_random_charts():
    """A wandering motion (the rotation vector sweeping 2.5 rad about a turning axis): the chart found
    keeps its rotations at least as far from the lock as the best of 1,000 random charts does."""
    t = np.linspace(0.0, 1.0, 300)[:, None]
    rotvec = 2.5 * np.sin(np.pi * t) * np.hstack([np.cos(2 * t), np.sin(3 * t), 0.5 + 0 * t])
    R_W = Rotation.from_rotvec(rotvec).as_matrix()
    W = charts.chart_for(R_W, np.eye(3))
    random = Rotation.random(1000, random_state=5).as_matrix()
    best_random = max(float(np.min(charts.cos_beta(C, R_W))) for C in random)
    assert float(np.min(charts.cos_beta(W, R_W))) >= best_random - 1e-9
    assert float(np.min(charts.cos_beta(W, R_W))) > float(np.min(charts.cos_beta(np.eye(3), R_W)))


def test_a_passive_ball_past_its_charts_lock_is_followed_in_a_turned_chart(ballbar):
    """The four-bar with a ball: in the file's chart the loops cannot be followed past the ball's lock
    (refused, with the stations followed before it); in the chart `fitted` turns it to, the whole motion
    is followed, and the ball's rotation is Ry of the hinge four-bar's coupler angle at every sample."""
    t = np.linspace(0.0, 2.0, 401)
    q_a = _crank(t)
    with pytest.raises(closure.ClosureError, match="singular configuration") as refused:
        closure.positions(ballbar, q_a, np.zeros(ballbar.n))
    assert 0 < len(refused.value.closed) < 401
    chain = charts.fitted(ballbar, q_a)
    (ball,) = charts.balls(chain.spec)
    assert not np.allclose(ball.W, np.eye(3)) and "it reaches the lock" in chain.spec.notes[-1]
    q = closure.positions(chain, q_a, np.zeros(chain.n))
    R_W = charts.rotations_W(chain.spec, ball, q)
    assert np.min(charts.cos_beta(ball.W, R_W)) > 1 - 1e-9
    hinges = closure.ClosedChain.of(load_spec(BUILTIN / "models" / "fourbar.toml"))
    coupler = closure.positions(hinges, q_a, np.zeros(hinges.n))[:, hinges.spec.joint_names.index("coupler")]
    Ry = Rotation.from_rotvec(coupler[:, None] * np.array([0.0, 1.0, 0.0])).as_matrix()
    assert np.max(np.abs(R_W - Ry)) < 1e-9


def test_a_ball_the_motion_keeps_far_from_its_lock_keeps_its_files_chart():
    """The built-in delta's platform ball, its motors on sines of 0.5 rad: the chain itself back."""
    delta = closure.ClosedChain.of(load_spec(MODELS / "delta.toml"))
    t = np.linspace(0.0, 1.0, 101)[:, None]
    q_a = 0.5 * np.sin(2 * np.pi * t + np.array([0.0, 2.0, 4.0])) - 0.5 * np.sin(np.array([0.0, 2.0, 4.0]))
    assert charts.fitted(delta, q_a) is delta


def test_the_spatial_four_bar_passes_the_closed_chain_gates_in_its_turned_chart(tmp_path, capsys):
    """The spatial four-bar (RSUR) driven through 1.5 turns: in the file's chart its ball comes within 11
    degrees of the lock (cos(beta) 0.19), where the recording's tracking gate fails (5.6e-7 rad against
    1e-7, measured); in the turned chart every closed-chain gate holds, and the note says so."""
    import json

    from harness.cli import main

    scenario = DATA / "scenarios" / "spatial_ballbar.toml"
    assert main(["run", str(scenario), "--out", str(tmp_path), "--quiet"]) == 0
    notes = json.loads((tmp_path / "results.json").read_text())["scenario"]["model_notes"]
    said = [n for n in notes if "turned to the chart" in n]
    assert len(said) == 1 and "reaches 79.2 degrees (cos(beta) = 0.187" in said[0]
    assert "turned to the chart" in capsys.readouterr().err


def test_a_ball_no_chart_frees_is_refused_naming_its_hinges(ballbar, monkeypatch):
    """Where no chart does better than the file's on what the loops gave (here: the search made to
    return the file's), the loops' refusal is said with the ball's hinges and how near their lock."""
    monkeypatch.setattr(charts, "chart_for", lambda R_W, W0: W0)
    with pytest.raises(closure.ClosureError, match=r"singular configuration.*knuckle_x, knuckle_y, knuckle_z at "
                                                   r"cos\(beta\) = 0\.0"):
        charts.fitted(ballbar, _crank(np.linspace(0.0, 2.0, 401)))


def test_a_closed_chains_log_reads_its_passive_ball_in_the_chart_of_its_training_span(tmp_path, monkeypatch):
    """The spatial four-bar's bench (MuJoCo, its crank's channels alone) read as a log: the ball's chart
    is turned to the training span's motion (its rows alone: the validation span's do not choose it), said
    in results.json, the truth read in the same chart, and on the span the fit never saw the logged torque
    is the truth's G^T rnea there to the loops' compliance (MuJoCo's soft loops: 1.5e-5 measured, 1e-4
    allowed)."""
    import json

    from harness.cli import main
    from harness.runner.scenario import load_scenario
    from harness.sources.bench import record, write_log

    bench = load_scenario(DATA / "scenarios" / "spatial_ballbar.toml")
    write_log(record(bench), list(bench.robot.actuated), tmp_path / "log.csv")
    measured = '[[gates]]\nmetric = "log_identification.truth.validation_rel_error.measured"\nlimit = 1e-4\n'
    (tmp_path / "s.toml").write_text(_scenario_text(tmp_path / "log.csv", extra=measured, model=SPATIAL,
                                                    truth=SPATIAL))
    rows = []
    fitted = charts.fitted
    monkeypatch.setattr(charts, "fitted", lambda chain, q_a: rows.append(len(q_a)) or fitted(chain, q_a))
    assert main(["run", str(tmp_path / "s.toml"), "--out", str(tmp_path / "out"), "--quiet"]) == 0
    results = json.loads((tmp_path / "out" / "results.json").read_text())
    assert sum("turned to the chart" in n for n in results["scenario"]["model_notes"]) == 1
    assert rows == [results["log_identification"]["spans"]["training"]["samples"]]


def test_only_a_frictionless_right_handed_triad_of_hinges_without_limits_of_its_own_is_a_ball():
    """Turning hinges that carry a drive term, limits of their own or a left-handed triad (whose
    W R(theta) W^T is not the hinges' rotation) would change the robot, not its coordinates: not balls."""
    import dataclasses

    from harness.model.friction import JointFriction

    spec = load_spec(SPATIAL)
    assert [b.hinges for b in charts.balls(spec)] == [("knuckle_x", "knuckle_y", "knuckle_z")]

    def changed(name, **fields):
        return dataclasses.replace(spec, joints=tuple(dataclasses.replace(j, **fields) if j.name == name else j
                                                      for j in spec.joints))

    assert charts.balls(changed("knuckle_y", friction=JointFriction(viscous=0.1))) == []
    assert charts.balls(changed("knuckle_z", axis_W0=-spec.joint("knuckle_z").axis_W0)) == []
    assert charts.balls(dataclasses.replace(spec, limits={**(spec.limits or {}), "knuckle_x": (-1.0, 1.0)})) == []
