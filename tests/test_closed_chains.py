"""Closed chains: loops read from MJCF and TOML, the passive joints solved at the three levels, G,
and the actuated torques of two engines projected through the loop.

Independent references: the four-bar's closure by circle intersection and the parallelogram's
geometry (its forearm keeps the crank's angle), central finite differences of the constraint
equations and of the motion, MuJoCo's own constraint residual and Jacobian (efc_pos, efc_J) of the
file as MuJoCo reads it, and a forward solve of the rigid KKT system from Pinocchio's mass matrix.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from harness.base.tomlio import InputError
from harness.engines import mujoco as mj_engine
from harness.engines import pinocchio as pin_engine
from harness.model import closure, loops
from harness.model.friction import JointFriction
from harness.model.load import load_spec, spec_from_data

from .conftest import MODELS

GRAVITY_W = np.array([0.0, 0.0, -9.81])
FOURBAR_XML = (MODELS / "fourbar.xml").read_text()


@pytest.fixture(scope="module")
def fourbar():
    return closure.ClosedChain.of(load_spec(MODELS / "fourbar.toml"))


@pytest.fixture(scope="module")
def parallelogram():
    return closure.ClosedChain.of(load_spec(MODELS / "parallelogram.toml"))


@pytest.fixture(scope="module")
def delta():
    """Three actuated hinges, fifteen passive ones, five ball-joint loops (MJCF connects)."""
    return closure.ClosedChain.of(load_spec(MODELS / "delta.toml"))


@pytest.fixture(scope="module")
def gripper():
    """Two joint couplings (MJCF joint equalities), one of them with an offset and a joint `ref`."""
    return closure.ClosedChain.of(load_spec(MODELS / "gripper.toml"))


def _mjcf(tmp_path, xml: str, extra: str = ""):
    (tmp_path / "m.xml").write_text(xml)
    return spec_from_data({"mjcf": {"file": "m.xml"}, **({"closed_chain": extra} if extra else {})},
                          tmp_path / "m.toml")


def _column(spec, name):
    return spec.joint_names.index(name)


# --- reading -----------------------------------------------------------------------------------------


def test_a_four_bar_with_two_subtrees_from_the_ground_is_read_whole(fourbar):
    """Pinocchio's own MJCF importer builds half of this model (the issue's finding); the harness
    builds Pinocchio's model from the spec, which holds every body."""
    spec = fourbar.spec
    assert sorted(b.name for b in spec.bodies) == ["coupler", "crank", "rocker"]
    assert spec.inner_joint("rocker").parent == "world" and spec.inner_joint("crank").parent == "world"
    (loop,) = spec.loops
    assert (loop.kind, loop.body_a, loop.body_b) == ("connect", "coupler", "rocker")
    np.testing.assert_allclose(loop.point_a_W0, [0.3, 0.0, 0.2], atol=1e-15)
    np.testing.assert_allclose(loop.point_b_W0, [0.3, 0.0, 0.2], atol=1e-15)
    assert spec.actuated == ("crank",)
    assert pin_engine.build_model(spec, GRAVITY_W).model.nq == 3


def test_the_parallelogram_arm_names_three_actuated_joints(parallelogram):
    assert parallelogram.spec.actuated == ("turret", "shoulder", "crank")
    assert sorted(parallelogram.spec.joint_names[i] for i in parallelogram.passive) == ["elbow", "rod"]


REFUSED = {
    # a joint equality is read as a coupling where its polynomial is linear (tests/test_couplings.py)
    "a nonlinear coupling": ('<connect name="coupler_rocker" body1="coupler" body2="rocker" anchor="0.24 0 0.12"/>',
                             '<joint name="geared" joint1="rocker" joint2="crank" polycoef="0 1 0.5 0 0"/>',
                             "equality constraint 'geared' couples its joints by a polynomial of degree above 1"),
    "a joint held by an equality": ('<connect name="coupler_rocker" body1="coupler" body2="rocker" '
                                    'anchor="0.24 0 0.12"/>', '<joint name="held" joint1="rocker"/>',
                                    "equality constraint 'held' holds joint 'rocker' at a constant"),
    "a coupling the loop contradicts": ('<motor name="crank" joint="crank"/>',
                                        '<motor name="crank" joint="crank"/></actuator><equality><joint name="geared" '
                                        'joint1="rocker" joint2="crank"/></equality><actuator>',
                                        "the actuated joints are not independent"),
    "a tendon loop": ('<connect name="coupler_rocker" body1="coupler" body2="rocker" anchor="0.24 0 0.12"/>',
                      '<tendon name="pinned" tendon1="loop_tendon"/>', "equality constraint 'pinned' is a tendon"),
    "inactive": ('anchor="0.24 0 0.12"/>', 'anchor="0.24 0 0.12" active="false"/>', "starts inactive"),
    "no actuator": ('<motor name="crank" joint="crank"/>', "", "actuated joints are not named"),
    "dependent actuators": ('<motor name="crank" joint="crank"/>',
                            '<motor name="crank" joint="crank"/><motor name="rocker" joint="rocker"/>',
                            "the actuated joints are not independent"),
    # MuJoCo places a body connect's second anchor where the first is at qpos0; two sites need not meet
    "a loop that cannot close": ('<connect name="coupler_rocker" body1="coupler" body2="rocker" anchor="0.24 0 0.12"/>',
                                 '<connect name="far" site1="tip" site2="far"/>', "the loops do not close"),
    # a body without a joint is merged into its parent: the loop would join the coupler to itself
    "a body joined to itself": ('body2="rocker"', 'body2="tip_body"', "joins body 'coupler' to itself"),
}


@pytest.mark.parametrize("case", REFUSED)
def test_what_cannot_be_read_is_refused_in_one_line(tmp_path, case):
    old, new, message = REFUSED[case]
    xml = FOURBAR_XML.replace(old, new)
    xml = xml.replace('<geom type="capsule" fromto="0 0 0 0.24 0 0.12" size="0.01" mass="1.2"/>',
                      '<geom type="capsule" fromto="0 0 0 0.24 0 0.12" size="0.01" mass="1.2"/><site name="tip" '
                      'pos="0.24 0 0.12"/><body name="tip_body" pos="0.24 0 0.12"><geom size="0.01" mass="0.1"/>'
                      '</body>')
    xml = xml.replace('<geom type="capsule" fromto="0 0 0 -0.05 0 0.2" size="0.01" mass="0.8"/>',
                      '<geom type="capsule" fromto="0 0 0 -0.05 0 0.2" size="0.01" mass="0.8"/>'
                      '<site name="far" pos="1.5 0 0.2"/>')
    if case == "a tendon loop":
        xml = xml.replace("<equality>", '<tendon><fixed name="loop_tendon"><joint joint="rocker" coef="1"/>'
                                        "</fixed></tendon><equality>")
    assert xml != FOURBAR_XML
    with pytest.raises(InputError) as err:
        _mjcf(tmp_path, xml)
    assert message in str(err.value) and "m.xml" in str(err.value) and "\n" not in err.value.one_line()


def test_a_closed_chain_s_actuated_joints_can_be_named_in_the_model_file(tmp_path):
    xml = FOURBAR_XML.replace('<motor name="crank" joint="crank"/>', "")
    spec = _mjcf(tmp_path, xml, {"actuated": ["rocker"]})
    assert spec.actuated == ("rocker",)
    with pytest.raises(InputError, match=r"closed_chain\.actuated"):
        _mjcf(tmp_path, xml, {"actuated": ["wrist"]})
    with pytest.raises(InputError, match="give them there or here"):
        _mjcf(tmp_path, FOURBAR_XML, {"loops": [{"type": "connect", "body1": "coupler", "body2": "rocker",
                                                 "point": [0.3, 0.0, 0.2]}]})


