"""A floating base standing on contacts (harness/model/contacts.py, harness/engines/free_base.py): the
built-in Solo12 standing on its four feet while its base sways, a foot lifted and put down, and the built-in
G1 humanoid standing on its two soles (welds: a force and a moment each), its arms moving, a foot lifted.

Independent references: Newton's and Euler's laws for the whole robot (its bodies' masses and inertias
from the model, their accelerations as MuJoCo's sensors read them, the feet's forces as its constraint
solver gave them), MuJoCo's own kinematics of the model file's sites for where the feet stand, finite
differences of the stance's positions, and Pinocchio's RNEA with external forces for the feet's
generalised force."""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from harness.base.series import read_csv
from harness.base.tomlio import InputError
from harness.engines.mujoco import build_model
from harness.engines.pinocchio import build_model as pin_model
from harness.engines.pinocchio import rnea
from harness.model import floating
from harness.model.contacts import generalised_force, ground_frames, ground_points
from harness.model.floating import BaseMotion, random_base_motion
from harness.model.kinematics import cross
from harness.runner.scenario import load_scenario
from harness.sources.bench import record
from harness.stages.floating_fit import _whole

from .conftest import SCENARIOS

STANDING = SCENARIOS / "solo12_standing.toml"
ON_SOLES = SCENARIOS / "g1_standing.toml"


@pytest.fixture(scope="module", params=[(STANDING, 1.0, 0.3, 0.7, 1.0), (ON_SOLES, 0.6, 0.12, 0.48, 0.5)],
                ids=["solo12 on its feet", "g1 on its soles"])
def standing(request, tmp_path_factory):
    """A built-in scenario's first second (the humanoid's first 0.6 s, its pelvis turned 0.4 rad about the
    vertical and 0.1 rad about its x-axis throughout, so that no sole stands on the world's axes), its foot
    lifted from 0.3 s to 0.7 s (0.12 s to 0.48 s, swung half as far: the file's lift, earlier and shorter), and
    its recording."""
    path, duration, start, end, swing = request.param
    if path == ON_SOLES:
        text = _absolute(path.read_text())
        for axis, offset in (("yaw", 0.4), ("roll", 0.1)):
            text = text.replace(f'[base_motion.{axis}]\ntype = "sinusoids"\n',
                                f'[base_motion.{axis}]\ntype = "sinusoids"\noffset = {offset}\n')
        assert "offset = 0.4" in text and "offset = 0.1" in text
        path = tmp_path_factory.mktemp("soles") / "g1_turned.toml"
        path.write_text(text)
    scenario = load_scenario(path)
    contacts = tuple(c if c.lift is None else dataclasses.replace(c, lift=dataclasses.replace(
        c.lift, start=start, end=end, swing=tuple((j, swing * v) for j, v in c.lift.swing))) for c in scenario.contacts)
    scenario = dataclasses.replace(scenario, duration=duration, output_steps=round(100 * duration),
                                   contacts=contacts)
    return scenario, record(scenario)


def _base(rec) -> BaseMotion:
    return BaseMotion.from_rows(rec.base_pose, rec.base_twist_W, rec.base_rate_W)


