"""Ball joints (MuJoCo's `ball`): read as the three hinges about the body's axes, in that order
(harness/model/mjcf.py, harness/model/cardano.py), and judged against the engines' own ball joints.

Independent references: MuJoCo's own model of the file (its ball's quaternion, angular velocity and
acceleration, mj_inverse) and Pinocchio's own MJCF parse (its spherical joint, RNEA and CRBA), both
reached from the hinges' coordinates through R(theta) and D; the same file written with the three
hinges in one body, which MuJoCo applies in order; central finite differences of the ball's state.
Tolerances: 1e-12 relative between engines (round-off measured 4e-16 to 2e-15; 1e-9 would already
be a bug), 1e-15 m or rad between two readings of the same geometry (one rounding of an axis), 1e-7
for central differences at a step of 1e-4 (their error is about step^2 = 1e-8 of the size).
"""

from __future__ import annotations

import numpy as np
import pytest

from harness.base.tomlio import InputError
from harness.engines import pinocchio as pin_engine
from harness.engines.mujoco_file import file_inverse_dynamics
from harness.model import closure
from harness.model.cardano import ball_state
from harness.model.load import load_spec, spec_from_data
from harness.model.quaternion import derivative
from harness.runner.audit import audit

from .conftest import BUILTIN, DATA, MODELS
from .test_floating import DOG

GRAVITY_W = np.array([0.0, 0.0, -9.81])
DELTA = MODELS / "delta.toml"  # its platform on a ball joint of MuJoCo's own

PENDULUM = """<mujoco model="pendulum">
  <worldbody>
    <body name="upper" pos="0 0 1">
      <joint name="shoulder" type="hinge" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 0 0 -0.4" size="0.03" mass="1.5"/>
      <body name="lower" pos="0.01 0.02 -0.4" quat="0.9 0.1 0.3 0.2">
        JOINT
        <geom type="box" pos="0.05 0.1 -0.2" size="0.03 0.05 0.2" mass="0.7" quat="0.8 0.1 0.2 0.3"/>
      </body>
    </body>
  </worldbody>
  ACTUATOR
</mujoco>
"""
BALL = '<joint name="wrist" type="ball"/>'
HINGES = ('<joint name="wrist_x" type="hinge" axis="1 0 0"/><joint name="wrist_y" type="hinge" axis="0 1 0"/>'
          '<joint name="wrist_z" type="hinge" axis="0 0 1"/>')


def _pendulum(tmp_path, joint: str = BALL, actuator: str = "", name: str = "pendulum"):
    path = tmp_path / f"{name}.xml"
    path.write_text(PENDULUM.replace("JOINT", joint).replace("ACTUATOR", actuator))
    return path


def _read(path):
    return spec_from_data({"mjcf": {"file": path.name}}, path.with_suffix(".toml"))


def test_a_ball_joint_reads_as_the_hinges_of_its_bodys_axes_in_order(tmp_path):
    """The ball's reading is the file's with three hinges x, y, z in the ball's body (MuJoCo applies a
    body's hinges in order): the same joints, points, axes, bodies and carriages, and one note."""
    ball, hinges = _read(_pendulum(tmp_path)), _read(_pendulum(tmp_path, HINGES, name="hinges"))
    assert list(ball.joint_names) == list(hinges.joint_names) == ["shoulder", "wrist_x", "wrist_y", "wrist_z"]
    assert [b.name for b in ball.bodies] == [b.name for b in hinges.bodies] == [
        "upper", "lower[wrist_x]", "lower[wrist_y]", "lower"]
    for a, b in zip(ball.joints, hinges.joints, strict=True):
        assert (a.parent, a.child) == (b.parent, b.child)
        np.testing.assert_allclose(a.axis_W0, b.axis_W0, rtol=0, atol=1e-15)
        np.testing.assert_allclose(a.p_W0, b.p_W0, rtol=0, atol=1e-15)
    for a, b in zip(ball.bodies, hinges.bodies, strict=True):
        assert a.mass == b.mass
        np.testing.assert_allclose(a.p_W_com0, b.p_W_com0, rtol=0, atol=1e-15)
        np.testing.assert_allclose(a.R_WB0 @ a.I_B @ a.R_WB0.T, b.R_WB0 @ b.I_B @ b.R_WB0.T, rtol=0, atol=1e-15)
    assert len(ball.notes) == 1 and "ball joint 'wrist'" in ball.notes[0] and "wrist_y = +-pi/2" in ball.notes[0]