def test_a_tree_from_toml_closes_with_its_stated_loops(tmp_path, fourbar):
    """The four-bar as a TOML tree (bodies and joints written out) with [[closed_chain.loops]]: the
    same loop as the MJCF file's, the same passive joints along a turn of the crank."""
    spec = fourbar.spec
    bodies = [{"name": b.name, "shape": "explicit", "mass": b.mass, "com": b.p_W_com0.tolist(),
               "e1": b.R_WB0[:, 0].tolist(), "e2": b.R_WB0[:, 1].tolist(), "inertia": b.principal_inertia.tolist()}
              for b in spec.bodies]
    joints = [{"name": j.name, "type": j.type, "parent": j.parent, "child": j.child, "point": j.p_W0.tolist(),
               "axis": j.axis_W0.tolist()} for j in spec.joints]
    data = {"model": {"name": "fourbar_toml"}, "bodies": bodies, "joints": joints,
            "closed_chain": {"actuated": ["crank"], "loops": [{"name": "C", "type": "connect", "body1": "coupler",
                                                                "body2": "rocker", "point": [0.3, 0.0, 0.2]}]}}
    toml_spec = spec_from_data(data, tmp_path / "fourbar.toml")
    chain = closure.ClosedChain.of(toml_spec)
    q_a = np.linspace(0.0, 2 * np.pi, 200)[:, None]
    ours = closure.positions(chain, q_a, np.zeros(3))
    theirs = closure.positions(fourbar, q_a, np.zeros(3))
    order = [toml_spec.joint_names.index(n) for n in spec.joint_names]
    np.testing.assert_allclose(ours[:, order], theirs, atol=1e-10)
    with pytest.raises(InputError, match=r"closed_chain\.loops"):
        spec_from_data({**data, "closed_chain": {"actuated": ["crank"], "loops": [
            {"type": "connect", "body1": "coupler", "body2": "ghost", "point": [0, 0, 0]}]}}, tmp_path / "f.toml")


def test_stations_closed_in_blocks_are_those_followed_one_at_a_time(parallelogram, monkeypatch):
    """The continuation's blocks (CONTINUATION_BLOCK stations closed by one Newton's method, each predicted
    from the last one kept) give the configurations of stations followed one at a time, to 1e-12 of the
    mechanism's size (both closed to CLOSED = 1e-12), along 6 s of three actuated joints' sines."""
    t = np.linspace(0.0, 6.0, 1200)
    q_a = np.stack([0.8 * np.sin(0.9 * t), 0.5 * np.sin(1.3 * t), 0.4 * np.sin(1.7 * t)], axis=1)
    blocks = closure.positions(parallelogram, q_a, np.zeros(5))
    monkeypatch.setattr(closure, "CONTINUATION_BLOCK", 1)
    np.testing.assert_allclose(blocks, closure.positions(parallelogram, q_a, np.zeros(5)), rtol=0,
                               atol=1e-12 * parallelogram.size)


def test_a_block_whose_newton_moves_the_passive_joints_beyond_its_travel_is_not_kept(fourbar):
    """The four-bar's crank in eight steps from its drawn configuration: 0.05 rad apart (the continuation's
    step), the block is kept; 0.2 rad apart, every station still closes, with no fold between neighbours
    (measured), but Newton moves the rocker from G's prediction by more than the block's travel (0.33 rad
    at the fifth station, whose steps allow 0.25): the block is refused (its stations are then followed
    one at a time)."""
    q, J = closure.close_with_jacobian(fourbar, np.zeros(fourbar.n), "the start", numbered=False)
    near, far = (np.arange(1, 9)[:, None] * step for step in (closure.CONTINUATION_STEP, 0.2))
    kept = closure._block(fourbar, q, J, near)
    assert kept is not None and np.allclose(kept[0][:, list(fourbar.actuated)], near, rtol=0, atol=1e-15)
    assert closure._block(fourbar, q, J, far) is None


# --- the three levels and G ----------------------------------------------------------------------------


def test_the_four_bar_s_passive_joints_are_its_circle_intersection(fourbar):
    """Crank angle theta about y: B = A + R_y(theta) (B0 - A); C is where the circles about B (radius
    |BC|) and about D (radius |DC|) meet, on the branch the mechanism is drawn in; the rocker's angle
    is the turn of DC from its drawn direction."""
    spec = fourbar.spec
    A, B0, C0, D = (np.array(p) for p in ([0, 0, 0], [0.06, 0, 0.08], [0.3, 0, 0.2], [0.35, 0, 0]))
    theta = np.linspace(0.0, 2 * np.pi, 721)
    q = closure.positions(fourbar, theta[:, None], np.zeros(3))
    xz = lambda v: v[..., [0, 2]]  # noqa: E731
    turn = lambda a: np.array([[np.cos(a), np.sin(a)], [-np.sin(a), np.cos(a)]])  # R_y in (x, z)  # noqa: E731
    B = xz(A) + np.einsum("nij,j->ni", turn(theta).transpose(2, 0, 1), xz(B0 - A))
    r1, r2 = np.linalg.norm(C0 - B0), np.linalg.norm(C0 - D)
    d = np.linalg.norm(xz(D) - B, axis=1)
    a = (r1**2 - r2**2 + d**2) / (2 * d)
    h = np.sqrt(r1**2 - a**2)
    u = (xz(D) - B) / d[:, None]
    n = np.stack([-u[:, 1], u[:, 0]], axis=1)
    candidates = [B + a[:, None] * u + s * h[:, None] * n for s in (1.0, -1.0)]
    drawn = np.argmin([np.linalg.norm(c[0] - xz(C0)) for c in candidates])
    C = candidates[drawn]
    start, now = xz(C0 - D), C - xz(D)
    # a turn about +y takes (x, z) to (x cos + z sin, -x sin + z cos): angle = atan2 of the cross and dot
    rocker = np.arctan2(start[0] * now[:, 1] - start[1] * now[:, 0], start @ now.T) * -1.0
    np.testing.assert_allclose(np.unwrap(q[:, _column(spec, "rocker")]), np.unwrap(rocker), atol=1e-11)


def test_the_delta_s_parallelograms_keep_its_platform_level_and_centred_under_its_arms(delta):
    """Clavel's delta: at 50 random consistent states (the motors within +-0.5 rad, the fifteen passive
    joints from the five loops) the platform keeps its orientation (the parallelograms: its rotation
    from q = 0 under 1e-9 rad, the closure's tolerance) and each leg's rods stay parallel; its centre is
    where the three spheres of radius L_f about the elbows' offset points meet (an independent
    construction: trilateration), to 1e-9 m."""
    from harness.model.kinematics import forward_kinematics

    spec = delta.spec
    rng = np.random.default_rng(3)
    q_a = rng.uniform(-0.5, 0.5, (50, 3))
    q, ok = closure.reach(delta, q_a, np.zeros(delta.n))
    assert ok.all()
    kin = forward_kinematics(spec, q, np.zeros_like(q), np.zeros_like(q))
    R = kin.R_WB[:, kin.body_index("platform")]
    R0 = forward_kinematics(spec, np.zeros((1, delta.n)), np.zeros((1, delta.n)),
                            np.zeros((1, delta.n))).R_WB[0, kin.body_index("platform")]
    assert np.abs(R - R0).max() <= 1e-9
    R_b, L_a, R_p, L_f = 0.2, 0.3, 0.05, 0.8  # delta.xml's geometry
    C0 = np.array([0.0, 0.0, -np.sqrt(L_f ** 2 - (R_b + L_a - R_p) ** 2)])  # the platform's centre at q = 0
    com0, com = spec.body("platform").p_W_com0, kin.p_W_com[:, kin.body_index("platform")]
    centre = com + R @ (R0.T @ (C0 - com0))  # carried with the platform
    for i in range(3):
        u = np.array([np.cos(2 * np.pi * i / 3), np.sin(2 * np.pi * i / 3), 0.0])
        th = q[:, spec.joint_names.index(f"motor{i}")][:, None]
        # the motor turns its arm about the tangent (right hand): u -> u cos th - e_z sin th; the
        # parallelogram's mid-line, L_f long, joins the elbow to the platform's point R_p u from its centre
        elbow = R_b * u + L_a * (np.cos(th) * u - np.sin(th) * np.array([0.0, 0.0, 1.0]))
        assert np.abs(np.linalg.norm(centre + R_p * u - elbow, axis=1) - L_f).max() <= 1e-9