def test_the_feet_carry_the_robot_as_newton_and_euler_say(standing):
    """Sum of m a - m g over every body (the legs' centre-of-mass accelerations as MuJoCo's sensors read
    them, the base's from its recorded motion) equals the feet's recorded forces plus what the world applied
    to the base besides them; the rate of change of the angular momentum about the world's origin, their
    moments. To 1e-9 of the robot's weight (and of its weight times its size): the recorded quantities come
    from one evaluation of MuJoCo's dynamics per row, consistent to round-off."""
    sc, rec = standing
    spec, fb = sc.robot, sc.robot.floating
    base = _base(rec)
    g = sc.gravity_W
    R = base.R_WB
    r_B = fb.R_WF0.T @ (fb.body.p_W_com0 - fb.p_WF0)  # the base's centre of mass in its frame
    r = R @ r_B
    a_base = base.a_W + cross(base.alpha_W, r) + cross(base.omega_W, cross(base.omega_W, r))
    R_base = R @ (fb.R_WF0.T @ fb.body.R_WB0)  # the base body's principal axes
    masses = np.array([b.mass for b in spec.massive_bodies])
    force = fb.body.mass * (a_base - g) + np.einsum("b,nbi->ni", masses, rec.a_W - g)

    def spin(Rb, I_B, w, wd):  # d/dt (I w) = I w' + w x I w, I = R I_B R^T
        I_W = Rb @ I_B @ np.swapaxes(Rb, -1, -2)
        return (I_W @ wd[..., None])[..., 0] + cross(w, (I_W @ w[..., None])[..., 0])

    p_base = base.p_W + r
    moment = (cross(p_base, fb.body.mass * (a_base - g)) + spin(R_base, fb.body.I_B, base.omega_W, base.alpha_W)
              + np.sum(cross(rec.p_W, masses[None, :, None] * (rec.a_W - g)), axis=1)
              + np.sum(spin(rec.R_WB, np.stack([b.I_B for b in spec.massive_bodies]), rec.omega_W, rec.omegadot_W),
                       axis=1))
    F_c, x_c = rec.contact_F_W, rec.contact_x_W
    applied = rec.base_wrench_W  # about the base origin
    held_force = F_c.sum(axis=1) + applied[:, :3]
    held_moment = cross(x_c, F_c).sum(axis=1) + rec.contact_M_W.sum(axis=1) + applied[:, 3:] + cross(base.p_W,
                                                                                                     applied[:, :3])
    weight = (fb.body.mass + masses.sum()) * np.linalg.norm(g)
    assert np.max(np.abs(force - held_force)) <= 1e-9 * weight
    assert np.max(np.abs(moment - held_moment)) <= 1e-9 * weight * np.max(np.abs(x_c))
    # and the feet carry it: the weight is theirs (more or less as the robot accelerates), the base is held by
    # nothing else
    assert np.max(np.abs(applied)) <= 1e-9 * weight
    assert np.all(F_c[:, :, 2].sum(axis=1) > 0.5 * weight)


def test_every_held_foot_stands_where_it_stood_and_the_lifted_one_swings_clear(standing):
    """The stance placed in MuJoCo's model of the robot (its free joint's pose from the prescribed base,
    the joints from the stance, mj_kinematics): each held foot's site on its ground site to 1e-12 m, and a
    held sole's frame on its ground site's to 1e-12 rad; the lifted foot more than 2 cm off at its lift's
    middle and back on its site at the lift's end; the stance's rates its positions' central differences
    (h = 1e-5 s: to 1e-6 of their largest)."""
    sc, _ = standing
    t = np.linspace(0.0, sc.duration, 401)
    q, qd, qdd = sc.prescribed(t)
    base = sc.base_motion.evaluate(t)
    base0 = sc.base_motion.evaluate(np.zeros(1))
    ground = (sc.contacts, ground_points(sc.robot, sc.contacts, base0, q[0]),
              ground_frames(sc.robot, sc.contacts, base0, q[0]))
    model = build_model(sc.robot, sc.gravity_W, sc.simulation, floating=True, ground=ground)
    data = mujoco.MjData(model)
    qadr = [model.joint(j).qposadr[0] for j in sc.robot.joint_names]
    qpos = floating.to_mujoco(base)[0]
    feet = np.empty((len(t), len(sc.contacts), 3))
    turned = np.zeros((len(t), len(sc.contacts)))
    for k in range(len(t)):
        data.qpos[:7], data.qpos[qadr] = qpos[k], q[k]
        mujoco.mj_kinematics(model, data)
        feet[k] = [data.site(f"contact_{c.name}").xpos for c in sc.contacts]
        for i, c in enumerate(sc.contacts):  # the angle between the sole's frame and its frame on the ground
            R = data.site(f"contact_{c.name}").xmat.reshape(3, 3).T @ data.site(f"ground_{c.name}").xmat.reshape(3, 3)
            skew = (R - R.T) / 2.0  # sin(angle) times the axis, as a skew matrix: exact at small angles
            turned[k, i] = np.linalg.norm([skew[2, 1], skew[0, 2], skew[1, 0]]) if c.sole else 0.0
    on_ground = [data.site(f"ground_{c.name}").xpos for c in sc.contacts]
    off = np.linalg.norm(feet - np.array(on_ground), axis=-1)
    held = np.stack([c.planted(t) for c in sc.contacts], axis=1)
    assert np.max(off[held]) <= 1e-12
    assert np.max(turned[held]) <= 1e-12
    lifted = next(k for k, c in enumerate(sc.contacts) if c.lift is not None)
    lift = sc.contacts[lifted].lift
    middle, end = (np.argmin(np.abs(t - x)) for x in ((lift.start + lift.end) / 2, lift.end))
    assert off[middle, lifted] > 0.02 and off[end, lifted] <= 1e-12
    h = 1e-5
    (qp, qdp, _), (qm, qdm, _) = sc.prescribed(t + h), sc.prescribed(t - h)
    assert np.max(np.abs((qp - qm) / (2 * h) - qd)) <= 1e-6 * np.max(np.abs(qd))
    assert np.max(np.abs((qdp - qdm) / (2 * h) - qdd)) <= 1e-6 * np.max(np.abs(qdd))


