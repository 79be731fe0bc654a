"""The MuJoCo test bench as a source of data: a scenario's robot moved along its motion and
recorded (the truth every stage is judged against)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from harness.base.tomlio import InputError
from harness.engines.mujoco import Diverged, simulate
from harness.engines.recording import Recording

if TYPE_CHECKING:  # annotations only: the scenario is read, never built, here
    from harness.runner.scenario import Scenario


def record(scenario: Scenario) -> Recording:
    """The scenario simulated in MuJoCo: `output_steps + 1` rows from t = 0. A motion that drives
    the simulation to non-finite values is bad input, named by its joint and time."""
    try:
        return simulate(scenario.robot, scenario.gravity_W, scenario.prescribed, scenario.output_steps,
                        scenario.output_dt, scenario.simulation)
    except Diverged as exc:
        raise InputError(scenario.source, f"motion.{exc.joint}",
                         f"drives the simulation to non-finite values at t = {exc.t:.6g} s (MuJoCo: "
                         f"{exc.engine_message.split('. ')[0]}); a motion this fast or this far cannot be "
                         "simulated") from None