def test_the_parallelogram_s_forearm_keeps_the_crank_s_angle(parallelogram):
    spec = parallelogram.spec
    rng = np.random.default_rng(3)
    q_a = np.cumsum(rng.uniform(-0.01, 0.01, (400, 3)), axis=0)  # a wandering motion within +-0.6 rad
    q = closure.positions(parallelogram, q_a, np.zeros(5))
    c = {n: q[:, _column(spec, n)] for n in spec.joint_names}
    np.testing.assert_allclose(c["elbow"], c["crank"] - c["shoulder"], atol=1e-12)
    np.testing.assert_allclose(c["rod"], c["shoulder"] - c["crank"], atol=1e-12)


@pytest.mark.parametrize("name", ["fourbar", "parallelogram", "gripper", "delta"])
def test_the_constraint_jacobian_and_bias_are_the_derivatives_of_phi(name, request):
    """J against central differences of Phi (step 1e-6: error ~ h^2 |Phi'''| ~ 1e-12, round-off
    ~ eps |x| / h ~ 1e-10: tolerance 1e-8); b against central differences of J q' along the
    direction q' (the same orders)."""
    chain = request.getfixturevalue(name)
    spec, n = chain.spec, chain.n
    rng = np.random.default_rng(5)
    q = rng.uniform(-0.5, 0.5, (6, n))
    qd = rng.uniform(-2.0, 2.0, (6, n))
    J = loops.jacobian(spec, chain.loops, q)
    h = 1e-6
    for j in range(n):
        e = np.zeros(n)
        e[j] = h
        fd = (loops.residual(spec, chain.loops, q + e) - loops.residual(spec, chain.loops, q - e)) / (2 * h)
        np.testing.assert_allclose(J[:, :, j], fd, atol=1e-8)
    Jd = (loops.jacobian(spec, chain.loops, q + h * qd) - loops.jacobian(spec, chain.loops, q - h * qd)) / (2 * h)
    np.testing.assert_allclose(loops.bias(spec, chain.loops, q, qd), (Jd @ qd[:, :, None])[:, :, 0], atol=1e-7)


@pytest.mark.parametrize("name", ["fourbar", "parallelogram", "gripper", "delta"])
def test_velocity_and_acceleration_levels_are_the_motion_s_derivatives(name, request):
    """q' = G q'_a and q'' = G q''_a + g against central differences of the solved positions along
    a smooth actuated motion, at 200 instants over 2 s (step 1e-4 s: truncation ~ h^2 |q'''| ~ 1e-7)."""
    chain = request.getfixturevalue(name)
    h = 1e-4
    t = (np.linspace(0.01, 1.99, 200)[:, None] + np.array([-h, 0.0, h])).ravel()  # each instant, its neighbours
    na = len(chain.actuated)
    w = np.arange(1, na + 1) * 1.3
    q_a = 0.4 * np.sin(np.outer(t, w))
    qd_a = 0.4 * w * np.cos(np.outer(t, w))
    qdd_a = -0.4 * w**2 * np.sin(np.outer(t, w))
    q = closure.positions(chain, q_a, np.zeros(chain.n))
    m = closure.motion(chain, q, qd_a, qdd_a)
    np.testing.assert_allclose((q[2::3] - q[0::3]) / (2 * h), m.qd[1::3], atol=1e-6)
    np.testing.assert_allclose((m.qd[2::3] - m.qd[0::3]) / (2 * h), m.qdd[1::3], atol=1e-5)
    assert np.abs(loops.residual(chain.spec, chain.loops, q)).max() <= closure.CLOSED * chain.size


@pytest.mark.parametrize("name", ["fourbar", "parallelogram", "gripper", "delta"])
def test_g_lies_in_mujoco_s_constraint_null_space(name, request):
    """MuJoCo's own reading of the file: its equality rows' residual efc_pos is zero at our closed
    configurations, and its constraint Jacobian efc_J annihilates G, to 1e-12 of their sizes."""
    chain = request.getfixturevalue(name)
    model = mujoco.MjModel.from_xml_path(str(chain.spec.mjcf))
    data = mujoco.MjData(model)
    m = closure.random_motion(chain, *_bounds(chain), count=40, seed=2)
    for k in range(len(m.q)):
        T = _file_configuration(model, data, chain.spec.joint_names, m.q[k])
        mujoco.mj_forward(model, data)
        rows = data.efc_type == mujoco.mjtConstraint.mjCNSTR_EQUALITY
        J = data.efc_J.reshape(data.nefc, model.nv)[rows] @ T
        assert np.abs(data.efc_pos[rows]).max() <= 1e-12 * chain.size
        assert np.abs(J @ m.G[k]).max() <= 1e-12 * np.linalg.norm(J) * np.linalg.norm(m.G[k])


def _file_configuration(model, data, joints, q) -> np.ndarray:
    """MuJoCo's qpos of the file's model set from the harness's q (n,) of `joints`, and T (nv, n), its
    velocities from the harness's (v = T q'): a hinge its own, a ball joint from its three hinges
    `<ball>_x .. _z` (harness/model/cardano.py: its quaternion and D)."""
    from harness.model.cardano import ball_state

    T = np.zeros((model.nv, len(joints)))
    for i in range(model.njnt):
        name, adr, dof = model.joint(i).name, model.jnt_qposadr[i], model.jnt_dofadr[i]
        if model.jnt_type[i] == mujoco.mjtJoint.mjJNT_BALL:
            ks = [joints.index(f"{name}_{s}") for s in "xyz"]
            quat, _, _, D = ball_state(q[None, ks], np.zeros((1, 3)), np.zeros((1, 3)))
            data.qpos[adr:adr + 4], T[dof:dof + 3, ks] = quat[0], D[0]
        else:
            data.qpos[adr], T[dof, joints.index(name)] = q[joints.index(name)], 1.0
    return T


def _bounds(chain):
    limits = chain.spec.limits or {}
    names = [chain.spec.joint_names[i] for i in chain.actuated]
    lo = np.array([limits.get(n, (-np.pi, np.pi))[0] for n in names])
    hi = np.array([limits.get(n, (-np.pi, np.pi))[1] for n in names])
    return lo, hi, np.full(len(names), 2.0), np.full(len(names), 5.0)


WELDS = ['<weld name="w" body1="coupler" body2="pin"/>',
         '<weld name="w" body1="pin" body2="coupler" anchor="0.01 0.02 0.03"/>',
         '<weld name="w" body1="coupler" body2="pin" relpose="0.24 0 0.12 1 0 0 0"/>']