def test_the_feet_s_generalised_force_is_pinocchios_jacobian_transpose(standing):
    """generalised_force (kinematics alone) at random states of the base and joints, with random forces and
    moments at the feet, equals what Pinocchio's RNEA loses to the same wrenches as external forces (rnea
    without them minus rnea with them), base rows in the harness's convention, to 1e-12 of the largest."""
    sc, _ = standing
    spec = sc.robot
    N = 40
    rng = np.random.default_rng(3)
    base = random_base_motion(N, 5)
    q = rng.uniform(-1.0, 1.0, (N, len(spec.joints)))
    zero = np.zeros_like(q)
    F = rng.uniform(-20.0, 20.0, (N, len(sc.contacts), 3))
    M = rng.uniform(-1.0, 1.0, (N, len(sc.contacts), 3))
    x = rng.uniform(-0.5, 0.5, (N, len(sc.contacts), 3))
    ours = generalised_force(spec, sc.contacts, base, q, F, M, x)
    from harness.engines.pinocchio import PointForce

    pm = pin_model(spec.rigid(), sc.gravity_W, floating=True)
    feet = tuple(PointForce(spec.joint_names.index(spec.inner_joint(c.body).name), x[:, k], F[:, k], M[:, k])
                 for k, c in enumerate(sc.contacts))
    without, with_ = rnea(pm, q, zero, zero, base=base), rnea(pm, q, zero, zero, feet, base=base)
    theirs = np.concatenate([without.base - with_.base, without.tau - with_.tau], axis=1)
    assert np.max(np.abs(ours - theirs)) <= 1e-12 * np.max(np.abs(theirs))


def test_the_identification_s_rows_are_the_robot_s_inverse_dynamics(standing):
    """What the floating-base fit reads of a standing recording (the contacts' generalised force added to
    what the bench applied and to the motors' torques) is Pinocchio's M q'' + h of the rigid robot at the
    recorded states, no external force: to 1e-12 of each row's largest, a contact's chain's rows of the largest
    joint's (their torque is the motor's plus the contact's J^T F, terms that size; a held sole's ankle's is near
    zero while the weld takes the moment)."""
    sc, rec = standing
    base, q, qd, qdd, wrench, tau = _whole(sc, rec)
    ref = rnea(pin_model(sc.robot.rigid(), sc.gravity_W, floating=True), q, qd, qdd, base=base)
    assert np.max(np.abs(wrench - ref.base) / np.max(np.abs(ref.base), axis=0)) <= 1e-12
    chains = np.isin(sc.robot.joint_names, [j for c in sc.contacts for j in c.chain])
    scale = np.where(chains, np.max(np.abs(ref.tau)), np.max(np.abs(ref.tau), axis=0))
    assert np.max(np.abs(tau - ref.tau) / scale) <= 1e-12


def test_a_standing_recording_reads_back_as_written(standing, tmp_path):
    """recording.csv's contact columns (contact[<name>][Fx] .. [held]) read back bit for bit; a bench log (write_log)
    holds each contact's force, and a sole's moment (a point's, zero throughout, is not written), bit for bit."""
    import pandas as pd

    from harness.sources.bench import write_log

    sc, rec = standing
    rec.write_csv(tmp_path / "r.csv")
    back = read_csv(tmp_path / "r.csv")
    assert back.contacts == rec.contacts
    for name in ("contact_F_W", "contact_M_W", "contact_x_W", "contact_held"):
        assert np.array_equal(getattr(back, name), getattr(rec, name)), name
    write_log(rec, sc.robot.joint_names, tmp_path / "log.csv")
    log = pd.read_csv(tmp_path / "log.csv")
    for k, c in enumerate(sc.contacts):
        assert np.array_equal(log[[f"{c.name}_f{x}" for x in "xyz"]].to_numpy(), rec.contact_F_W[:, k])
        moment = [f"{c.name}_m{x}" for x in "xyz"]
        assert np.array_equal(log[moment].to_numpy(), rec.contact_M_W[:, k]) if c.sole else moment[0] not in log
        assert np.any(rec.contact_M_W[:, k] != 0.0) == c.sole


