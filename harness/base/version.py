"""The installed distribution's name and version (what results.json records of the harness)."""

from importlib.metadata import PackageNotFoundError, version

DISTRIBUTION = "robot-dynamics-harness"  # its name on the package index; imported and run as `harness`

try:
    __version__ = version(DISTRIBUTION)
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "unknown"
