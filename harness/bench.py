"""The MuJoCo test bench as a source of data: a scenario's robot moved along its motion and
recorded (the truth every stage is judged against)."""

from __future__ import annotations

from harness.engines.mujoco import simulate
from harness.recording import Recording
from harness.scenario import Scenario


def record(scenario: Scenario) -> Recording:
    """The scenario simulated in MuJoCo: `output_steps + 1` rows from t = 0."""
    return simulate(scenario.robot, scenario.gravity_W, scenario.prescribed, scenario.output_steps,
                    scenario.output_dt, scenario.simulation)