@pytest.mark.parametrize("weld", WELDS)
def test_a_weld_closes_as_mujoco_reads_it(tmp_path, weld):
    """A four-bar whose coupler is welded to a pin on the rocker (the loop's last joint is the pin's):
    MuJoCo's residual of the file's weld is zero at the configurations solved from the harness's
    reading of it, in each of MJCF's ways of stating a weld."""
    xml = FOURBAR_XML.replace('<connect name="coupler_rocker" body1="coupler" body2="rocker" anchor="0.24 0 0.12"/>',
                              weld)
    xml = xml.replace('<body name="coupler" pos="0.06 0 0.08">',
                      '<body name="coupler" pos="0.06 0 0.08" euler="0 0.3 0">')
    xml = xml.replace('<geom type="capsule" fromto="0 0 0 -0.05 0 0.2" size="0.01" mass="0.8"/>',
                      '<geom type="capsule" fromto="0 0 0 -0.05 0 0.2" size="0.01" mass="0.8"/>'
                      '<body name="pin" pos="-0.05 0 0.2" euler="0 0.4 0"><joint name="pin" type="hinge" axis="0 1 0"/>'
                      '<geom type="sphere" size="0.02" mass="0.1"/></body>')
    spec = _mjcf(tmp_path, xml)
    (loop,) = spec.loops
    assert loop.kind == "weld"
    chain = closure.ClosedChain.of(spec)
    q = closure.positions(chain, np.linspace(0.0, 6.0, 60)[:, None], np.zeros(4))
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    jid = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, j) for j in spec.joint_names]
    for k in range(0, 60, 6):
        data.qpos[model.jnt_qposadr[jid]] = q[k]
        mujoco.mj_forward(model, data)
        assert np.abs(data.efc_pos[data.efc_type == mujoco.mjtConstraint.mjCNSTR_EQUALITY]).max() <= 1e-12


# --- torques -------------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["fourbar", "parallelogram", "gripper",
                                  pytest.param("delta", marks=pytest.mark.slow)])  # the delta: 1.2 s of loop solves
def test_two_engines_agree_on_the_actuated_torques_and_raw_torques_are_not_them(name, request):
    """G^T rnea (Pinocchio) and G^T qfrc_inverse (MuJoCo, with the loop as an equality constraint) at
    200 random consistent states: to 1e-9 of the largest (round-off is ~1e-15; above 1e-9 is a bug).
    The engines' raw actuated entries are not the chain's torques (they are the tree's)."""
    chain = request.getfixturevalue(name)
    m = closure.random_motion(chain, *_bounds(chain), count=200, seed=11)
    tau_pin = pin_engine.rnea(pin_engine.build_model(chain.spec, GRAVITY_W), m.q, m.qd, m.qdd).tau
    tau_mj = mj_engine.inverse_dynamics(chain.spec, GRAVITY_W, m.q, m.qd, m.qdd)
    a_pin, a_mj = closure.actuated_torques(m.G, tau_pin), closure.actuated_torques(m.G, tau_mj)
    scale = np.abs(a_pin).max()
    assert np.abs(a_pin - a_mj).max() <= 1e-9 * scale
    raw = tau_mj[:, list(chain.actuated)]
    assert np.abs(raw - a_pin).max() >= 0.1 * scale


@pytest.mark.parametrize("name", ["fourbar", "parallelogram", "gripper", "delta"])
def test_the_actuated_torques_drive_the_rigid_chain_through_its_motion(name, request):
    """Forward check: with Pinocchio's M(q) and h(q, q') (RNEA at q'' = 0), the rigid KKT system
    [M  -J^T; J  0] [q''; lambda] = [S^T tau_a - h; -b] under tau_a = G^T tau returns the motion's q''
    (to 1e-9 of its size), and lambda the loop forces `multipliers` gives (least norm: a planar
    loop's out-of-plane row carries none)."""
    chain = request.getfixturevalue(name)
    m = closure.random_motion(chain, *_bounds(chain), count=50, seed=4)
    pm = pin_engine.build_model(chain.spec, GRAVITY_W)
    tau = pin_engine.rnea(pm, m.q, m.qd, m.qdd).tau
    h = pin_engine.rnea(pm, m.q, m.qd, np.zeros_like(m.qdd)).tau
    M = pin_engine.crba(pm, m.q)
    tau_a = closure.actuated_torques(m.G, tau)
    lam = closure.multipliers(chain, m.J, tau, tau_a)
    b = loops.bias(chain.spec, chain.loops, m.q, m.qd)
    n, rows = chain.n, m.J.shape[1]
    for k in range(len(m.q)):
        K = np.block([[M[k], -m.J[k].T], [m.J[k], np.zeros((rows, rows))]])
        rhs = np.concatenate([-h[k], -b[k]])
        rhs[list(chain.actuated)] += tau_a[k]
        sol = np.linalg.lstsq(K, rhs, rcond=None)[0]
        np.testing.assert_allclose(sol[:n], m.qdd[k], atol=1e-9 * max(1.0, np.abs(m.qdd[k]).max()))
        np.testing.assert_allclose(m.J[k].T @ sol[n:], m.J[k].T @ lam[k], atol=1e-9 * np.abs(tau[k]).max())


# --- scenarios -----------------------------------------------------------------------------------------

SCENARIOS = MODELS.parent / "scenarios"


def _scenario(tmp_path, name: str, edit=lambda text: text) -> object:
    from harness.runner.scenario import load_scenario

    text = edit((SCENARIOS / f"{name}.toml").read_text()).replace('"../models/', f'"{MODELS}/')
    text = text.replace('gate_sets = ["gates/', f'gate_sets = ["{SCENARIOS}/gates/')
    (tmp_path / f"{name}.toml").write_text(text)
    return load_scenario(tmp_path / f"{name}.toml")


SCENARIO_REFUSALS = {
    "a passive joint's motion": ("fourbar", lambda t: t + '\n[motion.rocker]\ntype = "locked"\n',
                                 "motion.rocker", "is passive"),
    "an identification method": ("fourbar", lambda t: t + '\n[identification]\nname = "m"\nplugin = "x"\n',
                                 "identification", "closed chain"),
    # crank - shoulder = pi / 2 at t = 0: the crank along the upper arm, J_p singular
    "a motion at the parallelogram's fold": (
        "parallelogram", lambda t: t.replace("[motion.crank]\ntype = \"sinusoids\"\noffset = 0.0",
                                             "[motion.crank]\ntype = \"sinusoids\"\noffset = 1.7707963267948966"),
        "motion", "cannot be followed"),
    # crank - shoulder passes pi / 2 between two samples: the parallelogram folds flat on the way
    "a motion through the parallelogram's fold": (
        "parallelogram", lambda t: t.replace("[motion.crank]\ntype = \"sinusoids\"\noffset = 0.0\nsin = [[0.3, 2.7]]",
                                             "[motion.crank]\ntype = \"sinusoids\"\noffset = 1.5\nsin = [[0.5, 2.7]]"),
        "motion", "crosses a singular configuration"),
}


@pytest.mark.parametrize("case", SCENARIO_REFUSALS)
def test_a_closed_chain_scenario_refuses_what_it_cannot_run(tmp_path, case):
    name, edit, key, message = SCENARIO_REFUSALS[case]
    with pytest.raises(InputError) as err:
        _scenario(tmp_path, name, edit)
    assert err.value.key == key and message in str(err.value)


class ProjectedTree:
    """A user's closed-chain model: Pinocchio's RNEA of the tree projected by G (harness/model/closure.py),
    for the spec it is given (the robot's own, or one with a body 1 % heavier)."""

    def __init__(self, spec):
        self.chain = closure.ClosedChain.of(spec)
        self.pm = pin_engine.build_model(spec, GRAVITY_W)
        self.joint_names = list(reversed(spec.joint_names))  # its own column order
        self.actuated_joints = list(reversed(spec.actuated))
        self._order = [spec.joint_names.index(j) for j in self.joint_names]

    def inverse_dynamics(self, q, qd, qdd):
        back = np.argsort(self._order)
        q, qd, qdd = q[:, back], qd[:, back], qdd[:, back]
        tau = pin_engine.rnea(self.pm, q, qd, qdd).tau
        tau_a = closure.actuated_torques(closure.projection(self.chain, q, closed=False), tau)
        names = list(self.chain.spec.actuated)
        return tau_a[:, [names.index(a) for a in self.actuated_joints]]


