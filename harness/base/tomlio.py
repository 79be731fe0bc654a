"""Validated reading of the project's TOML data files (models and scenarios).

Every error names the file and the dotted key at fault, so that the CLI can print one line
and exit with status 2. A `Table` remembers which keys were read: `Table.finish()` refuses
any key that nobody asked for, so a misspelt key is an error rather than a silent default.
"""

from __future__ import annotations

import math
import os
import stat
import tomllib
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

_MISSING = object()
MAX_MAGNITUDE = 1e15  # SI numbers beyond this overflow products (m l^2, rho R^2 l) long before they mean anything


class InputError(Exception):
    """Bad input: a file that cannot be read or a key whose value is not acceptable."""

    def __init__(self, file: Path | str, key: str, message: str):
        self.file = str(file)
        self.key = key
        self.message = message
        super().__init__(self.one_line())

    def __reduce__(self):  # from a worker process, with its three fields
        return type(self), (self.file, self.key, self.message)

    def one_line(self) -> str:
        where = f"{self.file}: {self.key}" if self.key else self.file
        return f"{where}: {self.message}"


MiB = 1 << 20
# No input is read beyond a stated size: an endless file (/dev/zero, a FIFO) or a wrong one is refused
# after this many bytes instead of filling the memory.
MAX_TOML_BYTES = 16 * MiB  # a model or scenario file: kilobytes in practice
MAX_XML_BYTES = 64 * MiB  # a URDF: the largest published ones are a few MiB
READ_PIECE = 16 * MiB  # a stream's bytes are read this many at a time
MAX_DATA_BYTES = 2048 * MiB  # a log, a recording or a results.json: 900,000 samples of a 7-joint arm take 0.5 GiB


def in_one_line(text: str) -> str:
    """A message of many lines (an engine's: "From file: ...\nin function: ...\nreason: ...") whole,
    on one line: its lines stripped and joined by "; "."""
    return "; ".join(line.strip() for line in str(text).splitlines() if line.strip())


def _read_stream(f, limit: int) -> bytes:
    """At most limit + 1 bytes of a stream, read READ_PIECE at a time."""
    content = bytearray()
    while len(content) <= limit and (piece := f.read(min(READ_PIECE, limit + 1 - len(content)))):
        content += piece
    return bytes(content)


def too_large(path: Path | str, limit: int) -> InputError:
    """The refusal of a file beyond `limit` bytes."""
    return InputError(path, "", f"larger than {limit // MiB} MiB, the most this kind of file may hold")


def read_bounded(path: Path | str, limit: int) -> bytes:
    """A file's bytes, refused (InputError naming the file) beyond `limit` bytes or when unreadable."""
    try:
        with open(path, "rb") as f:
            info = os.fstat(f.fileno())
            size = info.st_size if stat.S_ISREG(info.st_mode) else None
            if size is not None and size > limit:
                raise too_large(path, limit)
            # a regular file read at its size; a stream (a FIFO, a device) up to the limit in pieces, so
            # that no buffer of the limit's size is asked for (2 GiB for a log)
            content = f.read() if size is not None else _read_stream(f, limit)
    except FileNotFoundError:
        raise InputError(path, "", "file not found") from None
    except OSError as exc:
        raise InputError(path, "", f"cannot read file ({exc.strerror or exc})") from None
    if len(content) > limit:
        raise too_large(path, limit)
    return content


def read_toml(path: Path) -> dict[str, Any]:
    """Parse a TOML file, turning every failure into an `InputError` naming the file."""
    return parse_toml(read_toml_text(path), path)


def read_toml_text(path: Path) -> str:
    try:
        return read_bounded(path, MAX_TOML_BYTES).decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(path, "", f"cannot read file ({exc.__class__.__name__}: {exc})") from None


def parse_toml(text: str, path: Path) -> dict[str, Any]:
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(path, "", f"invalid TOML: {exc}") from None
    except RecursionError:
        raise InputError(path, "", "invalid TOML: nested too deeply") from None


