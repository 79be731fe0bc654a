"""Accuracy gates: data in each scenario file, checked against results.json.

    [[gates]]
    metric = "torques.graph_vs_pinocchio.max_rel_error"   # dotted path into results.json
    limit = 1e-9
    direction = "at_most"                                 # or "at_least"; default at_most
    name = "graph torques agree with Pinocchio"           # optional; default the metric

A gate set is a file of gates that many scenarios share, included with `[scenario] gate_sets`:

    [gate_set]
    description = "..."
    [[gates]]
    ...

Gates fail closed: a metric that is null, not a number, or not finite fails its gate. A metric
that names no result at all is bad input (a misspelt path must not pass or fail quietly).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from harness.tomlio import InputError, Table

DIRECTIONS = ("at_most", "at_least")


@dataclass(frozen=True)
class Gate:
    name: str
    metric: str
    limit: float
    direction: str = "at_most"

    def as_dict(self) -> dict:
        return {"name": self.name, "metric": self.metric, "limit": self.limit, "direction": self.direction}


def read_gates(tables: list[Table]) -> tuple[Gate, ...]:
    gates = []
    for t in tables:
        metric = t.string("metric")
        if not metric or any(not part for part in metric.split(".")):
            raise t.error("metric", f"{metric!r} is not a dotted path into results.json")
        gate = Gate(t.string("name", default=metric), metric, t.number("limit"),
                    t.string("direction", default="at_most", choices=DIRECTIONS))
        t.finish()
        gates.append(gate)
    return tuple(gates)


MISSING = object()  # what lookup returns for a path that names nothing


def lookup(results: dict, metric: str, missing=None):
    """The value at a dotted path (list elements by index), or `missing` where there is none."""
    node = results
    for part in metric.split("."):
        if isinstance(node, dict) and part in node:
            node = node[part]
        elif isinstance(node, list) and part.isdigit() and int(part) < len(node):
            node = node[int(part)]
        else:
            return missing
    return node


def unknown_metrics(gates, results: dict) -> list[int]:
    """Indices of the gates whose metric names no result."""
    return [i for i, g in enumerate(gates) if lookup(results, g.metric, MISSING) is MISSING]


def verdict(gates, results: dict, source) -> dict:
    """results with the verdict: `passed` and one row per gate, first in the file. A gate whose
    metric names no result is an InputError naming `source` and the gate."""
    bad = unknown_metrics(gates, results)
    if bad:
        g = gates[bad[0]]
        raise InputError(source, f"gates: {g.name}", f"metric {g.metric!r} names no result of this run")
    rows, passed = check(gates, results)
    head = {"schema": results.get("schema"), "passed": passed, "gates": rows}
    return {**head, **{k: v for k, v in results.items() if k not in head}}


def check(gates: tuple[Gate, ...] | list[Gate], results: dict) -> tuple[list[dict], bool]:
    """One row per gate with the value found, and whether every gate passed."""
    rows = []
    for g in gates:
        value = lookup(results, g.metric)
        number = isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
        if not number:
            passed, reason = False, "no value (nothing was evaluated)" if value is None else \
                f"not a finite number: {value!r}"
            value = None
        else:
            passed = value <= g.limit if g.direction == "at_most" else value >= g.limit
            reason = ""
        rows.append({**g.as_dict(), "value": value, "passed": bool(passed), "reason": reason})
    return rows, all(r["passed"] for r in rows)


def from_results(results: dict, source) -> tuple[Gate, ...]:
    """The gate definitions stored in a results.json, validated: a results file without gates, or
    with a gate row that is not complete, is bad input."""
    rows = results.get("gates")
    if not isinstance(rows, list) or not rows:
        raise InputError(source, "gates", "no gates in this results file (nothing to check cannot pass)")
    out = []
    for i, r in enumerate(rows):
        if not isinstance(r, dict):
            raise InputError(source, f"gates[{i}]", "expected an object")
        t = Table({k: r[k] for k in ("name", "metric", "limit", "direction") if k in r}, source, f"gates[{i}]")
        out.extend(read_gates([t]))
    return tuple(out)