@pytest.mark.slow
def test_a_users_closed_chain_model_is_judged_on_its_actuated_torques(tmp_path):
    """The four-bar scenario with two models under test: the projected tree of the robot itself agrees
    with both engines along the motion and at the random states to 1e-9; the same with the rocker 1 %
    heavier is off by more than 1e-4 of the crank's load (the rocker's weight alone is 8 N against a
    largest crank torque of a few N m) and fails its gates. The run's recording reads back with its
    loop gaps and loop wrenches; the tree's raw torques are not the chain's."""
    import dataclasses

    import harness
    from harness.base.series import read_csv

    sc = _scenario(tmp_path, "fourbar")
    robot = sc.robot
    assert np.array_equal(sc.gravity_W, GRAVITY_W)  # the MJCF file's, which the models are built with
    heavy = dataclasses.replace(robot, bodies=tuple(dataclasses.replace(b, mass=b.mass * 1.01) if b.name == "rocker"
                                                    else b for b in robot.bodies))
    result = harness.run(sc, models={"exact": ProjectedTree(robot), "heavy": ProjectedTree(heavy)})
    tq = result.results["torques"]
    for ref in ("pinocchio", "mujoco"):
        assert tq[f"exact_vs_{ref}"]["max_rel_error"] <= 1e-9
        assert tq[f"heavy_vs_{ref}"]["max_rel_error"] >= 1e-4
    assert tq["exact_random_vs_pinocchio"]["max_rel_error"] <= 1e-9
    assert tq["exact_random_vs_pinocchio"]["states"] == 200
    assert tq["heavy_random_vs_pinocchio"]["max_rel_error"] >= 1e-4
    failed = {g.name for g in result.gates if not g.passed}
    assert failed and all("heavy" in name for name in failed)
    cc = tq["closed_chain"]
    # forward: the exact model's run meets the built-in gate (1e-6 of a joint's range), the heavy one's not
    assert cc["forward"]["exact"]["max_rel_range"] <= 1e-6 < cc["forward"]["heavy"]["max_rel_range"]
    assert cc["raw_tree_vs_actuated_max_rel_error"] >= 0.1
    assert cc["passive_torque_with_loop_forces_max"] <= 1e-9 * max(tq["load_scale"].values())
    out = tmp_path / "out"
    from harness.cli import main

    assert main(["run", str(tmp_path / "fourbar.toml"), "--out", str(out), "--quiet"]) == 0
    rec = read_csv(out / "recording.csv")
    assert rec.loops == ("coupler_rocker",)
    assert np.max(rec.loop_gap) == json_of(out)["torques"]["closed_chain"]["loop_gap_max"]
    assert rec.loop_F_W.shape == (len(rec.t), 3, 3) and np.abs(rec.loop_F_W).max() > 0
    # the first seed's multipliers against MuJoCo's loop force on the coupler (body a of the only loop),
    # where the loop determines it: in the plane (x, z); out of it (y) the rigid loop leaves it open
    # (graph: least norm, 0) and MuJoCo's soft constraint puts a small force there
    from harness.papers.graph_theory_2021.closed import closed_chain_inverse
    from harness.papers.graph_theory_2021.dynamics import build_graph_model

    cols = [rec.joint_index(j) for j in robot.joint_names]
    graph = closed_chain_inverse(robot, build_graph_model(robot, GRAVITY_W), rec.q[:, cols], rec.qd[:, cols],
                                 rec.qdd[:, cols])
    theirs = rec.loop_F_W[:, rec.bodies.index("coupler")]
    in_plane = [0, 2]
    assert np.abs(graph.lam[:, in_plane] - theirs[:, in_plane]).max() <= 1e-9 * np.abs(theirs).max()
    assert np.all(graph.lam[:, 1] == 0.0) or np.abs(graph.lam[:, 1]).max() <= 1e-12 * np.abs(theirs).max()


@pytest.mark.slow
def test_a_bench_without_rk4_stage_torques_skips_the_forward_comparison_and_says_why(tmp_path):
    """With the bench integrating by Euler there are no RK4 stage torques to drive both runs with: the
    forward comparison of each model is skipped with the reason, and its gate is reported as a skip,
    neither passed nor failed."""
    import harness

    sc = _scenario(tmp_path, "fourbar", lambda t: t.replace('integrator = "RK4"', 'integrator = "Euler"'))
    result = harness.run(sc)
    forward = result.results["torques"]["closed_chain"]["forward"]
    assert list(forward) == ["graph"] and "not RK4" in forward["graph"]["skipped"]
    (gate,) = [g for g in result.gates if g.metric == "torques.closed_chain.forward.graph.max_rel_range"]
    assert gate.skipped and "not RK4" in gate.reason


def json_of(folder):
    import json

    return json.loads((folder / "results.json").read_text())


# --- identification ------------------------------------------------------------------------------------



@pytest.mark.slow
def test_friction_on_a_closed_chain_is_simulated_judged_and_identified(tmp_path):
    """The four-bar with rotor inertia and friction on its crank and friction on its passive rocker: MuJoCo
    applies the laws on every joint and the drive's computed torque, projected by G, compensates them;
    the engines' actuated torques agree to 1e-9 (the passive joint's friction reaching the crank through
    G^T), and so does the graph-theory model (the rocker's friction in its loop equations) along the
    motion and at random states; Pinocchio's rigid loops carry the laws (MuJoCo's run against them within
    1e-6 of the range: 2.9e-8 measured; 6.8e-4 without friction, which damps the open-loop run), the graph
    model's forward run meets the scenario's gate against them, and [torque_identification] with
    friction finds each joint's viscous and Coulomb coefficients through G^T Y within 2e-3 (1.9e-4 to
    3.8e-4 measured: the soft loops' reference acceleration, docs/closed_chains.md), the passive rocker's
    as well as the crank's."""
    import dataclasses

    import tomli_w

    import harness

    laws = {j: {k: v for k, v in dataclasses.asdict(f).items() if v} for j, f in FOURBAR_LAWS.items()}
    (tmp_path / "fourbar_friction.toml").write_text(tomli_w.dumps(
        {"model": {"name": "fourbar_friction"}, "mjcf": {"file": str(MODELS / "fourbar.xml")}, "joints": laws}))

    def edit(text):
        return text.replace('model = "../models/fourbar.toml"', f'model = "{tmp_path / "fourbar_friction.toml"}"')

    _scenario(tmp_path, "fourbar", lambda t: edit(t).replace("sin = [[1.5, 2.0]]", "sin = [[1.2, 2.6]]"))
    (tmp_path / "validation.toml").write_text((tmp_path / "fourbar.toml").read_text())
    sc = _scenario(tmp_path, "fourbar",
                   lambda t: edit(t) + '\n[torque_identification]\nfriction = true\nvalidation = "validation.toml"\n')
    result = harness.run(sc)
    assert result.passed and len(result.gates) == 10, [g for g in result.gates if not g.passed]
    cc = result.results["torques"]["closed_chain"]
    assert cc["mujoco_vs_rigid_loops"]["max_rel_range"] <= 1e-6
    found = result.results["torque_identification"]["friction"]["joints"]
    for joint in ("crank", "rocker"):
        for term in ("viscous", "coulomb"):
            assert found[joint][term]["rel_error"] <= 2e-3, (joint, term)
    # a law that reads the load is refused on a closed chain: the bench's drive reads the tree's torque at
    # its commanded accelerations, Pinocchio and the graph model at the recorded ones, which the loops
    # make differ (3.6e-6 of the crank's load apart with load_coulomb = 0.01): the law does not say which
    laws["crank"]["load_coulomb"] = 0.01
    (tmp_path / "fourbar_friction.toml").write_text(tomli_w.dumps(
        {"model": {"name": "fourbar_friction"}, "mjcf": {"file": str(MODELS / "fourbar.xml")}, "joints": laws}))
    with pytest.raises(InputError) as err:
        _scenario(tmp_path, "fourbar", edit)
    assert err.value.key == "joints.crank.load_coulomb" and "depend on the load" in str(err.value)


