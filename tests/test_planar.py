"""The second seed: the redundant planar manipulator in two designs (DH models, thin rods, a point
mass), its claims, and the audit of its printed inertia matrix."""

from __future__ import annotations

import numpy as np
import pytest

from harness.engines.pinocchio import build_model, crba
from harness.model.load import dh_transform, load_spec
from harness.papers.yahya2012.audit import audit_inertia_matrix, corrected_M12, dh_symbols, printed_inertia_matrix
from tests.conftest import MODELS, SCENARIOS, copy_gate_sets, results_of

DESIGNS = ("conventional", "proposed")
# the paper's Table 2, grams -> kg
MASSES = {"conventional": [1.5, 2.26, 2.22, 2.18, 2.14, 0.6], "proposed": [1.5, 2.26, 0.72, 0.68, 0.64, 0.6]}


@pytest.mark.parametrize("design", DESIGNS)
def test_dh_model_is_the_papers_table_1_and_2(design):
    spec = load_spec(MODELS / f"planar6_{design}.toml")
    assert [b.mass for b in spec.bodies] == MASSES[design]
    l, d1, _ = dh_symbols(spec)
    np.testing.assert_array_equal(l, [0.19, 0.18, 0.17, 0.16, 0.15])
    assert d1 == 0.21
    # frames chained by hand from the DH rows at q = 0 give the joint axes and rod centres
    T = np.eye(4)
    for body, joint, (alpha, a, d, theta) in zip(spec.bodies, spec.joints, spec.dh, strict=True):
        np.testing.assert_allclose(joint.axis_W0, T[:3, 2], atol=1e-15)
        np.testing.assert_allclose(joint.p_W0, T[:3, 3], atol=1e-15)
        T = T @ dh_transform(alpha, a, d, theta)
        np.testing.assert_allclose(body.p_W_com0, T[:3, 3] - a / 2 * T[:3, 0], atol=1e-15)
        np.testing.assert_allclose(body.principal_inertia, [0, 1, 1] * np.array(body.mass * a**2 / 12), atol=1e-18)
    # joint 1 about the vertical, joints 2..6 about one horizontal direction
    np.testing.assert_allclose(spec.joints[0].axis_W0, [0, 0, 1], atol=1e-15)
    for joint in spec.joints[2:]:
        np.testing.assert_allclose(joint.axis_W0, spec.joints[1].axis_W0, atol=1e-15)


def test_a_rod_link_needs_a_length(tmp_path, capsys):
    from harness.cli import main

    text = (MODELS / "planar6_proposed.toml").read_text().replace("a = 0.19", "a = 0.0")
    (tmp_path / "models").mkdir()
    (tmp_path / "scenarios").mkdir()
    copy_gate_sets(tmp_path / "scenarios")
    (tmp_path / "models" / "planar6_proposed.toml").write_text(text)
    (tmp_path / "scenarios" / "s.toml").write_text(
        (SCENARIOS / "planar6_case1_conventional.toml").read_text().replace("planar6_conventional", "planar6_proposed"))
    assert main(["run", str(tmp_path / "scenarios" / "s.toml"), "--out", str(tmp_path / "out")]) == 2
    assert "dh.links.L2.a" in capsys.readouterr().err


CASES = [f"planar6_case{c}_{d}" for c in (1, 2) for d in DESIGNS]


@pytest.mark.slow  # four whole scenarios, 2 to 3 s each (their gates run in .ci/run as well)
@pytest.mark.parametrize("name", CASES)
def test_torques_agree_three_ways_and_joints_3_to_6_share_one_angle(run_scenario, name):
    out = run_scenario(SCENARIOS / f"{name}.toml")
    torques = results_of(out)["torques"]
    for pair in ("graph_vs_pinocchio", "graph_vs_mujoco", "pinocchio_vs_mujoco"):
        assert torques[pair]["max_rel_error"] <= 1e-9, pair
    q = out.recording.q
    for k in (3, 4, 5):
        np.testing.assert_allclose(q[:, k], q[:, 2], atol=1e-9)


