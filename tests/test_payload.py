"""A payload's ten inertial parameters from two runs of one motion, without and with it
(harness/stages/payload.py), against the payload as stated in its model file."""

from __future__ import annotations

import numpy as np
import pytest

from harness.api import run
from harness.model.load import load_spec
from tests.conftest import MODELS, SCENARIOS, results_of

# models/ur5_payload.toml: 2 kg at com, inertia about com (world axes at q = 0)
MASS, COM = 2.0, np.array([0.84725, 0.22915, 0.0145])
INERTIA = np.array([[0.0073, 0.0004, -0.0002], [0.0004, 0.0083, 0.0001], [-0.0002, 0.0001, 0.0023]])


def _stated(joint_point: np.ndarray) -> np.ndarray:
    """The payload's [m, m c, I_O] about the joint point, from the model file by hand (parallel axes)."""
    c = COM - joint_point
    I_O = INERTIA + MASS * (c @ c * np.eye(3) - np.outer(c, c))
    return np.array([MASS, *(MASS * c), I_O[0, 0], I_O[0, 1], I_O[1, 1], I_O[0, 2], I_O[1, 2], I_O[2, 2]])


@pytest.mark.slow  # a second or more: a whole pipeline, or processes
def test_the_payload_comes_back_from_ideal_data():
    """Ideal data: the ten parameters within 1e-6 of their kind's size (measured 1e-14), and they
    are the payload the model file states, moved to the wrist's joint point by the parallel-axis rule."""
    r = results_of(run(SCENARIOS / "ur5_payload.toml").output)["payload"]
    assert r["max_rel_error"] <= 1e-6
    point = load_spec(MODELS / "ur5.toml").inner_joint("wrist_3_link").p_W0
    got = np.array([p["identified"] for p in r["parameters"]])
    np.testing.assert_allclose(got, _stated(point), rtol=0, atol=1e-9)


@pytest.mark.slow  # a second or more: a whole pipeline, or processes
def test_under_torque_noise_each_parameter_is_within_four_standard_deviations(tmp_path):
    """1 % and 0.02 N m of noise on every torque of both runs: each identified parameter within
    four of its standard deviations of the truth (a seeded run; a Gaussian error passes four
    standard deviations once in 16 000)."""
    text = (SCENARIOS / "ur5_payload.toml").read_text()
    text = text.replace('model = "../models/ur5_payload.toml"', f'model = "{MODELS / "ur5_payload.toml"}"')
    text = text.replace('without = "ur5_sines.toml"', f'without = "{SCENARIOS / "ur5_sines.toml"}"')
    text = text.replace('gate_sets = ["gates/engines.toml", "gates/graph_theory_2021.toml"]', "")
    text = text.replace("[simulation]", "[measurement]\nseed = 4\n[measurement.noise.joint_torques]\n"
                                        "relative = 0.01\nabsolute = 0.02\n\n[simulation]", 1)
    text = text[:text.index("[model_under_test]")] + text[text.index("[payload]"):]
    (tmp_path / "s.toml").write_text(text)
    r = results_of(run(tmp_path / "s.toml").output)["payload"]
    for p in r["parameters"]:
        assert abs(p["identified"] - p["true"]) <= 4 * p["std"], p
