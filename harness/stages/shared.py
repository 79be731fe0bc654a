"""What several stages share of a bench scenario's joint-torque identification: its
`[torque_identification]` settings and the structural base parameters it is judged in."""

from __future__ import annotations

from dataclasses import dataclass

from harness.engines.pinocchio import build_model
from harness.identify.torque_id import structural_base
from harness.sources.bench import Setup


@dataclass(frozen=True, eq=False)
class TorqueConfig:
    """`[torque_identification]`: the trajectory the identified model is validated on (another
    scenario of the same robot), and whether each joint's rotor inertia, viscous and Coulomb friction
    and offset are identified with the bodies' parameters."""

    validation: Setup
    friction: bool
    rows: str | None = None  # a moving floating base's fit: "base" or "all" (harness/identify/floating_id.py)
    consistent: bool = False  # and its physically consistent fit too


def torque_config(scenario) -> TorqueConfig | None:
    """The scenario's `[torque_identification]`, None without one."""
    return getattr(scenario, "configs", {}).get("torque_identification")


def with_friction(scenario) -> bool:
    """Whether the scenario's joint-torque fits identify the joints' friction and rotor inertia."""
    config = torque_config(scenario)
    return config is not None and config.friction


def families_refused(robot, fit: str) -> str | None:
    """Why `fit` (a fit with the plain law's four drive columns alone, "the estimators fit") cannot take this
    robot: its drives whose law has a friction family's terms (harness/model/friction.py, FAMILIES), as
    "drive (family)"; None where none has."""
    families = [f"{d} ({f.family})" for d, f in zip(robot.drive_names, robot.frictions, strict=True)
                if f.family != "viscous_coulomb"]
    return (f"{fit} each drive's rotor inertia, viscous and Coulomb friction and offset, not a friction family's "
            f"terms: {', '.join(families)}") if families else None


def structural_base_of(ctx):
    """The scenario's structural base parameters (harness/identify/torque_id.py), found once per run."""
    sc = ctx.scenario
    friction = with_friction(sc)
    return ctx.once(("structural base parameters", friction),
                    lambda: structural_base(build_model(sc.robot, sc.gravity_W), sc.robot.limits,
                                            with_friction=friction, chain=chain_of(sc.robot)))


def chain_of(robot):
    """The robot's closed chain (harness/model/closure.py), None for an open tree."""
    if not robot.loops:
        return None
    from harness.model.closure import ClosedChain

    return ClosedChain.of(robot)
