"""A paper's tables as data (the reference/ folder of its package), keyed by (body, parameter)."""

from __future__ import annotations

import csv
from functools import cache
from importlib.resources import files

_UNITS = ("_kgm2", "_kg", "_m")


def _parameter(column: str) -> str:
    for unit in _UNITS:
        if column.endswith(unit):
            return column[: -len(unit)]
    return column


@cache
def reference_table(package: str, name: str) -> dict[tuple[str, str], float | None]:
    """A table of the paper: (body, parameter) -> value, None where the paper prints nothing."""
    text = files(package).joinpath("reference", name).read_text()
    out: dict[tuple[str, str], float | None] = {}
    for row in csv.DictReader(text.splitlines()):
        for column, value in row.items():
            if column != "body":
                out[(row["body"], _parameter(column))] = float(value) if value.strip() else None
    return out


def has_reference_table(package: str, name: str) -> bool:
    """Whether `name` is a file of the package's reference/ folder (never a path out of it)."""
    return "/" not in name and "\\" not in name and name not in ("", ".", "..") and \
        files(package).joinpath("reference", name).is_file()
