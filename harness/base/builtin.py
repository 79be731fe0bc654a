"""The built-in models, scenarios and gate sets, shipped inside the package (harness/data/), and how
a name given on the command line or to the API finds a file: a path as given; else, for a bare
name, `./scenarios/NAME.toml` and `./NAME.toml` in the current directory, then the package's own."""

from __future__ import annotations

from pathlib import Path

DATA = Path(__file__).resolve().parent.parent / "data"


def resolve(arg: str | Path, kind: str = "scenarios") -> Path:
    """A file for `arg`: the path itself where it exists or is not a bare name; else the first of
    ./KIND/NAME.toml, ./NAME.toml and the package's KIND/NAME.toml that exists (the path as given
    when none does, so that the error names what was asked for)."""
    path = Path(arg)
    if path.exists() or path.suffix or len(path.parts) != 1:
        return path
    for candidate in (Path(kind) / f"{arg}.toml", Path(f"{arg}.toml"), DATA / kind / f"{arg}.toml"):
        if candidate.is_file():
            return candidate
    return path


def listing(kind: str) -> list[tuple[str, list[Path]]]:
    """(where, files) for ./KIND and the package's KIND, the local folder first; a folder that does
    not exist is left out, and so is the package's when it is the local one."""
    out = []
    local = Path(kind)
    if local.is_dir():
        out.append((f"{kind}/", sorted(local.glob("*.toml"))))
    if not (local.is_dir() and local.resolve() == (DATA / kind).resolve()):
        out.append((f"{kind} built in ({DATA / kind})", sorted((DATA / kind).glob("*.toml"))))
    return out
