"""Validation harness for robot dynamic models against reference engines (MuJoCo, Pinocchio).

Public API (harness/api.py): `run(scenario_path)` -> Result with `.passed`, `.gates`, `.results`;
`load_scenario(path)`, `load_model(path)`; `identified_model(run folder)`, the model a log run exported,
with `joint_names` and `inverse_dynamics(q, qd, qdd)`; the plugin protocols are in harness/base/plugins.py. Importing
this package loads neither an engine nor a paper's package: they load when a run needs them.
"""

from harness.base.version import DISTRIBUTION

__all__ = ["DISTRIBUTION", "InputError", "PluginError", "Result", "__version__", "identified_model", "load_model",
           "load_scenario", "run"]


def __getattr__(name: str):
    if name == "__version__":  # read from the installed metadata when asked for (harness/base/version.py)
        from harness.base.version import installed_version

        return installed_version()
    if name in ("run", "load_model", "load_scenario", "Result", "GateRow", "identified_model", "IdentifiedModel"):
        from harness import api

        return getattr(api, name)
    if name == "InputError":
        from harness.base.tomlio import InputError

        return InputError
    if name == "PluginError":
        from harness.base.plugins import PluginError

        return PluginError
    raise AttributeError(f"module 'harness' has no attribute {name!r}")
