"""Validation harness for robot dynamic models against reference engines (MuJoCo, Pinocchio).

Public API (harness/api.py): `run(scenario_path)` -> Result with `.passed`, `.gates`, `.results`;
`load_scenario(path)`, `load_model(path)`; the plugin protocols are in harness/plugins.py. Importing
this package loads neither an engine nor a paper's package: they load when a run needs them.
"""

from importlib.metadata import PackageNotFoundError, version

DISTRIBUTION = "robot-dynamics-harness"  # its name on the package index; imported and run as `harness`

try:
    __version__ = version(DISTRIBUTION)
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "unknown"

__all__ = ["InputError", "PluginError", "Result", "load_model", "load_scenario", "run"]


def __getattr__(name: str):
    if name in ("run", "load_model", "load_scenario", "Result", "GateRow"):
        from harness import api

        return getattr(api, name)
    if name == "InputError":
        from harness.tomlio import InputError

        return InputError
    if name == "PluginError":
        from harness.plugins import PluginError

        return PluginError
    raise AttributeError(f"module 'harness' has no attribute {name!r}")