def test_mujocos_ball_and_pinocchios_spherical_joint_agree_with_the_hinges(tmp_path):
    """`harness audit` of the file: MuJoCo's own ball (quaternion, body-axes angular velocity) and
    Pinocchio's own spherical joint against the harness's three hinges at random states, torques and
    mass matrix; the massive bodies' regressor columns of equal rank (the carriages are the reading's)."""
    row = audit("pendulum", _pendulum(tmp_path))
    assert row.verdict == "agrees", row.reason
    assert row.torques_vs_mujoco_file <= 1e-12 and row.torques_vs_pinocchio <= 1e-12
    assert row.mass_matrix_vs_pinocchio <= 1e-12 and row.torques_vs_mujoco <= 1e-12
    assert row.massive_ranks[0] == row.massive_ranks[1] == row.base_parameters == row.pinocchio_regressor_rank


# test_floating.py's quadruped, its hip a ball joint
FLOATING = DOG.replace('<joint name="hip" type="hinge" axis="0 1 0"/>', '<joint name="hip" type="ball"/>')


def test_a_floating_robot_on_a_ball_joint_agrees_with_both_engines_own_free_bases(tmp_path):
    """A floating trunk carrying a leg on a ball joint: `harness audit` judges it free (harness/runner/
    audit_floating.py) against MuJoCo's own model of the file (free joint and ball quaternion) and
    Pinocchio's own parse (free-flyer, the ball as the harness's hinges), base rows and joint torques at
    random states with the base on SO(3), within 1e-12; the ball's three hinges are the joints on the base."""
    path = tmp_path / "dog.xml"
    path.write_text(FLOATING)
    assert {"hip_x", "hip_y", "hip_z"} <= set(_read(path).floating.joints)
    row = audit("dog", path)
    assert row.verdict == "agrees", row.reason
    assert all(value <= 1e-12 for value in row.floating.values()), row.floating
    from harness.identify import floating_id

    spec = _read(path)
    pm = pin_engine.build_model(spec, GRAVITY_W, floating=True)
    base = floating_id.structural_base(pm, spec.limits, "all")
    carriages = [k for k in range(1, pm.model.njoints) if pm.model.inertias[k].mass == 0.0]
    assert len(carriages) == 3  # the ball's two, the arm's cross: the base holds none of their known zeros
    assert not set(base.independent) & {10 * (k - 1) + c for k in carriages for c in range(10)}


def test_the_balls_quaternion_and_angular_velocity_are_the_derivatives_of_its_hinges_motion():
    """Along theta(t) = a sin(w t + phi): the quaternion's central difference is q' = q (0, omega_B) / 2
    (harness/model/quaternion.py, derivative), and omega_B's is the acceleration ball_state gives."""
    t, h = np.linspace(0.0, 2.0, 41), 1e-4
    a, w, phi = np.array([0.9, 1.2, -1.4]), np.array([1.3, 2.1, 0.7]), np.array([0.2, -0.4, 1.0])

    def state(times):
        x = w * times[:, None] + phi
        return ball_state(a * np.sin(x), a * w * np.cos(x), -a * w**2 * np.sin(x))

    quat, omega, omegadot, _ = state(t)
    (q_plus, w_plus, _, _), (q_minus, w_minus, _, _) = state(t + h), state(t - h)
    np.testing.assert_allclose((q_plus - q_minus) / (2 * h), derivative(quat, omega), rtol=0, atol=1e-7)
    np.testing.assert_allclose((w_plus - w_minus) / (2 * h), omegadot, rtol=0, atol=1e-7 * np.abs(omegadot).max())


@pytest.fixture(scope="module")
def delta():
    return closure.ClosedChain.of(load_spec(DELTA))


