"""The generic stages of a run, registered in the order they run. A study (a paper's package, or a
user's) adds its own stages through harness.base.plugins.Study; the pipeline treats both alike."""

from __future__ import annotations

from harness.base.plugins import Stage
from harness.stages.context import VALIDATION_SPAN, Context, Progress, recording_key

__all__ = ["LOG_TABLES", "VALIDATION_SPAN", "Context", "Progress", "core_stages", "log_stages", "recording_key"]

# the scenario tables of log_stages(), known without importing them (their modules import the convex solver
# and the optimiser: a simulated scenario does not pay for that)
LOG_TABLES = ("friction_law", "refinement", "floating_log")


def log_stages() -> tuple[Stage, ...]:
    """The stages of a measured log's run (harness/sources/log/)."""
    from harness.stages import floating_log, log_identification, log_methods, refinement

    return (floating_log.STAGE, log_identification.STAGE, log_methods.STAGE, refinement.STAGE)


def core_stages() -> tuple[Stage, ...]:
    from harness.stages import estimators, identification, limits, payload, torques

    return (limits.STAGE, torques.STAGE, identification.TORQUE_STAGE, identification.METHODS_STAGE, estimators.STAGE,
            payload.STAGE)
