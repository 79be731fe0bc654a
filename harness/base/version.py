"""The installed distribution's name and version (what results.json records of the harness). The
version is read from the installed metadata when first asked for (`harness.__version__`, or this
module's `__version__`): importlib.metadata costs about 40 ms, which `import harness` does not pay."""

from functools import cache

DISTRIBUTION = "robot-dynamics-harness"  # its name on the package index; imported and run as `harness`


@cache
def installed_version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version(DISTRIBUTION)
    except PackageNotFoundError:  # running from a source tree that is not installed
        return "unknown"


def __getattr__(name: str):
    if name == "__version__":
        return installed_version()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