def test_the_built_in_delta_turns_its_platform_on_a_ball_and_the_graph_theory_model_reads_it(delta):
    """The built-in delta's platform turns on a ball joint of MuJoCo's own: read as three passive hinges
    (its loops and both engines' agreement through G: tests/test_closed_chains.py). At 50 random
    consistent states (motors within +-0.5 rad) the ball's middle hinge stays far from its lock; MuJoCo's
    own model of the file, its ball a quaternion, gives the tree's torques of the hinges within 1e-12 of
    the largest; and the graph-theory model, the ball an edge from the rod through two massless carriages
    (harness/papers/graph_theory_2021/topology.py), gives the actuated torques G^T tau within 1e-12."""
    from harness.papers.graph_theory_2021.model import make

    spec = delta.spec
    ball = [spec.joint_names.index(f"wrist_{s}") for s in "xyz"]
    assert set(ball) <= set(delta.passive) and any("ball joint 'wrist'" in note for note in spec.notes)
    m = closure.random_motion(delta, np.full(3, -0.5), np.full(3, 0.5), np.ones(3), np.ones(3), count=50, seed=5)
    assert np.max(np.abs(m.q[:, ball[1]])) < 1.0  # rad: cos > 0.5, D well conditioned
    pm = pin_engine.build_model(spec.rigid(), GRAVITY_W)
    rigid = pin_engine.rnea(pm, m.q, m.qd, m.qdd).tau
    own = file_inverse_dynamics(DELTA.with_suffix(".xml"), list(spec.joint_names), GRAVITY_W, m.q, m.qd, m.qdd)
    assert np.abs(own - rigid).max() <= 1e-12 * np.abs(rigid).max()
    actuated = closure.actuated_torques(m.G, pin_engine.rnea(pin_engine.build_model(spec, GRAVITY_W), m.q, m.qd,
                                                                m.qdd).tau)
    graph = make(spec, GRAVITY_W).inverse_dynamics(m.q, m.qd, m.qdd)
    assert np.abs(graph - actuated).max() <= 1e-12 * np.abs(actuated).max()