@pytest.mark.slow  # a few seconds: a whole pipeline or a subprocess
@pytest.mark.parametrize("case", (1, 2))
def test_the_papers_claims_are_checked_with_their_numbers(run_scenario, case):
    """Claim 1 follows from physics (link 6 is the same in both designs and moves the same way);
    claims 2 and 3 are the paper's, and hold in both cases. The shared motor's torque is the
    sum of the torques of the joints it drives (virtual work at one common speed)."""
    out = run_scenario(SCENARIOS / f"planar6_case{case}_proposed.toml")
    dc = out["design_comparison"]
    equal, fewer, motor = dc["claims"]
    assert equal["holds"] and equal["numbers"]["max_rel_difference"] <= 1e-9
    assert fewer["holds"] and fewer["numbers"]["equal_at"] == ["J6"] and not fewer["numbers"]["larger_at"]
    assert motor["holds"] and motor["numbers"]["peak_ratio"] < 1 and motor["numbers"]["rms_ratio"] < 1
    rec = out.recording
    np.testing.assert_allclose(dc["shared_motor"], rec.tau[:, 2:6].sum(axis=1), rtol=0, atol=1e-12)
    baseline = run_scenario(SCENARIOS / f"planar6_case{case}_conventional.toml").recording
    np.testing.assert_allclose(np.array(dc["conventional"]), baseline.tau, rtol=0, atol=1e-9)


@pytest.fixture(scope="module", params=DESIGNS)
def audit(request):
    spec = load_spec(MODELS / f"planar6_{request.param}.toml")
    return spec, audit_inertia_matrix(spec)


def test_correct_inertia_entries_cannot_depend_on_theta1_and_for_joints_2_to_6_not_on_theta2(audit):
    """Physics of the reference: turning the whole arm about the base axis changes no inertia, and
    joints 2..6 are parallel, so M_ij (i, j >= 2) depends on th3..th6 only."""
    _, a = audit
    for e in a["entries"]:
        assert not e["correct_depends_on_theta1"], e["entry"]
        row = int(e["entry"][1])  # entries of row 1 (M1j) depend on th2; no other does
        assert e["correct_depends_on_theta2"] == (row == 1), e["entry"]


def test_audit_verdicts(audit):
    """M11 agrees as printed; M13..M16 agree with their lost leading minus restored; M12 does not,
    but agrees once m2 and m3 trade places in its l1 and l2 terms; M22..M66 carry terms in th1 that
    the correct entries cannot have, and agree to round-off where those terms vanish (th1 = 0)."""
    _, a = audit
    verdict = {e["entry"]: e for e in a["entries"]}
    assert verdict["M11"]["verdict"] == "agrees"
    assert all(verdict[f"M1{j}"]["verdict"] == "agrees up to sign" for j in (3, 4, 5, 6))
    assert verdict["M12"]["verdict"] == "disagrees" and verdict["M12"]["max_rel_difference_negated"] > 1e-3
    assert a["corrections"][0]["entry"] == "M12" and a["corrections"][0]["max_rel_difference"] <= 1e-12
    lower = [f"M{i}{j}" for i in range(2, 7) for j in range(i, 7)]
    assert a["printed_depend_on_theta1_wrongly"] == lower
    for name in lower:
        assert verdict[name]["verdict"] == "disagrees"
        assert verdict[name]["max_rel_difference_at_theta1_zero"] <= 1e-12, name
    assert sorted(a["disagreeing"]) == sorted(["M12", *lower])


def test_printed_m66_is_the_rod_about_its_end_where_th1_terms_vanish():
    """An independent value: link 6 turning about joint 6 is a rod about its end, m6 l5^2 / 3."""
    spec = load_spec(MODELS / "planar6_conventional.toml")
    l, d1, m = dh_symbols(spec)
    th = np.random.default_rng(3).uniform(-3, 3, size=(20, 6))
    th[:, 0] = 0.0
    np.testing.assert_allclose(printed_inertia_matrix(th, l, d1, m)[:, 5, 5], m[5] * l[4] ** 2 / 3, rtol=1e-14)
    pm = build_model(spec, np.zeros(3))
    np.testing.assert_allclose(corrected_M12(th, l, d1, m), crba(pm, th)[:, 0, 1], rtol=0, atol=1e-14)