@pytest.mark.parametrize("name", ["fourbar", "parallelogram", "gripper",
                                  pytest.param("delta", marks=pytest.mark.slow)])  # the delta: 2 s of loop solves
def test_a_closed_chains_base_parameters_come_from_g_t_y(name, request):
    """The actuated-torque regressor G^T Y: the four-bar's 30 standard parameters leave 9 base
    parameters with every joint driven and 8 as a closed chain (the figures the issue measured outside
    the project); the parallelogram arm's closed chain has fewer than its tree. From noise-free actuated
    torques at random consistent states (Pinocchio's RNEA projected, not the regressor), the base
    parameters are recovered and another set of states' torques predicted to 1e-9."""
    from harness.identify.torque_fit import identify_from_torques
    from harness.identify.torque_id import structural_base

    chain = request.getfixturevalue(name)
    spec = chain.spec
    pm = pin_engine.build_model(spec, GRAVITY_W)
    tree = structural_base(pm, spec.limits)
    base = structural_base(pm, spec.limits, chain=chain)
    if name == "fourbar":
        assert (len(tree.independent), len(base.independent)) == (9, 8)
    assert len(base.independent) < len(tree.independent)
    fit_states = closure.random_motion(chain, *_bounds(chain), count=60, seed=21)
    check_states = closure.random_motion(chain, *_bounds(chain), count=60, seed=22)

    def tau_a(m):
        return closure.actuated_torques(m.G, pin_engine.rnea(pm, m.q, m.qd, m.qdd).tau)

    ti = identify_from_torques(pm, spec.joint_names, fit_states.q, fit_states.qd, fit_states.qdd,
                               tau_a(fit_states), (check_states.q, check_states.qd, check_states.qdd,
                                                   tau_a(check_states)), base, chain)
    assert np.abs(ti.beta - ti.beta_true).max() <= 1e-9 * np.abs(ti.beta_true).max()
    assert np.abs(ti.validation_error).max() <= 1e-9 * np.abs(tau_a(check_states)).max()


@pytest.mark.parametrize("name", ["fourbar", "parallelogram", "gripper", "delta"])
def test_a_closed_chain_written_as_mjcf_reads_back_with_its_loops(tmp_path, name, request):
    """write_mjcf keeps the loops (site-based equalities at full precision, a coupling a joint equality)
    and puts motors on the actuated joints only: the file reads back as the same closed chain, its joined
    points to 1e-15 m, its couplings' ratio and offset to the bit."""
    from harness.model.mjcf import write_mjcf

    spec = request.getfixturevalue(name).spec
    (tmp_path / "w.xml").write_text(write_mjcf(spec, GRAVITY_W))
    back = spec_from_data({"mjcf": {"file": "w.xml"}}, tmp_path / "w.toml")
    assert back.actuated == spec.actuated and len(back.loops) == len(spec.loops) >= 1
    for ours, theirs in zip(spec.loops, back.loops, strict=True):
        assert (theirs.kind, theirs.body_a, theirs.body_b) == (ours.kind, ours.body_a, ours.body_b)
        assert (theirs.follower, theirs.leader, theirs.ratio, theirs.offset) == (ours.follower, ours.leader,
                                                                                 ours.ratio, ours.offset)
        np.testing.assert_allclose(theirs.point_a_W0, ours.point_a_W0, atol=1e-15)
        np.testing.assert_allclose(theirs.point_b_W0, ours.point_b_W0, atol=1e-15)


def _driven(chain, h: float, steps: int, spec=None):
    """A smooth consistent motion of the chain (each actuated joint 0.3 sin(1.7 k t)) at every RK4 stage's
    time of `steps` steps of h, and its actuated torques tau_a = G^T rnea (of `spec`'s parameters, default
    the chain's): the motion, the torques at each step's four stages (steps, 4, n; zero on the passive
    joints) and Pinocchio's model of the chain."""
    t = np.arange(2 * steps + 1) * (h / 2)
    w = np.arange(1, len(chain.actuated) + 1) * 1.7
    wt = np.outer(t, w)
    q_a, qd_a, qdd_a = 0.3 * np.sin(wt), 0.3 * w * np.cos(wt), -0.3 * w**2 * np.sin(wt)
    m = closure.motion(chain, closure.positions(chain, q_a, np.zeros(chain.n)), qd_a, qdd_a)
    pm = pin_engine.build_model(spec or chain.spec, GRAVITY_W)
    tau = np.zeros_like(m.q)
    tau[:, list(chain.actuated)] = closure.actuated_torques(m.G, pin_engine.rnea(pm, m.q, m.qd, m.qdd).tau)
    return m, np.stack([tau[0:-1:2], tau[1::2], tau[1::2], tau[2::2]], axis=1), pm  # t, t + h/2 (twice), t + h


@pytest.mark.parametrize("name", ["fourbar", "parallelogram", "gripper", "delta"])
def test_pinocchios_rigid_loops_move_the_chain_as_its_actuated_torques_say(name, request):
    """Pinocchio's constraintDynamics (the loops as RigidConstraintModels, harness/engines/pinocchio.py,
    constrained_rollout) under tau_a = G^T rnea of a smooth consistent motion, given at each RK4 stage's
    time, follows that motion: RK4's error at a 1 ms step on motions of a few rad/s is ~h^4 |q^(5)| ~
    1e-11 a step; within 1e-8 of each joint's range over 0.5 s. This is what the bench's MuJoCo run is
    compared with (torques.closed_chain.mujoco_vs_rigid_loops)."""
    chain = request.getfixturevalue(name)
    m, stages, pm = _driven(chain, 1e-3, 500)
    q, _ = pin_engine.constrained_rollout(pm, chain.spec, m.q[0], m.qd[0], stages, 1e-3, 10)
    truth = m.q[::20]
    span = np.ptp(truth, axis=0)
    assert np.all(np.abs(q - truth).max(axis=0) <= 1e-8 * span)


FOURBAR_LAWS = {  # a law on every joint of the four-bar: the actuated crank's, the passive rocker's and coupler's
    "crank": JointFriction(armature=0.02, viscous=0.3, coulomb=0.5, coulomb_velocity=0.05),
    "rocker": JointFriction(viscous=0.2, coulomb=0.3, coulomb_velocity=0.05),
    "coupler": JointFriction(offset=0.1)}


