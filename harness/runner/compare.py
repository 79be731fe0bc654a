"""Two runs of a scenario side by side (`harness compare BASELINE CANDIDATE`): is the candidate worse
than the baseline on any gated metric, beyond what the gate allows?

The metrics compared are the candidate's gates' (results.json `gates`), each read in both runs. A metric
is worse when it moved the gate's wrong way (up for an `at_most` gate, down for an `at_least` one) by
more than the tolerance times the baseline's size:

    worse  <=>  change > tolerance * max(|baseline|, FLOOR * |limit|)

The tolerance is the gate's `tolerance` where the scenario sets one ([[gates]] tolerance = 0.05: a
relative change), else by the gate's kind:
- a round-off gate (at_most, limit above 0 and at most ROUND_OFF_LIMIT: two engines' agreement, an identification
  on ideal data) is judged on its order of magnitude: ROUND_OFF_TOLERANCE, ten times the baseline
  (round-off moves by a few times between machines, libraries and summation orders; a bug moves it by
  orders), every value under FLOOR of the limit counted as that;
- every other gate (an error, a coverage, a count) on its relative change: RELATIVE_TOLERANCE (a
  deterministic pipeline gives the same figure to many digits on the same inputs: a change of 1 % is
  a change of method or data). A count (inconsistent links, findings) of 0 may not become 1.
A metric the baseline had no number for is new (not worse); one the candidate has no number for, where
the baseline had one, is worse; one under a skipped result in either run is not compared, said."""

from __future__ import annotations

import math
from dataclasses import dataclass

from harness.runner.ci import cell
from harness.runner.gates import Gate, lookup, skipped_by

ROUND_OFF_LIMIT = 1e-6  # an at_most gate whose limit is this small judges round-off
ROUND_OFF_TOLERANCE = 9.0  # a round-off metric is worse beyond 10 times the baseline
RELATIVE_TOLERANCE = 0.01  # any other metric, beyond a 1 % change its wrong way
FLOOR = 1e-3  # a value under this share of the gate's limit counts as that share: the size of a zero


WORDS = {"worse": "WORSE", "not worse": "ok", "new": "new", "skipped": "skip"}  # each outcome in one word


@dataclass(frozen=True)
class Compared:
    """One gated metric in both runs."""

    gate: Gate
    baseline: float | None
    candidate: float | None
    tolerance: float  # the relative change allowed
    rule: str  # "the scenario's", "order of magnitude" or "relative change"
    outcome: str  # "worse", "not worse", "new", "skipped"
    bound: float | None  # the largest (at_most) or smallest (at_least) value not worse
    note: str = ""

    @property
    def worse(self) -> bool:
        return self.outcome == "worse"

    @property
    def word(self) -> str:
        """The outcome in one word, as the terminal shows it."""
        return WORDS[self.outcome]

    def described(self) -> str:
        """`baseline B, candidate C (+x %); allowed ...` and why, where there is more to say."""
        change = "" if self.baseline is None or self.candidate is None else _change(self.baseline, self.candidate)
        allowed = (f"up to {1 + self.tolerance:g} x the baseline" if self.rule == "order of magnitude" else
                   f"{100 * self.tolerance:g} % {'up' if self.gate.direction == 'at_most' else 'down'}")
        return (f"baseline {_num(self.baseline)}, candidate {_num(self.candidate)}{change}; allowed {allowed} "
                f"({self.rule})" + (f"; {self.note}" if self.note else ""))

    def row(self) -> dict:
        """As a gate row (harness/runner/ci.py writes JUnit and Markdown of it): the candidate's value
        against the bound, the baseline's in the reason."""
        return {"name": self.gate.name, "metric": self.gate.metric, "direction": self.gate.direction,
                "limit": self.bound if self.bound is not None else self.gate.limit, "value": self.candidate,
                "passed": not self.worse, "skipped": self.outcome == "skipped", "reason": self.described(),
                "where": "", "outcome": self.outcome}