def test_the_lift_s_weight_leaves_and_lands_with_no_velocity_or_acceleration(standing):
    """w = sin^4(pi s): w, w', w'' zero at both ends; w' and w'' the central differences of w and w'."""
    sc, _ = standing
    lift = next(c.lift for c in sc.contacts if c.lift is not None)
    ends = np.array([lift.start, lift.end])
    for x in lift.weight(ends):
        assert np.max(np.abs(x)) <= 1e-12
    t, h = np.linspace(lift.start + 0.01, lift.end - 0.01, 57), 1e-6
    _, wd, wdd = lift.weight(t)
    (wp, wdp, _), (wm, wdm, _) = lift.weight(t + h), lift.weight(t - h)
    assert np.max(np.abs((wp - wm) / (2 * h) - wd)) <= 1e-7 * np.max(np.abs(wd))
    assert np.max(np.abs((wdp - wdm) / (2 * h) - wdd)) <= 1e-7 * np.max(np.abs(wdd))


BAD = [
    ('base_motion', lambda s: s.replace("[base_motion.x]", "[ignored.x]").replace("[base_motion.", "[ignored_"),
     None),
    ('contacts[1].body', lambda s: s.replace('body = "FR_LOWER_LEG"', 'body = "FR_FOOT"'), "no moving body"),
    ('contacts[1].body', lambda s: s.replace('body = "FR_LOWER_LEG"', 'body = "FL_LOWER_LEG"'), "carries contact"),
    ('contacts[1].body', lambda s: s.replace('body = "FR_LOWER_LEG"', 'body = "FR_UPPER_LEG"'), "needs three"),
    ('contacts[1].name', lambda s: s.replace('name = "FR_foot"', 'name = "FL_foot"'), "named twice"),
    ('contacts[1].body', lambda s: s.replace('body = "FR_LOWER_LEG"', 'kind = "sole"\nbody = "FR_LOWER_LEG"'),
     "a sole held on the ground needs six"),
    ('contacts[1].kind', lambda s: s.replace('body = "FR_LOWER_LEG"', 'kind = "foot"\nbody = "FR_LOWER_LEG"'),
     "not one of point, sole"),
    ('motion.FR_KFE', lambda s: s.replace('[motion.FR_KFE]\ntype = "locked"\nposition = -1.2',
                                          '[motion.FR_KFE]\ntype = "sinusoids"\noffset = -1.2\nsin = [[0.1, 2.0]]'),
     "holds contact"),
    ('contacts[0].lift.from', lambda s: s.replace("from = 0.8", "from = 0.805"), "not on the recording's grid"),
    ('contacts[0].lift.to', lambda s: s.replace("to = 1.4", "to = 2.4"), "by the recording's end"),
    ('contacts[0].lift.swing.FR_HFE', lambda s: s.replace("swing = { FL_HFE", "swing = { FR_HFE"),
     "not a joint of the contact's chain"),
    ('contacts', lambda s: s.replace("point = [0.1946, -0.14695, -0.32]", "point = [0.1946, -0.14695, -0.52]")
     .replace("[base_motion.z]\ntype = \"sinusoids\"\noffset = 0.0\nsin = [[0.01, 3.0]]",
              "[base_motion.z]\ntype = \"sinusoids\"\noffset = 0.0\nsin = [[0.3, 3.0]]"), "out of its chain's reach"),
]


def _absolute(text: str) -> str:
    """A built-in scenario's text with the files it names given by their whole path (to be written elsewhere)."""
    return (text.replace('"../models/', f'"{SCENARIOS.parent / "models"}/')
            .replace('"gates/', f'"{SCENARIOS / "gates"}/').replace('validation = "', f'validation = "{SCENARIOS}/'))