def test_pinocchios_rigid_loops_carry_the_joints_friction_and_rotor_inertia(fourbar):
    """With friction on every joint (rotor inertia on the crank, viscous and smooth Coulomb friction on the
    crank and the passive rocker, an offset on the coupler's joint), tau_a = G^T rnea (the laws included)
    of a smooth consistent motion drives constraintDynamics along it: the laws' torques at each stage's
    velocity subtracted, the rotor inertia Pinocchio's armature; within 1e-8 of each joint's range over
    0.5 s, as without friction. A law that depends on the load is refused in one line (the solve would
    have to give the rigid-body torque it reads)."""
    import dataclasses

    spec = fourbar.spec.with_frictions(tuple(FOURBAR_LAWS[j] for j in fourbar.spec.joint_names))
    m, stages, pm = _driven(fourbar, 1e-3, 500, spec)
    q, _ = pin_engine.constrained_rollout(pm, spec, m.q[0], m.qd[0], stages, 1e-3, 10)
    truth = m.q[::20]
    assert np.all(np.abs(q - truth).max(axis=0) <= 1e-8 * np.ptp(truth, axis=0))
    frictionless, _ = pin_engine.constrained_rollout(pin_engine.build_model(fourbar.spec, GRAVITY_W), fourbar.spec,
                                                     m.q[0], m.qd[0], stages, 1e-3, 10)
    assert np.abs(frictionless - truth).max() > 1e-3  # the laws move the chain: the check above can fail
    loaded = spec.with_frictions(tuple(dataclasses.replace(f, load_coulomb=0.01) for f in spec.frictions))
    with pytest.raises(pin_engine.NotSimulated, match="depends on its load"):
        pin_engine.constrained_rollout(pin_engine.build_model(loaded, GRAVITY_W), loaded, m.q[0], m.qd[0], stages,
                                       1e-3, 10)


# --- forward dynamics of a model under test --------------------------------------------------------------


def _pinocchio_as_a_model(chain, pm):
    """G^T rnea as a closed chain's model: every joint's (q, q', q'') in, the actuated joints' torques out."""
    act = list(chain.actuated)

    def inverse(q, qd, qdd):
        m = closure.motion(chain, q, qd[:, act], qdd[:, act])
        return closure.actuated_torques(m.G, pin_engine.rnea(pm, q, qd, qdd).tau)
    return inverse


def test_a_models_forward_dynamics_read_off_its_inverse_dynamics_follows_the_motion(parallelogram):
    """harness/model/chain_forward.py: the actuated mass matrix (3 x 3 here) and bias read off G^T rnea,
    RK4 in the actuated joints with the loops closed at every stage, two rollouts at once (from t = 0
    and t = 0.05 s) under the torques of a smooth consistent motion: each follows the motion within 1e-8
    of each joint's range over 0.05 s (RK4's error at 1 ms, as for Pinocchio's rigid loops above). The
    four-bar's is checked against Pinocchio's rigid loops below."""
    from harness.model import chain_forward

    chain = parallelogram
    m, stages, pm = _driven(chain, 1e-3, 100)
    act = list(chain.actuated)
    starts = np.array([0, 50])
    window = starts[:, None] + np.arange(51)
    q = chain_forward.rollout(chain, _pinocchio_as_a_model(chain, pm), m.q[2 * starts], m.qd[2 * starts][:, act],
                              stages[window[:, :-1]][..., act], 1e-3)
    truth = m.q[::2][window]
    span = np.ptp(m.q, axis=0)
    assert q.shape == truth.shape
    assert np.all(np.abs(q - truth).max(axis=(0, 1)) <= 1e-8 * span)


def test_the_graph_theory_models_forward_run_agrees_with_pinocchios_rigid_loops(fourbar):
    """The first seed's closed-chain model (its incidence matrices, the loops' forces as unknowns) forward-
    simulated from its own inverse dynamics against Pinocchio's constraintDynamics under the same
    torques, both RK4 at 1 ms over 0.05 s: two schemes in different coordinates, whose truncation errors
    differ by ~1e-10 of the range (the scenario's figure over 0.1 s, 3e-10); within 1e-8."""
    from harness.model import chain_forward
    from harness.papers.graph_theory_2021.model import make

    m, stages, pm = _driven(fourbar, 1e-3, 50)
    act = list(fourbar.actuated)
    q_ref, _ = pin_engine.constrained_rollout(pm, fourbar.spec, m.q[0], m.qd[0], stages, 1e-3, 1)
    graph = make(fourbar.spec, gravity_W=GRAVITY_W)
    q = chain_forward.rollout(fourbar, graph.inverse_dynamics, m.q[:1], m.qd[:1, act], stages[None][..., act], 1e-3)
    span = np.ptp(q_ref, axis=0)
    assert np.all(np.abs(q[0] - q_ref).max(axis=0) <= 1e-8 * span)


@pytest.mark.slow  # a forward run of a stiff loop (3.5 s)
def test_a_spatial_four_bar_whose_passive_joint_does_not_move_passes_its_forward_gate(tmp_path):
    """A spatial four-bar (tests/data/models/spatial_fourbar.xml: the coupler on a universal joint of two
    hinges) whose motion leaves the passive joint u2 still (its range over the run is round-off): the
    graph-theory model's forward run is judged against u2's floor (1e-3 of the hinges' largest range),
    not its own range of 1e-16 (which read 4.07 and failed the gate at u2), and every gate passes; a
    1e-6 rad error at u2 would still be 1e-3 of its floor."""
    import json

    import pandas as pd

    from harness.cli import main
    from tests.conftest import DATA

    out = tmp_path / "out"
    assert main(["run", str(DATA / "scenarios" / "spatial_fourbar.toml"), "--out", str(out), "--quiet"]) == 0
    assert np.ptp(pd.read_csv(out / "recording.csv")["q_u2"]) < 1e-12  # still
    forward = json.loads((out / "results.json").read_text())["torques"]["closed_chain"]["forward"]["graph"]
    assert forward["max_rel_range"] <= 1e-6 and forward["per_joint"]["u2"] <= 1e-6


@pytest.mark.slow  # two forward runs (1.1 s)
def test_a_model_whose_rocker_is_heavier_by_a_ten_thousandth_is_seen_by_its_forward_run(fourbar):
    """The scenario's gate (1e-6 of a joint's range) can fail: a model whose rocker is 0.01 % heavier, run
    0.1 s from the motion's state under the true torques, leaves it by more than 1e-5 of the rocker's
    range (5.1e-5 measured; 5.1e-3 for 1 % heavier: linear in the error)."""
    import dataclasses

    from harness.model import chain_forward

    spec = fourbar.spec
    heavy = dataclasses.replace(spec, bodies=tuple(dataclasses.replace(b, mass=b.mass * 1.0001) if b.name == "rocker"
                                                   else b for b in spec.bodies))
    m, stages, _ = _driven(fourbar, 1e-3, 100)
    act = list(fourbar.actuated)
    wrong = _pinocchio_as_a_model(fourbar, pin_engine.build_model(heavy, GRAVITY_W))
    q = chain_forward.rollout(fourbar, wrong, m.q[:1], m.qd[:1, act], stages[None][..., act], 1e-3)
    rocker = spec.joint_names.index("rocker")
    assert np.abs(q[0, :, rocker] - m.q[::2, rocker]).max() > 1e-5 * np.ptp(m.q[:, rocker])


def test_a_model_without_inertia_is_refused_in_one_line(fourbar):
    """A model whose torques do not depend on q'' has no actuated mass matrix: refused, not integrated."""
    from harness.model import chain_forward

    def gravity_only(q, qd, qdd):
        return np.ones((len(q), len(fourbar.actuated)))

    with pytest.raises(chain_forward.ChainForwardError, match="actuated mass matrix is singular") as info:
        chain_forward.rollout(fourbar, gravity_only, np.zeros((1, fourbar.n)), np.zeros((1, 1)),
                              np.zeros((1, 2, 4, 1)), 1e-3)
    assert "\n" not in str(info.value)


