"""Which gates judge a plugin: a model under test or an identification method named in a scenario must be
judged by a gate on one of its metrics, or it would pass whatever it computes."""

from __future__ import annotations

from pathlib import Path

from harness.base.tomlio import InputError
from harness.runner.gates import Gate

RESERVED_NAMES = ("mujoco", "pinocchio", "harness_least_squares", "harness_consistent")


def check_names(path: Path, kind: str, entries, gates: tuple[Gate, ...], on_log: bool = False) -> None:
    """Each plugin's name used once, naming no reference engine, and judged by a gate."""
    names = [e.name for e in entries]
    for i, n in enumerate(names):
        if n in names[:i] or n in RESERVED_NAMES:
            raise InputError(path, f"{kind}.name", f"{n!r} is used twice, or names a reference engine or the "
                                                   "harness's own fit")
        unjudged(path, kind, n, gates, on_log)


def judging_metrics(kind: str, name: str, on_log: bool = False) -> tuple[str, ...]:
    """The metrics a gate can judge a model under test or an identification method by (`on_log`: a
    method on a measured log, judged on its validation span)."""
    if on_log:
        return (f"identification_methods.{name}.validation_rel_error",
                f"identification_methods.{name}.physical.inconsistent_links",
                f"identification_methods.{name}.truth.validation_rel_error (a bench log with its truth)")
    if kind == "model_under_test":
        return (f"torques.{name}_vs_mujoco.max_rel_error", f"torques.{name}_vs_pinocchio.max_rel_error",
                f"torques.{name}_random_vs_pinocchio.max_rel_error",
                f"torques.mass_matrix.{name}_vs_pinocchio.max_rel_error",
                f"torques.reactions.{name}_vs_mujoco.force.max_rel_error",
                f"torques.reactions.{name}_vs_mujoco.moment.max_rel_error",
                f"torques.floating.{name}_vs_pinocchio_max_rel_error (a floating base)",
                f"torques.floating.base_wrench_{name}_vs_mujoco_max_rel_error (a floating base the bench moves)")
    return (f"identification_methods.{name}.base_parameters.max_rel_error",
            f"identification_methods.{name}.validation.max_rel_error",
            f"identification_methods.{name}.validation.rms_rel_error")


def judged(kind: str, name: str, gates: tuple[Gate, ...]) -> bool:
    """Whether a gate judges the model under test or identification method `name`."""
    prefixes = ({f"torques.{name}_vs_", f"torques.{name}_random_vs_", f"torques.mass_matrix.{name}_vs_",
                 f"torques.reactions.{name}_vs_", f"torques.floating.{name}_vs_",
                 f"torques.floating.base_wrench_{name}_vs_"} if kind == "model_under_test"
                else {f"identification_methods.{name}."})
    return any(g.metric.startswith(p) for g in gates for p in prefixes)


def unjudged(path: Path, kind: str, name: str, gates: tuple[Gate, ...], on_log: bool = False) -> None:
    """A model under test or identification method that no gate judges would pass whatever it
    computes: refused, naming the metrics a gate could use."""
    if not judged(kind, name, gates):
        metrics = ", ".join(judging_metrics(kind, name, on_log))
        raise InputError(path, f"{kind}.name", f"{name!r} is judged by no gate, so it would pass whatever it "
                                               f"computes: add [[gates]] on {metrics}")
