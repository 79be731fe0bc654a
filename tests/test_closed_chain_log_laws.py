"""A closed chain's log: the friction law, a filtered log and delays, on logs made here from the rigid
loops' exact torques (harness/identify/chain_law.py, harness/sources/log/closed.py; the logs and the
scenario text from tests/test_closed_chain_log.py). Apart from that module so that the two run beside
each other: each runs the whole pipeline several times."""

from __future__ import annotations

import pytest

from .conftest import MODELS
from .test_closed_chain_log import DURATION, RATE, SINES, TRUTH, _exact_log, _run, _scenario_text


@pytest.mark.slow  # a filtered closed-chain log run (1.1 s)
def test_a_filtered_log_s_friction_columns_are_filtered_as_its_torques_every_joint_s(tmp_path):
    """A 10 Hz zero-phase low-pass on the exact log: the measured torques' Coulomb turns are spread by the
    filter, and so are every joint's Coulomb columns, the passive joints' from their full-rate velocities
    through G (harness/sources/log/closed.py). The law search finds v_c within 5 % and the fit stays within
    5e-4 of the truth's torques on the span it never saw (measured 2.2e-5, where the filtered torques
    themselves are 5.9e-3 from the truth's at the filtered states); with every column left unfiltered it
    was 3.8e-3."""
    _exact_log(tmp_path / "log.csv", TRUTH, SINES, RATE, DURATION)
    (tmp_path / "s.toml").write_text(_scenario_text(tmp_path / "log.csv", "cutoff = 10.0"))
    code, results = _run(tmp_path / "s.toml", tmp_path / "out")
    assert code == 0
    li = results["log_identification"]
    truth = li["truth"]["validation_rel_error"]
    assert truth["consistent"] <= 5e-4 and truth["least squares"] <= 5e-4
    assert abs(li["friction_law"]["coulomb_velocity"]["elbow"] / 0.02 - 1) <= 0.05


FOURBAR_TRUTH = """
[model]
name = "fourbar_friction"
[mjcf]
file = "{xml}"
[joints.crank]
armature = 0.02
viscous = 0.3
coulomb = 0.5
offset = 0.1
coulomb_velocity = 0.05
[joints.rocker]
viscous = 0.2
coulomb = 0.3
coulomb_velocity = 0.05
"""


@pytest.mark.parametrize("duration", [6.0, 12.0])
def test_a_four_bar_s_one_torque_channel_gives_its_friction_law_with_a_gap_and_a_filter(tmp_path, duration):
    """The four-bar's crank log (one torque channel, 18 base parameters with every joint's friction,
    condition number 1e4) at 200 Hz with 1 % torque noise, a 0.3 s gap, a 15 Hz low-pass: the smoothing
    velocity found within 5 % of the truth's 0.05 rad/s, estimated with the parameters (of 6 s a choice
    by the folds' held-out error, which extrapolate, took 0.024). Of 12 s the held-out torques are within
    0.5 % of the truth's (measured 0.10 % and 0.16 %, the filtered torques themselves 1.7 % off); of 6 s
    they are 3 to 5 % off: one channel's 18 parameters from 4 s of motion extrapolate to the last 30 %."""
    (tmp_path / "truth.toml").write_text(FOURBAR_TRUTH.format(xml=MODELS / "fourbar.xml"))
    _exact_log(tmp_path / "log.csv", tmp_path / "truth.toml", (((3.0, 0.9), (1.0, 2.3), (0.5, 3.7)),), 200.0,
               duration, noise=0.01, cut=(2.5, 2.8))
    (tmp_path / "s.toml").write_text(_scenario_text(tmp_path / "log.csv", "cutoff = 15.0", "",
                                                    MODELS / "fourbar.toml", tmp_path / "truth.toml"))
    code, results = _run(tmp_path / "s.toml", tmp_path / "out")
    assert code == 0
    li = results["log_identification"]
    assert len(results["data"]["conditioning"]["segments"]["stretches"]) == 2
    assert abs(li["friction_law"]["coulomb_velocity"]["crank"] / 0.05 - 1) <= 0.05
    truth = li["truth"]["validation_rel_error"]
    if duration >= 12.0:
        assert truth["consistent"] <= 0.005 and truth["least squares"] <= 0.005