@pytest.mark.parametrize(("key", "edit", "said"), BAD, ids=[b[0] + (f": {b[2]}" if b[2] else "") for b in BAD])
def test_a_contact_the_bench_cannot_hold_is_refused_in_one_line(tmp_path, key, edit, said):
    text = _absolute(STANDING.read_text())
    path = tmp_path / "s.toml"
    path.write_text(edit(text))
    with pytest.raises(InputError) as err:
        load_scenario(path)
    if key == "base_motion":  # without a base motion the torque identification refuses first, or the contacts
        assert err.value.key in ("contacts", "torque_identification")
        return
    assert err.value.key == key, str(err.value)
    assert said in str(err.value) and "\n" not in str(err.value)


def test_a_noise_on_contact_wrenches_needs_contacts(tmp_path):
    sc = load_scenario(SCENARIOS / "solo12_floating.toml")
    assert sc.contacts == ()
    text = _absolute((SCENARIOS / "solo12_floating.toml").read_text())
    (tmp_path / "s.toml").write_text(text + "\n[measurement.noise.contact_wrenches]\nrelative = 0.01\n")
    with pytest.raises(InputError) as err:
        load_scenario(tmp_path / "s.toml")
    assert err.value.key == "measurement.noise.contact_wrenches"


def test_the_stance_is_the_scenario_s_motion_everywhere_it_is_read(standing):
    """The bench followed the stance: the recording's joints are the prescribed motion's to the feet's
    compliance (the scenario's own gate: 1e-6 rad for the feet, 2e-5 for the soles, which carry the moments too),
    and a scenario without contacts keeps its [motion] as written."""
    sc, rec = standing
    q = sc.prescribed(rec.t)[0]
    assert np.max(np.abs(rec.q - q)) <= next(g.limit for g in sc.gates if g.metric == "recording.max_tracking_error")
    free = dataclasses.replace(sc, contacts=())
    assert not np.allclose(free.prescribed(rec.t)[0], q)
    assert pin.__version__  # Pinocchio is the reference of the two tests above


def test_a_foot_that_pulls_or_needs_friction_is_said_along_the_ground_s_normal(standing):
    """The standing figures read the feet's forces along gravity's vertical, whatever the world's axes: with
    gravity turned, feet held pulling 2 N and 5 N make -5 N the least normal force, a released foot's forces are
    not read, a push of 10 N with 3 N across needs a friction coefficient of 0.3, and a contact pressing 10 N
    with the moment of a pressure 4 cm off its point along the ground has its centre of pressure 4 cm away (a
    pulling one's is not read)."""
    from harness.stages.moving_base import standing as figures

    _, rec = standing
    R = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])  # world axes turned: "up" along x
    F = np.zeros_like(rec.contact_F_W)
    F[:, :, :] = R @ np.array([0.0, 0.0, 10.0])  # every foot pushing 10 N
    F[5, 1] = R @ np.array([3.0, 0.0, 10.0])  # 3 N across
    F[7, 0] = R @ np.array([0.0, 0.0, -2.0])  # pulling
    held = np.ones_like(rec.contact_held)
    held[9, 1] = False
    F[9, 1] = R @ np.array([50.0, 0.0, -60.0])  # released: not read
    # a sole's moment about its point: its pressure 4 cm off along the ground (-1 cm along the normal, which no
    # moment of a normal force shows), r x F with F = 10 N along the normal
    M = np.zeros_like(F)
    M[11, 0] = np.cross(R @ np.array([0.04 * 0.6, 0.04 * 0.8, -0.01]), F[11, 0])
    M[12, 1] = np.cross(R @ np.array([0.5, 0.0, 0.0]), R @ np.array([0.0, 0.0, -5.0]))  # pulling: not read
    F[12, 1] = R @ np.array([0.0, 0.0, -5.0])
    rec = dataclasses.replace(rec, contact_F_W=F, contact_M_W=M, contact_held=held)
    out = figures(rec, np.ones((len(rec.t), 6)), R @ np.array([0.0, 0.0, -9.81]))
    assert out["contact_least_normal_force_N"] == pytest.approx(-5.0, abs=1e-12)
    assert out["contact_friction_needed"] == pytest.approx(0.3, abs=1e-12)
    assert out["contact_centre_of_pressure_m"] == pytest.approx(0.04, abs=1e-12)