@dataclass
class Table:
    """One TOML table with its file and dotted path, read key by key with validation."""

    data: dict[str, Any]
    file: Path
    path: str = ""

    def __post_init__(self) -> None:
        self._used: set[str] = set()

    def key(self, name: str) -> str:
        """The dotted key of `name` in this table; the table's own where `name` is empty."""
        return f"{self.path}.{name}" if self.path and name else self.path or name

    def error(self, name: str, message: str) -> InputError:
        return InputError(self.file, self.key(name), message)

    def either(self, first: str, second: str, meaning: str) -> str:
        """Which of two keys the table gives, when it must give exactly one (`meaning` says what
        each is, for the error: "robot (from example-robot-data) or file")."""
        if self.has(first) == self.has(second):
            raise self.error(first, f"give either {meaning}")
        return first if self.has(first) else second

    def has(self, name: str) -> bool:
        return name in self.data

    def _raw(self, name: str, default: Any) -> Any:
        self._used.add(name)
        if name in self.data:
            return self.data[name]
        if default is _MISSING:
            raise self.error(name, "missing key")
        return default

    def string(self, name: str, default: Any = _MISSING, choices: Sequence[str] | None = None) -> str:
        value = self._raw(name, default)
        if not isinstance(value, str):
            raise self.error(name, f"expected a string, got {value!r}")
        if choices is not None and value not in choices:
            raise self.error(name, f"{value!r} is not one of {', '.join(choices)}")
        return value

    def strings(self, name: str, choices: Sequence[str] | None, default: Any = _MISSING) -> tuple[str, ...]:
        """A non-empty list of strings, each one of `choices` (any string when None)."""
        value = self._raw(name, default)
        if not isinstance(value, list) or not value or not all(isinstance(v, str) for v in value):
            raise self.error(name, "expected a non-empty list of strings")
        for v in value:
            if choices is not None and v not in choices:
                raise self.error(name, f"{v!r} is not one of {', '.join(choices)}")
        return tuple(value)

    def boolean(self, name: str, default: Any = _MISSING) -> bool:
        value = self._raw(name, default)
        if not isinstance(value, bool):
            raise self.error(name, f"expected true or false, got {value!r}")
        return value

    def integer(self, name: str, default: Any = _MISSING, minimum: int | None = None) -> int:
        value = self._raw(name, default)
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.error(name, f"expected an integer, got {value!r}")
        if minimum is not None and value < minimum:
            raise self.error(name, f"must be at least {minimum}, got {value}")
        return value

    def number(self, name: str, default: Any = _MISSING, positive: bool = False,
               nonnegative: bool = False) -> float:
        value = self._raw(name, default)
        return _check_number(self, name, value, positive=positive, nonnegative=nonnegative)

    def vector(self, name: str, length: int | None = 3, default: Any = _MISSING,
               nonzero: bool = False) -> np.ndarray:
        value = self._raw(name, default)
        if not isinstance(value, list):
            raise self.error(name, f"expected a list of numbers, got {value!r}")
        if length is not None and len(value) != length:
            raise self.error(name, f"expected {length} numbers, got {len(value)}")
        out = np.array([_check_number(self, name, v) for v in value], dtype=float)
        if nonzero and not np.any(out):
            raise self.error(name, "must not be the zero vector")
        return out

    def rows(self, name: str, columns: int, default: Any = _MISSING) -> np.ndarray:
        """A list of lists of `columns` numbers each, as an array of shape (n, columns)."""
        value = self._raw(name, default)
        if not isinstance(value, list) or not all(isinstance(v, list) for v in value):
            raise self.error(name, f"expected a list of lists of {columns} numbers")
        sub = Table({str(i): v for i, v in enumerate(value)}, self.file, self.key(name))
        out = [sub.vector(str(i), length=columns) for i in range(len(value))]
        return np.array(out, dtype=float).reshape(len(value), columns)

    def table(self, name: str, default: Any = _MISSING) -> Table:
        value = self._raw(name, default)
        if not isinstance(value, dict):
            raise self.error(name, f"expected a table, got {value!r}")
        return Table(value, self.file, self.key(name))

    def tables(self, name: str) -> list[Table]:
        value = self._raw(name, _MISSING)
        if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
            raise self.error(name, "expected an array of tables ([[...]])")
        return [Table(v, self.file, f"{self.key(name)}[{i}]") for i, v in enumerate(value)]

    def remaining(self, exclude: Sequence[str] = ()) -> dict[str, Any]:
        """Every key not read yet (nor excluded), marked as read: a table that passes its other
        keys on (to a plugin) takes them as they are."""
        rest = {k: v for k, v in self.data.items() if k not in self._used and k not in exclude}
        self._used.update(rest)
        return rest

    def one_or_many(self, name: str) -> list[Table]:
        """A table ([name]) or an array of tables ([[name]]), as a list."""
        if isinstance(self.data.get(name), dict):
            return [self.table(name)]
        return self.tables(name)

    def finish(self) -> None:
        """Refuse every key that was not read: unknown keys are errors, not ignored."""
        unknown = sorted(set(self.data) - self._used)
        if unknown:
            raise self.error(unknown[0], "unknown key")


def _check_number(table: Table, name: str, value: Any, positive: bool = False,
                  nonnegative: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise table.error(name, f"expected a number, got {value!r}")
    try:
        value = float(value)
    except OverflowError:
        raise table.error(name, f"a number of {len(str(value))} digits is beyond double precision") from None
    if not math.isfinite(value):
        raise table.error(name, f"must be a finite number, got {value}")
    if abs(value) > MAX_MAGNITUDE:
        raise table.error(name, f"{value:g} is beyond {MAX_MAGNITUDE:g}: no quantity of a robot or its motion "
                                "is that large in SI units")
    if positive and value <= 0.0:
        raise table.error(name, f"must be positive, got {value}")
    if nonnegative and value < 0.0:
        raise table.error(name, f"must not be negative, got {value}")
    return value
