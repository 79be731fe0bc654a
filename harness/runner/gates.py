"""Accuracy gates: data in each scenario file, checked against results.json.

    [[gates]]
    metric = "torques.graph_vs_pinocchio.max_rel_error"   # dotted path into results.json
    limit = 1e-9
    direction = "at_most"                                 # or "at_least"; default at_most
    name = "graph torques agree with Pinocchio"           # optional; default the metric
    tolerance = 0.05                                      # optional: the relative change `harness compare`
                                                          # allows against a baseline (harness/runner/compare.py)

A gate set is a file of gates that many scenarios share, included with `[scenario] gate_sets`:

    [gate_set]
    description = "..."
    [[gates]]
    ...

Gates fail closed: a metric that is null, not a number, or not finite fails its gate. A metric
that names no result at all is bad input (a misspelt path must not pass or fail quietly). The one
exception is a metric under a result that says it was skipped (`{"skipped": "why"}`: an
identification method whose tool is not installed): its gate is reported as skipped, with the
reason, and counted apart; it neither passes nor fails the run. A metric under a result that says it
failed (`{"failed": "why"}`: an identification method on a log whose fit raised) fails its gate, with
the reason.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from harness.base.tomlio import InputError, Table

DIRECTIONS = ("at_most", "at_least")


@dataclass(frozen=True)
class Gate:
    name: str
    metric: str
    limit: float
    direction: str = "at_most"
    tolerance: float | None = None  # the relative change a comparison allows (None: by the gate's kind)

    def as_dict(self) -> dict:
        return {"name": self.name, "metric": self.metric, "limit": self.limit, "direction": self.direction,
                **({"tolerance": self.tolerance} if self.tolerance is not None else {})}


def read_gates(tables: list[Table]) -> tuple[Gate, ...]:
    gates = []
    for t in tables:
        metric = t.string("metric")
        if not metric or any(not part for part in metric.split(".")):
            raise t.error("metric", f"{metric!r} is not a dotted path into results.json")
        gate = Gate(t.string("name", default=metric), metric, t.number("limit"),
                    t.string("direction", default="at_most", choices=DIRECTIONS),
                    t.number("tolerance", nonnegative=True) if t.has("tolerance") else None)
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


def _said_on_path(results: dict, metric: str, key: str) -> str | None:
    """The reason a result on the metric's path gives under `key` ({"skipped": "why"}), or None."""
    node = results
    for part in metric.split("."):
        if isinstance(node, dict) and isinstance(node.get(key), str):
            return node[key]
        if isinstance(node, dict) and part in node:
            node = node[part]
        else:
            return None
    return None


def skipped_by(results: dict, metric: str) -> str | None:
    """Why the result a metric lies under was skipped (`{"skipped": "why"}` on its path), or None."""
    return _said_on_path(results, metric, "skipped")


def failed_by(results: dict, metric: str) -> str | None:
    """Why the result a metric lies under failed (`{"failed": "why"}` on its path: an identification
    method whose fit raised), or None."""
    return _said_on_path(results, metric, "failed")


def unknown_metrics(gates, results: dict) -> list[int]:
    """Indices of the gates whose metric names no result (one under a skipped or failed result is known)."""
    return [i for i, g in enumerate(gates)
            if lookup(results, g.metric, MISSING) is MISSING and skipped_by(results, g.metric) is None
            and failed_by(results, g.metric) is None]


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
        skipped = skipped_by(results, g.metric)
        if skipped is not None:
            rows.append({**g.as_dict(), "value": None, "passed": True, "skipped": True, "reason": f"skipped: {skipped}",
                         "where": ""})
            continue
        value = lookup(results, g.metric)
        failed = failed_by(results, g.metric)
        number = isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
        if failed is not None:
            passed, reason, value = False, f"failed: {failed}", None
        elif not number:
            passed, reason = False, "no value (nothing was evaluated)" if value is None else \
                f"not a finite number: {value!r}"
            value = None
        else:
            passed = value <= g.limit if g.direction == "at_most" else value >= g.limit
            reason = ""
        rows.append({**g.as_dict(), "value": value, "passed": bool(passed), "reason": reason,
                     "where": where(results, g.metric)})
    return rows, all(r["passed"] for r in rows)


def where(results: dict, metric: str) -> str:
    """Where a metric's worst case lies, read from the keys a stage writes beside it: for a metric
    `X_error` (or `X`), `X_parameter` (a base parameter, as the combination it stands for),
    `X_joint`, `X_entry` (of a matrix), `X_state` (a random state's index), `X_t` (seconds) and
    `X_likely` (the likely cause of a finding), e.g.
    `max_rel_joint` and `max_rel_t` beside `max_rel_error` give "elbow at t = 1.23 s". Empty where
    the stage wrote none."""
    head, _, leaf = metric.rpartition(".")
    node = lookup(results, head) if head else results
    if not isinstance(node, dict):
        return ""
    stem = leaf.removesuffix("_error")
    found = {k: node.get(f"{stem}_{k}") for k in ("parameter", "joint", "entry", "state", "t", "likely")}
    parts = []
    if isinstance(found["parameter"], str):
        parts.append(f"parameter {found['parameter']}")
    if isinstance(found["joint"], str):
        parts.append(found["joint"])
    if isinstance(found["entry"], str):
        parts.append(f"entry {found['entry']}")
    if isinstance(found["state"], int) and not isinstance(found["state"], bool):
        parts.append(f"at random state {found['state']}")
    if isinstance(found["t"], int | float) and not isinstance(found["t"], bool) and math.isfinite(found["t"]):
        parts.append(f"at t = {found['t']:.4g} s")
    if isinstance(found["likely"], str) and found["likely"]:
        parts.append(f"(likely {found['likely']})")
    return " ".join(parts)


def summary_line(name: str, rows: list[dict]) -> str:
    """The verdict in one line, the same words wherever it is shown (terminal, Markdown summary,
    report): `NAME: PASSED (n gates)` or `NAME: FAILED (k of n gates fail)`."""
    failing = sum(not r["passed"] for r in rows)
    skipped = sum(bool(r.get("skipped")) for r in rows)
    count = f"{len(rows)} gate{'s' if len(rows) != 1 else ''}" + (f", {skipped} skipped" if skipped else "")
    return f"{name}: PASSED ({count})" if not failing else f"{name}: FAILED ({failing} of {count} fail)"


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
        t = Table({k: r[k] for k in ("name", "metric", "limit", "direction", "tolerance") if k in r}, source,
                  f"gates[{i}]")
        out.extend(read_gates([t]))
    return tuple(out)