def _num(x: float | None) -> str:
    return "no value" if x is None else f"{x:.4g}"


def _change(baseline: float, candidate: float) -> str:
    if baseline == candidate:
        return " (the same)"
    if baseline == 0:
        return ""
    return f" ({100 * (candidate - baseline) / abs(baseline):+.3g} %)"


def _number(results: dict, metric: str) -> float | None:
    value = lookup(results, metric)
    ok = isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
    return float(value) if ok else None


def tolerance_of(gate: Gate) -> tuple[float, str]:
    """The relative change a gate allows its metric, and by which rule (the module's docstring)."""
    if gate.tolerance is not None:
        return gate.tolerance, "the scenario's"
    if gate.direction == "at_most" and 0 < gate.limit <= ROUND_OFF_LIMIT:
        return ROUND_OFF_TOLERANCE, "order of magnitude"
    return RELATIVE_TOLERANCE, "relative change"


def compare_metric(gate: Gate, baseline: dict, candidate: dict) -> Compared:
    """One gated metric of two runs' results (the module's docstring)."""
    tolerance, rule = tolerance_of(gate)
    skipped = skipped_by(baseline, gate.metric) or skipped_by(candidate, gate.metric)
    b, c = _number(baseline, gate.metric), _number(candidate, gate.metric)
    if skipped is not None:
        return Compared(gate, b, c, tolerance, rule, "skipped", None, f"not compared: {skipped}")
    if b is None:
        return Compared(gate, b, c, tolerance, rule, "new", None, "the baseline has no number for it")
    size = max(abs(b), FLOOR * abs(gate.limit))
    sign = 1.0 if gate.direction == "at_most" else -1.0
    bound = b + sign * tolerance * size
    if c is None:
        return Compared(gate, b, c, tolerance, rule, "worse", bound, "the candidate has no number for it")
    worse = sign * (c - b) > tolerance * size
    return Compared(gate, b, c, tolerance, rule, "worse" if worse else "not worse", bound)


def compare(gates: tuple[Gate, ...], baseline: dict, candidate: dict) -> list[Compared]:
    """Every gate of the candidate, its metric in both runs."""
    return [compare_metric(g, baseline, candidate) for g in gates]


def dropped(baseline_gates: tuple[Gate, ...], gates: tuple[Gate, ...]) -> list[str]:
    """The metrics the baseline gated and the candidate does not: said, not compared."""
    kept = {g.metric for g in gates}
    return [g.metric for g in baseline_gates if g.metric not in kept]


def line(name: str, rows: list[dict]) -> str:
    """The comparison of one scenario in one line, from its rows (`Compared.row`): `NAME: NOT WORSE (n
    metrics)` or `NAME: WORSE (k of n metrics)`."""
    worse = sum(not r["passed"] for r in rows)
    count = f"{len(rows)} metric{'s' if len(rows) != 1 else ''}"
    return f"{name}: WORSE ({worse} of {count})" if worse else f"{name}: NOT WORSE ({count})"


def markdown(verdicts: list[tuple[str, list[dict]]]) -> str:
    """The comparisons as a Markdown job summary: per scenario its line and a row per metric."""
    out = []
    for name, rows in verdicts:
        out.append(f"### {cell(line(name, rows))}\n")
        out.append("| gate | metric | candidate | allowed | result | baseline, change and rule |\n"
                   "|---|---|---:|---:|---|---|")
        for r in rows:
            compared = r["outcome"] in ("worse", "not worse")
            allowed = f"{'<=' if r['direction'] == 'at_most' else '>='} {r['limit']:.4g}" if compared else ""
            word = "**WORSE**" if r["outcome"] == "worse" else WORDS[r["outcome"]]
            out.append(f"| {cell(r['name'])} | `{cell(r['metric'])}` | {_num(r['value'])} | {allowed} | {word} | "
                       f"{cell(r['reason'])} |")
        out.append("")
    return "\n".join(out) + "\n"



