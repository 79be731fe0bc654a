"""An output folder holds one run's files, whole: never two runs' files side by side.

A command that writes a folder (`harness run`, `sweep`, `audit`) writes every file into a staging
folder beside it, lists them in a manifest (MANIFEST_FILE: the run's id, what wrote it, and each
file's SHA-256), and only then puts them in place, under a lock on the parent folder, so that two
commands writing into one folder at once leave one of them whole. What stood there is replaced only
when it is a run of the same kind and name (a scenario run again), or when the user says so
(`--replace`); a folder holding files no run listed is never touched. Each subfolder a run writes
(identified/) carries a manifest of its own, so that it still says which run wrote it when it is
taken on its own: `verify` refuses a folder whose files are not exactly those its manifest lists.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import shutil
import tempfile
import uuid
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

from harness.base.tomlio import MAX_TOML_BYTES, InputError, read_bounded

MANIFEST_FILE = "manifest.json"
SCHEMA = {"name": "harness-manifest", "version": 1}
WRITTEN_BEFORE = ("results.json", "sweep.json", "audit.json")  # what a run wrote before runs carried a manifest


def new_id() -> str:
    """A run's id: 32 hexadecimal digits, drawn at random (uuid4)."""
    return uuid.uuid4().hex


@dataclass(frozen=True)
class Manifest:
    """Which run wrote a folder (`run`: its id; `kind`: run, sweep or audit; `name`: its scenario) and
    every file it wrote there, {path relative to the folder, with '/': SHA-256 in hexadecimal}."""

    run: str
    kind: str
    name: str
    files: dict[str, str]

    def text(self) -> str:
        return json.dumps({"schema": SCHEMA, "run": self.run, "kind": self.kind, "name": self.name,
                           "files": self.files}, indent=1) + "\n"

    @classmethod
    def read(cls, folder: Path) -> Manifest | None:
        """The manifest of `folder`, None where it has none; one that is not a manifest is refused."""
        path = folder / MANIFEST_FILE
        if not path.is_file():
            return None
        try:
            data = json.loads(read_bounded(path, MAX_TOML_BYTES).decode("utf-8"))
            if data.get("schema", {}).get("name") != SCHEMA["name"]:
                raise ValueError("not a harness manifest")
            files = data["files"]
            if not (isinstance(files, dict) and all(isinstance(v, str) for v in files.values())):
                raise ValueError("its files are not a table of SHA-256 digests")
            return cls(str(data["run"]), str(data["kind"]), str(data["name"]), dict(files))
        except (ValueError, KeyError, TypeError, AttributeError) as exc:
            raise InputError(path, "", f"not a manifest a harness run wrote ({exc})") from None


def sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        while piece := f.read(1 << 20):
            digest.update(piece)
    return digest.hexdigest()


def _files(folder: Path) -> list[str]:
    """Every file under `folder` but its own manifest, relative, with '/'."""
    return sorted(p.relative_to(folder).as_posix() for p in folder.rglob("*")
                  if p.is_file() and p.relative_to(folder).as_posix() != MANIFEST_FILE)


def seal(folder: Path, run: str, kind: str, name: str) -> None:
    """Write the manifests of a folder a run has filled: each subfolder's first (its files), then the
    folder's own (every file, the subfolders' manifests included)."""
    for sub in sorted(p for p in folder.iterdir() if p.is_dir()):
        _write_manifest(sub, run, kind, name)
    _write_manifest(folder, run, kind, name)


def _write_manifest(folder: Path, run: str, kind: str, name: str) -> None:
    files = {f: sha256(folder / f) for f in _files(folder)}
    (folder / MANIFEST_FILE).write_text(Manifest(run, kind, name, files).text())


def verify(folder: Path) -> Manifest:
    """The manifest of a folder a run wrote, once every file it lists is there as written and nothing
    else is; InputError naming the first file that is not."""
    manifest = Manifest.read(folder)
    if manifest is None:
        raise InputError(folder / MANIFEST_FILE, "", "missing: not a folder a harness run wrote whole (put "
                                                     "together by hand, or written before runs carried a manifest): "
                                                     "run it again")
    on_disk = _files(folder)
    unlisted = [f for f in on_disk if f not in manifest.files]
    if unlisted:
        raise InputError(folder / unlisted[0], "", f"not written by run {manifest.run} ({manifest.kind} of "
                                                   f"{manifest.name!r}), whose files this folder holds")
    for f, digest in manifest.files.items():
        if not (folder / f).is_file():
            raise InputError(folder / f, "", f"missing: run {manifest.run} ({manifest.kind} of {manifest.name!r}) "
                                             "wrote it")
        if sha256(folder / f) != digest:
            raise InputError(folder / f, "", f"changed since run {manifest.run} ({manifest.kind} of "
                                             f"{manifest.name!r}) wrote it (its SHA-256 is not the manifest's)")
    return manifest


@dataclass(frozen=True)
class Held:
    """What an output folder holds: a run (`kind`, `name`; `entries`, the names in it that run wrote)
    and `foreign`, the names in it no run listed."""

    kind: str
    name: str
    entries: tuple[str, ...]
    foreign: tuple[str, ...]