# --- the first seed's method -----------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["fourbar", "parallelogram", "delta"])
def test_the_graph_theory_method_closes_the_loops_with_its_incidence_matrices(name, request):
    """The graph-theory model of a closed chain (harness/papers/graph_theory_2021/closed.py: the tree's
    Newton-Euler equations by its incidence matrices, the loops' forces as unknowns, the passive joints'
    drives zero) against the constraint-Jacobian route (Pinocchio's RNEA projected by G, multipliers from
    J^T lambda = tau - S^T tau_a), two derivations sharing no code, at 100 random consistent states:
    actuated torques and multipliers to 1e-9 of their largest (round-off ~1e-15); with the multipliers
    its passive joints transmit no moment along their axes."""
    chain = request.getfixturevalue(name)
    spec = chain.spec
    m, graph, tau_a = _graph_against_constraint_jacobian(chain, spec, seed=31)
    from harness.model.kinematics import forward_kinematics

    axes = forward_kinematics(spec, m.q, m.qd, m.qdd).axis_W
    passive = list(chain.passive)
    assert all(spec.joints[p].revolute for p in passive)
    along = np.einsum("npa,npa->np", graph.M_W[:, passive], axes[:, passive])
    assert np.abs(along).max() <= 1e-9 * np.abs(tau_a).max()


@pytest.mark.parametrize("name", ["fourbar", "parallelogram"])  # one loop each: its one constraint model
def test_the_graph_theory_multipliers_are_pinocchios_own_constraint_forces(name, request):
    """The first seed's multipliers against Pinocchio's constraintDynamics, which knows nothing of them:
    driven by the graph-theory model's actuated torques at 20 random consistent states, Pinocchio's rigid
    loops (RigidConstraintModel, proximal mu = 1e-8) accelerate as the motion does (1e-7: mu's
    regularisation) and their contact force, turned from its frame on body a to the world, is the
    model's lambda where a force moves the chain: in J's range, to 1e-9 of its size (measured 1e-13).
    Along the planar loop's normal, which moves nothing, the model's is zero (least norm) and
    Pinocchio's what its proximal iterations leave (1.7e-7 of the force after 50 iterations on the
    parallelogram, 1.7e-6 after 500): not comparable, and not compared."""
    import pinocchio as pin

    from harness.papers.graph_theory_2021.closed import closed_chain_inverse
    from harness.papers.graph_theory_2021.dynamics import build_graph_model

    chain = request.getfixturevalue(name)
    spec, act = chain.spec, list(chain.actuated)
    (loop,) = spec.loops
    m = closure.random_motion(chain, *_bounds(chain), count=20, seed=41)
    graph = closed_chain_inverse(spec, build_graph_model(spec, GRAVITY_W), m.q, m.qd, m.qdd)
    pm = pin_engine.build_model(spec, GRAVITY_W)
    model, data = pm.model, pm.model.createData()
    pin.forwardKinematics(model, data, np.zeros(model.nq))
    ends = []
    for body, p in ((loop.body_a, loop.point_a_W0), (loop.body_b, loop.point_b_W0)):
        jid = 0 if body == "world" else pm.joint_ids[spec.joint_names.index(spec.inner_joint(body).name)]
        ends += [jid, data.oMi[jid].actInv(pin.SE3(np.eye(3), np.asarray(p)))]
    cm = pin.RigidConstraintModel(pin.ContactType.CONTACT_3D, model, *ends, pin.ReferenceFrame.LOCAL)
    cmodels, cdatas = pin.StdVec_RigidConstraintModel(), pin.StdVec_RigidConstraintData()
    cmodels.append(cm), cdatas.append(cm.createData())
    pin.initConstraintDynamics(model, data, cmodels, cdatas)
    settings = pin.ProximalSettings(1e-12, 1e-8, 50)
    idx = pm.q_index
    for k in range(len(m.q)):
        qq, vv, tt = np.zeros(model.nq), np.zeros(model.nv), np.zeros(model.nv)
        qq[idx], vv[idx] = m.q[k], m.qd[k]
        tt[idx[act]] = graph.tau[k, act]
        a = pin.constraintDynamics(model, data, qq, vv, tt, cmodels, cdatas, settings)[idx]
        np.testing.assert_allclose(a, m.qdd[k], atol=1e-7 * np.abs(m.qdd[k]).max())
        lam_W = (data.oMi[ends[0]] * ends[1]).rotation @ cdatas[0].contact_force.linear
        U, S, _ = np.linalg.svd(m.J[k], full_matrices=False)
        moving = U[:, S > 1e-9 * S[0]]  # the loop's force directions that move a joint: J's range
        np.testing.assert_allclose(moving.T @ lam_W, moving.T @ graph.lam[k], atol=1e-9 * np.abs(graph.lam[k]).max())


def test_the_graph_theory_method_carries_every_joints_friction_through_the_loops(fourbar):
    """With a law on every joint (rotor inertia, viscous, smooth Coulomb and a load-dependent term on the
    crank; friction on the passive rocker and an offset on the coupler's joint): a passive joint's
    equation is tau_p + f_p = 0, so its friction enters the loops' forces and its bearing transmits it
    (its wrench's moment along its axis is -f_p). The graph-theory model's
    actuated torques and multipliers against G^T (rnea + the laws), Pinocchio's tree torques with the
    same laws (read at the tree's rigid-body torque), at 100 random consistent states: within 1e-9 of
    their largest; without the passive rocker's friction they differ by more than 1e-3."""
    import dataclasses

    from harness.papers.graph_theory_2021.closed import closed_chain_inverse
    from harness.papers.graph_theory_2021.dynamics import build_graph_model

    laws = {**FOURBAR_LAWS, "crank": dataclasses.replace(FOURBAR_LAWS["crank"], load_coulomb=0.01)}
    spec = fourbar.spec.with_frictions(tuple(laws[j] for j in fourbar.spec.joint_names))
    m, graph, tau_a = _graph_against_constraint_jacobian(fourbar, spec, seed=37)
    # a passive joint's bearing transmits its friction: its wrench's moment along its axis is -f_p
    from harness.model.friction import torque
    from harness.model.kinematics import forward_kinematics

    passive = list(fourbar.passive)
    axes = forward_kinematics(spec, m.q, m.qd, m.qdd).axis_W[:, passive]
    f_p = torque(spec.frictions, m.qd, m.qdd, np.zeros_like(m.q))[:, passive]  # no load term on a passive joint
    along = np.einsum("npa,npa->np", graph.M_W[:, passive], axes)
    assert np.abs(f_p).min() > 0 and np.abs(along + f_p).max() <= 1e-9 * np.abs(tau_a).max()
    no_rocker = spec.with_frictions(tuple(JointFriction() if j == "rocker" else laws[j] for j in spec.joint_names))
    other = closed_chain_inverse(no_rocker, build_graph_model(no_rocker, GRAVITY_W), m.q, m.qd, m.qdd)
    act = list(fourbar.actuated)
    assert np.abs(other.tau[:, act] - tau_a).max() > 1e-3 * np.abs(tau_a).max()


def _graph_against_constraint_jacobian(chain, spec, seed: int):
    """The graph-theory model of `spec` (the chain's, or with other laws) and the constraint-Jacobian
    route at 100 random consistent states: actuated torques and multipliers within 1e-9 of their
    largest. Returns the states, the graph model's answer and tau_a."""
    from harness.papers.graph_theory_2021.closed import closed_chain_inverse
    from harness.papers.graph_theory_2021.dynamics import build_graph_model

    m = closure.random_motion(chain, *_bounds(chain), count=100, seed=seed)
    graph = closed_chain_inverse(spec, build_graph_model(spec, GRAVITY_W), m.q, m.qd, m.qdd)
    tree = pin_engine.rnea(pin_engine.build_model(spec, GRAVITY_W), m.q, m.qd, m.qdd).tau
    tau_a = closure.actuated_torques(m.G, tree)
    lam = closure.multipliers(chain, m.J, tree, tau_a)
    act = list(chain.actuated)
    assert np.abs(graph.tau[:, act] - tau_a).max() <= 1e-9 * np.abs(tau_a).max()
    assert np.abs(graph.lam - lam).max() <= 1e-9 * np.abs(lam).max()
    return m, graph, tau_a
