"""Accuracy gates: data in each scenario file, checked against results.json.

    [[gates]]
    metric = "torques.graph_vs_pinocchio.max_rel_error"   # dotted path into results.json
    limit = 1e-9
    direction = "at_most"                                 # or "at_least"; default at_most
    name = "graph torques agree with Pinocchio"           # optional; default the metric

Gates fail closed: a metric that is missing, not a number, or not finite fails its gate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from harness.tomlio import Table

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


def lookup(results: dict, metric: str):
    """The value at a dotted path (list elements by index), or None where there is none."""
    node = results
    for part in metric.split("."):
        if isinstance(node, dict) and part in node:
            node = node[part]
        elif isinstance(node, list) and part.isdigit() and int(part) < len(node):
            node = node[int(part)]
        else:
            return None
    return node


def check(gates: tuple[Gate, ...] | list[Gate], results: dict) -> tuple[list[dict], bool]:
    """One row per gate with the value found, and whether every gate passed."""
    rows = []
    for g in gates:
        value = lookup(results, g.metric)
        number = isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
        if not number:
            passed, reason = False, "missing" if value is None else f"not a finite number: {value!r}"
            value = None
        else:
            passed = value <= g.limit if g.direction == "at_most" else value >= g.limit
            reason = ""
        rows.append({**g.as_dict(), "value": value, "passed": bool(passed), "reason": reason})
    return rows, all(r["passed"] for r in rows)


def from_results(results: dict) -> tuple[Gate, ...]:
    """The gate definitions stored in a results.json."""
    return tuple(Gate(r["name"], r["metric"], r["limit"], r.get("direction", "at_most"))
                 for r in results.get("gates", []))