def held(out: Path, flag: str) -> Held | None:
    """What `out` holds; None where it does not exist or is empty."""
    if not out.exists():
        return None
    if not out.is_dir():
        raise InputError(out, flag, "exists and is not a folder")
    names = sorted(p.name for p in out.iterdir())
    if not names:
        return None
    manifest = Manifest.read(out)
    if manifest is None:
        return Held("", "", (), tuple(names))
    listed = {f.split("/")[0] for f in manifest.files} | {MANIFEST_FILE}
    return Held(manifest.kind, manifest.name, tuple(n for n in names if n in listed),
                tuple(n for n in names if n not in listed))


def claim(out: Path, kind: str, name: str, replace: bool, flag: str = "--out") -> None:
    """Refuse, before any work, an output folder this run may not write: one holding files no run
    wrote (never replaced), or another run's (replaced only with `replace`)."""
    there = held(out, flag)
    if there is None:
        return
    if there.foreign:
        shown = ", ".join(there.foreign[:3]) + (", ..." if len(there.foreign) > 3 else "")
        earlier = next((f for f in WRITTEN_BEFORE if f in there.foreign), None) if not there.kind else None
        why = (f"a run written before runs carried a manifest (its {earlier}): remove it, or give a new or empty "
               "folder" if earlier else f"files no harness run wrote ({shown}): give a new or empty folder (a run "
               "replaces only what a run wrote)")
        raise InputError(out, flag, f"holds {why}")
    if (there.kind, there.name) != (kind, name) and not replace:
        raise InputError(out, flag, f"holds a {there.kind} of {there.name!r}: give another folder, or --replace to "
                                    f"replace it with this {kind} of {name!r}")


@contextlib.contextmanager
def _locked(folder: Path) -> Iterator[None]:
    """An exclusive lock on `folder` (flock on the folder itself: nothing is written beside it) while
    the block runs; where locks do not exist, none."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover  (not POSIX)
        yield
        return
    fd = os.open(folder, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)  # closing it releases the lock


def place(out: Path, files: dict[str, Callable[[Path], object]], kind: str, name: str, run: str,
          replace: bool = False, flag: str = "--out") -> None:
    """Write `files` ({relative path: writer of that path}) as run `run` (a `kind` of `name`) into
    `out`, whole: each into a staging folder beside `out`, the manifests sealed, then, under a lock on
    the parent folder, what `out` held of an earlier run moved out and the new files moved in (the
    manifest last). An InputError (the folder is another run's, or holds files no run wrote) or a
    failure to write leaves `out` as it was."""
    out = out.absolute()
    with staged(out, files) as staging:
        seal(staging, run, kind, name)
        with _locked(out.parent):
            claim(out, kind, name, replace, flag)  # again: another command may have written it meanwhile
            there = held(out, flag)
            out.mkdir(exist_ok=True)
            old = Path(tempfile.mkdtemp(prefix=f".{out.name}.replaced-", dir=out.parent))
            try:
                # the manifest out first and in last: the folder never claims files it lacks
                _move(out, old, sorted(there.entries if there else (), key=lambda e: e != MANIFEST_FILE))
                _move(staging, out, sorted((p.name for p in staging.iterdir()), key=lambda e: e == MANIFEST_FILE))
            except OSError:  # what was moved goes back: the earlier run whole, as it stood
                _move(out, staging, [p.name for p in out.iterdir()])
                _move(old, out, sorted((p.name for p in old.iterdir()), key=lambda e: e == MANIFEST_FILE))
                raise
            finally:
                shutil.rmtree(old, ignore_errors=True)


@contextlib.contextmanager
def staged(out: Path, files: dict[str, Callable[[Path], object]]) -> Iterator[Path]:
    """A staging folder beside `out` (its parent made where missing) holding `files` ({relative path:
    writer of that path}), removed with whatever is left in it after the block."""
    out.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f".{out.name}.staging-", dir=out.parent))
    try:
        for path, write in files.items():
            (staging / path).parent.mkdir(parents=True, exist_ok=True)
            write(staging / path)
        yield staging
    finally:
        shutil.rmtree(staging, ignore_errors=True)


def _move(source: Path, target: Path, entries: list[str]) -> None:
    for entry in entries:
        (source / entry).rename(target / entry)


def rewrite(folder: Path, entry: str, write: Callable[[Path], object]) -> None:
    """One file of a run's folder written again (`harness report` re-rendering report.html beside its
    results.json), its manifest's digest with it, under the folder's lock; a folder without a manifest,
    or whose manifest does not list the file, gets the file alone."""
    folder = folder.absolute()
    with _locked(folder.parent):
        manifest = Manifest.read(folder)
        fd, tmp = tempfile.mkstemp(prefix=f".{entry}.", dir=folder)
        os.close(fd)
        try:
            write(Path(tmp))
            os.replace(tmp, folder / entry)
        finally:
            if os.path.exists(tmp):
                os.unlink(tmp)
        if manifest is not None and entry in manifest.files:
            files = {**manifest.files, entry: sha256(folder / entry)}
            text = Manifest(manifest.run, manifest.kind, manifest.name, files).text()
            staged = folder / f".{MANIFEST_FILE}.new"
            staged.write_text(text)
            os.replace(staged, folder / MANIFEST_FILE)