@pytest.mark.slow  # a ball-jointed arm's identification run (1.3 s)
def test_a_balls_carriages_have_no_parameters_to_identify(delta):
    """The two massless bodies between a ball's hinges carry nothing: their ten parameters each are known
    zeros, in no base parameter of the delta's G^T Y (harness/identify/torque_id.py), whose count is then
    the rank of the massive bodies' columns alone."""
    from harness.identify.torque_id import chain_regressor, structural_base

    spec = delta.spec
    pm = pin_engine.build_model(spec, GRAVITY_W)
    base = structural_base(pm, spec.limits, chain=delta)
    carriages = [k for k, j in enumerate(spec.joints) if spec.body(j.child).massless]
    assert [spec.joint_names[k] for k in carriages] == ["wrist_x", "wrist_y"]
    assert not set(base.independent) & {10 * k + c for k in carriages for c in range(10)}
    assert np.all(base.combination[:, np.isin(base.dependent, [10 * k + c for k in carriages for c in range(10)])] == 0)
    m = closure.random_motion(delta, np.full(3, -0.5), np.full(3, 0.5), np.ones(3), np.ones(3), count=60, seed=8)
    W = chain_regressor(pm, delta, m.q, m.qd, m.qdd, closed=True)
    norms = np.linalg.norm(W, axis=0)  # a column at round-off of the largest is no parameter's effect
    massive = [c for c in range(W.shape[1]) if c // 10 not in carriages and norms[c] > 1e-9 * norms.max()]
    sv = np.linalg.svd(W[:, massive] / norms[massive], compute_uv=False)
    assert len(base.independent) == np.sum(sv > 1e-8 * sv[0])  # torque_id's RANK_TOL


@pytest.mark.parametrize("joint, actuator, said", [
    ('<joint name="wrist" type="ball" damping="0.1"/>', "", "ball joint 'wrist' has damping"),
    (BALL, '<actuator><motor joint="wrist" gear="1 0 0"/></actuator>', "drives ball joint 'wrist'"),
    ('<joint name="lift" type="slide" axis="0 0 1"/>' + BALL, "", "has ball joint 'wrist' and other joints"),
    (BALL + '<geom type="sphere" size="0.05" mass="1"/></body><body name="other"><joint name="wrist_y"/>', "",
     "the file names another joint 'wrist_y'"),
], ids=["damping", "motor", "beside a slide", "names taken"])
def test_a_ball_joint_the_hinges_cannot_stand_for_is_refused_in_one_line(tmp_path, joint, actuator, said):
    path = _pendulum(tmp_path, joint, actuator)
    with pytest.raises(InputError) as err:
        _read(path)
    assert err.value.key == "mjcf.file" and said in str(err.value) and "\n" not in str(err.value)


@pytest.mark.parametrize("default", [False, True], ids=["stated", "from a default class"])
def test_pinocchios_parse_with_the_balls_as_hinges_is_the_harnesss_reading(tmp_path, default):
    """What `harness init`'s placeholder model and the floating audit read (harness/engines/pinocchio_file.py,
    `ball_hinges`): Pinocchio's parse of the file with its ball written as the three hinges (the ball's type
    stated, or given by the file's default class) has the harness's joints, in its order, and the same
    torques at random states (1e-12 of the largest)."""
    from harness.engines.pinocchio_file import parse

    path = _pendulum(tmp_path)
    if default:
        path.write_text(path.read_text().replace('<joint name="wrist" type="ball"/>', '<joint name="wrist"/>')
                        .replace("<worldbody>", '<default><joint type="ball"/></default><worldbody>'))
    model, notes = parse(path, ball_hinges=True)
    spec = _read(path)
    assert list(model.names)[1:] == list(spec.joint_names) and "1 ball joint(s)" in notes[0]
    model.gravity.linear = GRAVITY_W
    rng = np.random.default_rng(2)
    q, qd, qdd = (rng.uniform(-1.0, 1.0, (20, 4)) for _ in range(3))
    data = model.createData()
    theirs = np.array([pin_engine.pin.rnea(model, data, *x) for x in zip(q, qd, qdd, strict=True)])
    ours = pin_engine.rnea(pin_engine.build_model(spec.rigid(), GRAVITY_W), q, qd, qdd).tau
    assert np.abs(theirs - ours).max() <= 1e-12 * np.abs(ours).max()


def test_a_rank_the_massless_bodies_do_not_explain_is_a_disagreement(tmp_path, monkeypatch):
    """The audit's verdict on the regressor's rank (harness/runner/audit.py): a base count and Pinocchio's
    rank that differ (the file's hinges in one body: Pinocchio's nested bodies have columns the harness's
    massless carriages have not) pass only where their massive bodies' columns have one rank; given two,
    it disagrees."""
    import harness.runner.audit as audit_module

    monkeypatch.setattr(audit_module, "massive_ranks", lambda *args: (11, 12))
    row = audit("hinges", _pendulum(tmp_path, HINGES, name="hinges"))
    assert row.verdict == "disagrees" and "of the massive bodies' columns alone 11 and 12" in row.reason


def test_init_on_a_file_with_a_ball_joint_passes_and_judges_its_method_on_every_bodys_parameters(tmp_path):
    """`harness init` on the pendulum: its placeholder method (Pinocchio's regressor of the file with the ball
    as the harness's hinges) takes the carriages' parameters as unknowns too, so its base parameters are
    judged on the base of every body's ten (harness/stages/plugin_fits.py; on the base without the
    carriages' known zeros they were 1.18 off on another maker's arm), and all six gates pass."""
    import json

    from harness.cli import main

    assert main(["init", str(tmp_path / "p"), "--mjcf", str(_pendulum(tmp_path))]) == 0
    assert main(["run", str(tmp_path / "p" / "scenario.toml"), "--out", str(tmp_path / "o"), "--quiet"]) == 0
    gates = json.loads((tmp_path / "o" / "results.json").read_text())["gates"]
    assert len(gates) == 6 and all(g["passed"] for g in gates)


def test_a_balls_cone_judges_the_angle_of_its_rotation_and_bounds_the_motions_the_harness_makes(tmp_path):
    """A ball's `range` is a cone: the largest angle its rotation may reach (30 degrees here, MuJoCo's default
    unit). Read as RobotSpec.cones, it judges a motion by the angle of the ball's rotation (`motion.limits`,
    the independent reference scipy's Rotation of the intrinsic x-y-z angles, to 1e-12), and its hinges'
    limits are +-cone/3, inside which the rotation's angle cannot pass the cone (the angle of a product of
    rotations is at most the sum of theirs)."""
    from scipy.spatial.transform import Rotation

    from harness.model.states import random_states
    from harness.stages.limits import ratios

    spec = _read(_pendulum(tmp_path, '<joint name="wrist" type="ball" range="0 30"/>'))
    hinges, cone = spec.cones["wrist"]
    assert hinges == ("wrist_x", "wrist_y", "wrist_z") and cone == pytest.approx(np.pi / 6, abs=1e-15)
    assert all(spec.limits[h] == pytest.approx((-cone / 3, cone / 3), abs=1e-15) for h in hinges)
    assert any("a cone of 0.523599 rad" in note for note in spec.notes)
    k = [spec.joint_names.index(h) for h in hinges]
    n = len(spec.joints)
    q = random_states(np.full(n, -0.6), np.full(n, 0.6), np.ones(n), np.ones(n), 200, seed=4)[0]
    angle = Rotation.from_euler("XYZ", q[:, k]).magnitude()
    got = ratios(spec, q, np.zeros_like(q), np.zeros_like(q)).ratios["position"][k]
    np.testing.assert_allclose(got, angle.max() / cone, rtol=1e-12)
    assert got[0] > 1.0  # hinges at up to 0.6 rad turn the ball beyond its cone
    lo, hi = zip(*(spec.limits[h] for h in hinges), strict=True)
    inside = random_states(np.array(lo), np.array(hi), np.ones(3), np.ones(3), 2000, seed=5)[0]
    assert Rotation.from_euler("XYZ", inside).magnitude().max() <= cone


def test_the_constrained_models_integration_refuses_a_chain_of_hinges_in_one_line(tmp_path, capsys):
    """The graph-theory study's forward simulation reads each joint's angle off its two bodies: the ball
    arm's hinges turn massless carriages, so `forward_simulation = true` is bad input (exit 2, one line
    naming the key), not a traceback from inside the integration."""
    from harness.cli import main

    text = (DATA / "scenarios" / "ball_arm_sines.toml").read_text()
    text = text.replace('"../models/', f'"{DATA}/models/').replace('"../../../harness/data/', f'"{BUILTIN}/')
    study = "[studies.graph_theory_2021]"
    text = text.replace(study, f"{study[:-1]}.lagrange]\nforward_simulation = true")
    (tmp_path / "s.toml").write_text(text)
    assert main(["run", str(tmp_path / "s.toml"), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "lagrange.forward_simulation" in err[0] and "'elbow_x'" in err[0]
    assert not (tmp_path / "out").exists()


def test_a_passive_ball_at_its_charts_lock_is_refused_naming_its_hinges(delta):
    """The delta's platform ball, read as Cardano hinges, turned to its chart's lock (the middle hinge at
    pi/2): its first and last hinges turn about one axis through one point, their columns of the loops'
    Jacobian are equal, and the passive joints are not determined; the refusal names the three hinges. A
    thousandth of a radian from the lock the pseudo-inverse is made (the singular values' ratio ~1e-3 there,
    far above closure.RANK)."""
    from harness.model.loops import jacobian

    spec = delta.spec
    q = np.zeros((2, len(spec.joints)))
    q[1, spec.joint_names.index("wrist_y")] = np.pi / 2
    with pytest.raises(closure.ClosureError, match=r"at sample 1 .* the hinges wrist_x wrist_y wrist_z \(a ball"):
        closure.pinv_passive(delta, jacobian(spec, delta.loops, q), "sample")
    q[1, spec.joint_names.index("wrist_y")] = np.pi / 2 - 1e-3
    assert np.all(np.isfinite(closure.pinv_passive(delta, jacobian(spec, delta.loops, q), "sample")))
