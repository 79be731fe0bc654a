"""How the reference engine integrates a motion: integrator, time step and the drive's tracking
bandwidth (a scenario's `[simulation]` table). Settings only: importing it loads no engine."""

from __future__ import annotations

from dataclasses import dataclass

INTEGRATORS = ("RK4", "Euler", "implicitfast")
EVALUATIONS_PER_STEP = {"RK4": 4, "Euler": 1, "implicitfast": 1}  # of the dynamics, each calling the drive


@dataclass(frozen=True)
class Simulation:
    """How the reference engine integrates the motion.

    The joints are driven by computed torque (inverse dynamics of the prescribed acceleration)
    with a critically damped correction of bandwidth `tracking_bandwidth` rad/s on the tracking
    error: q''_cmd = q''_d + 2 w (q'_d - q') + w^2 (q_d - q).
    """

    integrator: str = "RK4"
    timestep: float = 5e-4
    tracking_bandwidth: float = 20.0
