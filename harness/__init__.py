"""Validation harness for robot dynamic models against reference engines (MuJoCo, Pinocchio)."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("harness")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "unknown"
