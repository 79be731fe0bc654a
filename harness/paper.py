"""The papers' tables as data (harness/reference/), keyed by (body, parameter)."""

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
def reference_table(name: str) -> dict[tuple[str, str], float | None]:
    """A table of the paper: (body, parameter) -> value, None where the paper prints nothing."""
    text = files("harness").joinpath("reference", name).read_text()
    out: dict[tuple[str, str], float | None] = {}
    for row in csv.DictReader(text.splitlines()):
        for column, value in row.items():
            if column != "body":
                out[(row["body"], _parameter(column))] = float(value) if value.strip() else None
    return out
