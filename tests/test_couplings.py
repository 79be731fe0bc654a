"""Joint couplings q_f = r q_l + o (a URDF <mimic>, an MJCF joint equality, a model file's
`type = "joint"` loop): the follower is no degree of freedom, and what the chain's actuated joints need
is G^T tau, G constant (harness/model/loops.py, closure.py). Checked against Pinocchio's own mimic
joints, which reduce the tree inside its algorithms and share nothing with G; MuJoCo's reading of the
couplings and the bench's simulation are in tests/test_closed_chains.py (the `gripper` cases)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from harness.base.tomlio import InputError
from harness.engines import pinocchio as pin_engine
from harness.model import closure
from harness.model.load import load_spec
from tests.conftest import MODELS, ROOT

GRAVITY_W = np.array([0.0, 0.0, -9.81])
ARM_URDF = ROOT / "examples" / "two_link_arm" / "two_link_arm.urdf"
MIMIC = '<mimic joint="shoulder" multiplier="-0.7" offset="0.2"/>'


def _arm(tmp_path, mimic: str = MIMIC, model: str = "") -> closure.ClosedChain | None:
    """The example two-link arm, its elbow following the shoulder by `mimic`, read by `model` (a model
    file's text after its [urdf] file key)."""
    (tmp_path / "arm.urdf").write_text(ARM_URDF.read_text().replace('<child link="fore"/>',
                                                                     f'<child link="fore"/>{mimic}'))
    (tmp_path / "arm.toml").write_text('[urdf]\nfile = "arm.urdf"\n' + model)
    spec = load_spec(tmp_path / "arm.toml")
    return closure.ClosedChain.of(spec) if spec.loops else None


def _reduced(model: pin.Model, chain: closure.ClosedChain, m: closure.ChainMotion):
    """Pinocchio's RNEA and CRBA of `model` (mimic joints) at the motion's actuated coordinates: (N, n_a)
    and (N, n_a, n_a), in the chain's actuated order."""
    data = model.createData()
    act = [chain.spec.joint_names[k] for k in chain.actuated]
    # a mimic joint has no coordinate of its own (it reads its leader's): the actuated joints' alone
    q_idx = [model.joints[model.getJointId(a)].idx_q for a in act]
    v_idx = [model.joints[model.getJointId(a)].idx_v for a in act]
    assert model.nq == model.nv == len(act)
    a_cols = list(chain.actuated)
    tau, M = np.empty((len(m.q), len(act))), np.empty((len(m.q), len(act), len(act)))
    for k in range(len(m.q)):
        q, v, a = np.zeros(model.nq), np.zeros(model.nv), np.zeros(model.nv)
        q[q_idx], v[v_idx], a[v_idx] = m.q[k, a_cols], m.qd[k, a_cols], m.qdd[k, a_cols]
        tau[k] = pin.rnea(model, data, q, v, a)[v_idx]
        full = pin.crba(model, data, q)
        M[k] = (np.triu(full) + np.triu(full, 1).T)[np.ix_(v_idx, v_idx)]
    return tau, M


def _projected(chain: closure.ClosedChain, m: closure.ChainMotion):
    """The harness's G^T tau and G^T M G of the open tree (Pinocchio's RNEA and CRBA of every joint)."""
    pm = pin_engine.build_model(chain.spec, GRAVITY_W)
    tau = closure.actuated_torques(m.G, pin_engine.rnea(pm, m.q, m.qd, m.qdd).tau)
    return tau, np.swapaxes(m.G, 1, 2) @ pin_engine.crba(pm, m.q) @ m.G


def test_a_mimic_joint_is_no_degree_of_freedom_as_pinocchios_own_parser_reads_it(tmp_path):
    """The URDF's <mimic> read as a coupling: the harness's G^T rnea and G^T M G of the open tree
    against the model Pinocchio's URDF parser builds with mimic=True (the elbow a JointModelMimic of
    the shoulder), at 50 random consistent states: to 1e-12 of the largest (round-off ~1e-15). The
    follower sits where the multiplier and offset put it."""
    chain = _arm(tmp_path)
    (loop,) = chain.spec.loops
    assert (loop.kind, loop.follower, loop.leader, loop.ratio, loop.offset) == ("joint", "elbow", "shoulder", -0.7, 0.2)
    assert chain.spec.actuated == ("shoulder",)
    m = closure.random_within_limits(chain, chain.spec.limits, 50, seed=3)
    np.testing.assert_allclose(m.q[:, 1], -0.7 * m.q[:, 0] + 0.2, atol=1e-14)
    model = pin.buildModelFromUrdf(str(tmp_path / "arm.urdf"), mimic=True)
    model.gravity.linear = GRAVITY_W
    assert model.nv == 1
    tau, M = _projected(chain, m)
    tau_pin, M_pin = _reduced(model, chain, m)
    assert np.abs(tau - tau_pin).max() <= 1e-12 * np.abs(tau_pin).max()
    assert np.abs(M - M_pin).max() <= 1e-12 * np.abs(M_pin).max()


def test_the_gripper_s_couplings_are_pinocchios_mimic_joints(gripper_chain):
    """The built-in gripper's two joint equalities (a mirrored finger, a tendon with an offset and a
    joint `ref` in the file) made Pinocchio mimic joints (transformJointIntoMimic on the open tree's
    model, with the coupling's ratio and offset): G^T rnea and G^T M G to 1e-12, at 50 random states."""
    chain = gripper_chain
    m = closure.random_within_limits(chain, chain.spec.limits, 50, seed=5)
    pm = pin_engine.build_model(chain.spec, GRAVITY_W)
    model = pm.model
    for loop in chain.spec.loops:
        model = pin.transformJointIntoMimic(model, model.getJointId(loop.leader), model.getJointId(loop.follower),
                                            loop.ratio, loop.offset)
    tau, M = _projected(chain, m)
    tau_pin, M_pin = _reduced(model, chain, m)
    assert np.abs(tau - tau_pin).max() <= 1e-12 * np.abs(tau_pin).max()
    assert np.abs(M - M_pin).max() <= 1e-12 * np.abs(M_pin).max()


def test_the_graph_theory_coupling_torques_are_the_projections_multipliers(gripper_chain):
    """The first seed's method carries a coupling as a torque pair on its two joints, solved with the
    passive (follower) joints' equations from its incidence matrices; its multipliers and actuated
    torques equal those of the constraint Jacobian route (closure.multipliers on Pinocchio's tree
    torques) to 1e-12 of their size, at 30 random consistent states."""
    from harness.papers.graph_theory_2021.closed import closed_chain_inverse
    from harness.papers.graph_theory_2021.dynamics import build_graph_model

    chain = gripper_chain
    m = closure.random_within_limits(chain, chain.spec.limits, 30, seed=7)
    graph = closed_chain_inverse(chain.spec, build_graph_model(chain.spec, GRAVITY_W), m.q, m.qd, m.qdd)
    tau = pin_engine.rnea(pin_engine.build_model(chain.spec, GRAVITY_W), m.q, m.qd, m.qdd).tau
    tau_a = closure.actuated_torques(m.G, tau)
    lam = closure.multipliers(chain, m.J, tau, tau_a)
    assert np.abs(graph.lam - lam).max() <= 1e-12 * np.abs(lam).max()
    assert np.abs(graph.tau[:, list(chain.actuated)] - tau_a).max() <= 1e-12 * np.abs(tau_a).max()
    assert np.abs(graph.tau[:, list(chain.passive)]).max() == 0.0


@pytest.fixture(scope="module")
def gripper_chain():
    return closure.ClosedChain.of(load_spec(MODELS / "gripper.toml"))


def test_a_coupling_stated_in_the_model_file_is_the_mimic_one(tmp_path):
    """`[[closed_chain.loops]] type = "joint"` on a URDF without <mimic> reads as the same coupling."""
    (tmp_path / "a").mkdir(), (tmp_path / "b").mkdir()
    chain = _arm(tmp_path / "a")
    stated = _arm(tmp_path / "b", mimic="", model=(
        '[closed_chain]\nactuated = ["shoulder"]\n[[closed_chain.loops]]\ntype = "joint"\nfollower = "elbow"\n'
        'leader = "shoulder"\nratio = -0.7\noffset = 0.2\n'))
    ours, theirs = chain.spec.loops[0], stated.spec.loops[0]
    assert (theirs.kind, theirs.follower, theirs.leader, theirs.ratio, theirs.offset) == (
        ours.kind, ours.follower, ours.leader, ours.ratio, ours.offset)


def test_a_mimic_of_no_moving_joint_is_a_joint_of_its_own_said(tmp_path):
    """A <mimic> naming a joint the URDF does not move (a published hand's misspelt reference): nothing to
    couple to, so the joint is the robot's own, said in one note."""
    assert _arm(tmp_path, '<mimic joint="wrist"/>') is None
    notes = load_spec(tmp_path / "arm.toml").notes
    assert notes == ("joint 'elbow' mimics 'wrist', which is not a moving joint of the URDF: read as a joint of its "
                     "own",)


def test_a_mimic_joint_can_be_read_as_a_joint_of_its_own_and_is_then_said_so(tmp_path):
    """[urdf] mimic = "independent": the follower moves as any joint (no loop), said in the model's notes;
    a mimic joint listed in `fixed` is held, with nothing to say."""
    (tmp_path / "a").mkdir(), (tmp_path / "b").mkdir()
    assert _arm(tmp_path / "a", model='mimic = "independent"\n') is None
    notes = load_spec(tmp_path / "a" / "arm.toml").notes
    said = "joint 'elbow' mimics 'shoulder' in the URDF: read as a joint of its own"
    assert [n.startswith(said) for n in notes] == [True]
    assert _arm(tmp_path / "b", model='fixed = ["elbow"]\n') is None
    assert not load_spec(tmp_path / "b" / "arm.toml").notes


COUPLING_REFUSALS = {
    "a mimic of a fixed joint": (MIMIC, 'fixed = ["shoulder"]\n', "urdf.urdf", "which [urdf] fixed holds at 0"),
    "a zero multiplier": ('<mimic joint="shoulder" multiplier="0"/>', "", "urdf.urdf",
                          "multiplier = 0 holds the joint"),
    "an unknown reading": (MIMIC, 'mimic = "ignored"\n', "urdf.mimic", "is not one of coupled, independent"),
    "a joint coupled to itself": ("", '[[closed_chain.loops]]\ntype = "joint"\nfollower = "elbow"\nleader = "elbow"\n',
                                  "closed_chain.loops[0].leader", "couples joint 'elbow' to itself"),
    "a zero ratio": ("", '[[closed_chain.loops]]\ntype = "joint"\nfollower = "elbow"\nleader = "shoulder"\nratio = 0\n',
                     "closed_chain.loops[0].ratio", "is 0"),
    "an unknown follower": ("", '[[closed_chain.loops]]\ntype = "joint"\nfollower = "wrist"\nleader = "shoulder"\n',
                            "closed_chain.loops[0].follower", "wrist"),
}


@pytest.mark.parametrize("case", COUPLING_REFUSALS)
def test_a_coupling_that_cannot_be_read_is_refused_in_one_line(tmp_path, case):
    mimic, model, key, message = COUPLING_REFUSALS[case]
    if model.startswith("[["):
        model = '[closed_chain]\nactuated = ["shoulder"]\n' + model
    with pytest.raises(InputError) as err:
        _arm(tmp_path, mimic, model)
    assert err.value.key == key and message in str(err.value) and "\n" not in err.value.one_line()


def test_the_audit_judges_couplings_against_pinocchios_mimic_joints():
    """`harness audit` on the gripper: its tree as any robot's, and its two couplings through G against
    Pinocchio's own parse of the MJCF file with the followers made mimic joints (to 1e-12; ~1e-15)."""
    from harness.runner.audit import audit

    row = audit("gripper", MODELS / "gripper.toml")
    assert row.verdict == "agrees" and row.couplings == 2 and row.couplings_vs_pinocchio <= 1e-12
