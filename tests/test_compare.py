"""`harness compare BASELINE CANDIDATE` (harness/runner/compare.py): per gated metric, is the candidate
worse than the baseline beyond its tolerance? The rule is checked on each side of its boundary for every
kind of gate, then the command on two runs of a scenario: the same run twice, one metric made worse,
another scenario, a missing run."""

from __future__ import annotations

import json
import shutil
import xml.etree.ElementTree as ET

import pytest

from harness.cli import main
from harness.runner.compare import FLOOR, RELATIVE_TOLERANCE, ROUND_OFF_TOLERANCE, compare_metric
from harness.runner.gates import Gate

ROUND_OFF = Gate("engines agree", "torques.max_rel_error", 1e-9)
ERROR = Gate("held-out error", "fit.error", 0.01)
COVERAGE = Gate("coverage", "fit.coverage", 0.9, "at_least")
COUNT = Gate("no inconsistent link", "fit.inconsistent", 0)


def _results(**values) -> dict:
    out: dict = {}
    for path, value in values.items():
        node = out
        *heads, leaf = path.split("__")
        for h in heads:
            node = node.setdefault(h, {})
        node[leaf] = value
    return out


@pytest.mark.parametrize(("gate", "path", "baseline", "candidate", "worse"), [
    # round-off: an order of magnitude, a zero counted as FLOOR of the limit
    (ROUND_OFF, "torques__max_rel_error", 1e-11, 0.99e-10, False),
    (ROUND_OFF, "torques__max_rel_error", 1e-11, 1.01e-10, True),
    (ROUND_OFF, "torques__max_rel_error", 0.0, 0.99 * ROUND_OFF_TOLERANCE * FLOOR * 1e-9, False),
    (ROUND_OFF, "torques__max_rel_error", 0.0, 1.01 * ROUND_OFF_TOLERANCE * FLOOR * 1e-9, True),
    (ROUND_OFF, "torques__max_rel_error", 1e-13, 1e-16, False),  # better
    # an error: its relative change
    (ERROR, "fit__error", 0.004, 0.004 * (1 + 0.99 * RELATIVE_TOLERANCE), False),
    (ERROR, "fit__error", 0.004, 0.004 * (1 + 1.01 * RELATIVE_TOLERANCE), True),
    (ERROR, "fit__error", 0.004, 0.002, False),
    # at least: worse downwards
    (COVERAGE, "fit__coverage", 0.95, 0.95 * (1 - 0.99 * RELATIVE_TOLERANCE), False),
    (COVERAGE, "fit__coverage", 0.95, 0.95 * (1 - 1.01 * RELATIVE_TOLERANCE), True),
    (COVERAGE, "fit__coverage", 0.95, 0.99, False),
    # a count of 0 may not become 1
    (COUNT, "fit__inconsistent", 0, 0, False),
    (COUNT, "fit__inconsistent", 0, 1, True),
])
def test_a_metric_is_worse_only_beyond_its_gates_tolerance_its_wrong_way(gate, path, baseline, candidate, worse):
    got = compare_metric(gate, _results(**{path: baseline}), _results(**{path: candidate}))
    assert got.worse is worse, got.described()
    assert got.outcome == ("worse" if worse else "not worse")


def test_the_scenarios_own_tolerance_replaces_the_default_and_missing_numbers_are_said():
    loose = Gate("held-out error", "fit.error", 0.01, tolerance=0.1)
    base = _results(fit__error=0.004)
    assert not compare_metric(loose, base, _results(fit__error=0.004 * 1.099)).worse
    assert compare_metric(loose, base, _results(fit__error=0.004 * 1.101)).worse
    assert compare_metric(loose, base, _results(fit__error=0.004 * 1.05)).rule == "the scenario's"
    assert compare_metric(ERROR, {}, base).outcome == "new"
    gone = compare_metric(ERROR, base, _results(fit__error=None))
    assert gone.worse and "no number" in gone.described()
    skipped = compare_metric(ERROR, base, {"fit": {"skipped": "FIGAROH is not installed"}})
    assert skipped.outcome == "skipped" and not skipped.worse and "FIGAROH" in skipped.described()


@pytest.fixture()
def runs(fast_run, tmp_path):
    """Two folders of runs: kr500_rail_7digits's run as baseline and candidate (and a copy of it under
    another scenario's name in the baseline)."""
    for side in ("baseline", "candidate"):
        shutil.copytree(fast_run, tmp_path / side / "kr500_rail_7digits")
    return tmp_path


def _edit(path, change) -> None:
    results = json.loads(path.read_text())
    change(results)
    path.write_text(json.dumps(results))


def test_the_same_run_twice_is_not_worse_and_a_worse_metric_is_named(runs, capsys):
    """The same results: exit 0, every gated metric `ok`. The candidate's identification error made
    twice the baseline's: exit 1, the metric named WORSE with both values, in the terminal, the Markdown
    summary and the JUnit file (one failure); the other metrics ok."""
    base, cand = runs / "baseline", runs / "candidate"
    assert main(["compare", str(base), str(cand)]) == 0
    out = capsys.readouterr().out
    gates = len(json.loads((base / "kr500_rail_7digits" / "results.json").read_text())["gates"])
    assert f"kr500_rail_7digits: NOT WORSE ({gates} metrics)" in out
    assert not [line for line in out.splitlines() if line.strip().startswith("WORSE")]
    results = json.loads((cand / "kr500_rail_7digits" / "results.json").read_text())
    metric = "identification.max_abs_rel_error"
    before = results["identification"]["max_abs_rel_error"]
    _edit(cand / "kr500_rail_7digits" / "results.json",
          lambda r: r["identification"].__setitem__("max_abs_rel_error", 2 * before))
    status = main(["compare", str(base / "kr500_rail_7digits" / "results.json"),
                   str(cand / "kr500_rail_7digits" / "results.json"), "--summary", str(runs / "s.md"),
                   "--junit-xml", str(runs / "j.xml")])
    out = capsys.readouterr().out
    assert status == 1
    worse = [line for line in out.splitlines() if line.strip().startswith("WORSE")]
    assert len(worse) == 1 and f"baseline {before:.4g}, candidate {2 * before:.4g}" in worse[0]
    summary = (runs / "s.md").read_text()
    assert "WORSE (1 of" in summary and f"`{metric}`" in summary and "**WORSE**" in summary
    suites = ET.parse(runs / "j.xml").getroot()
    assert suites.get("failures") == "1" and metric in ET.tostring(suites, encoding="unicode")


@pytest.mark.parametrize(("case", "said"), [
    ("another scenario", "another scenario"),
    ("a run missing", "no results of scenario 'other'"),
    ("no results", "no results.json"),
])
def test_runs_that_cannot_be_compared_are_refused_in_one_line(runs, capsys, case, said):
    base, cand = runs / "baseline", runs / "candidate"
    one = cand / "kr500_rail_7digits" / "results.json"
    if case == "another scenario":
        _edit(one, lambda r: r["scenario"].__setitem__("name", "other"))
        args = [str(base / "kr500_rail_7digits" / "results.json"), str(one)]
    elif case == "a run missing":
        shutil.copytree(base / "kr500_rail_7digits", base / "other")
        _edit(base / "other" / "results.json", lambda r: r["scenario"].__setitem__("name", "other"))
        args = [str(base), str(cand)]
    else:
        args = [str(base), str(runs / "empty")]
        (runs / "empty").mkdir()
    assert main(["compare", *args, "--summary", str(runs / "s.md")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("harness: error:") and said in err[0], err
    assert "ERROR (bad input)" in (runs / "s.md").read_text()


def test_a_gates_tolerance_is_read_kept_in_results_and_refused_when_negative(tmp_path):
    """[[gates]] tolerance = 0.05 is read, written with the gate into results.json's rows and read back from
    them (what `harness compare` judges the candidate by); a negative one is refused naming the key."""
    from harness.base.tomlio import InputError, Table
    from harness.runner.gates import from_results, read_gates

    path = tmp_path / "s.toml"
    (gate,) = read_gates([Table({"metric": "fit.error", "limit": 0.01, "tolerance": 0.05}, path)])
    assert gate.tolerance == 0.05 and gate.as_dict()["tolerance"] == 0.05
    assert from_results({"gates": [gate.as_dict()]}, path) == (gate,)
    assert "tolerance" not in read_gates([Table({"metric": "fit.error", "limit": 0.01}, path)])[0].as_dict()
    with pytest.raises(InputError, match="tolerance"):
        read_gates([Table({"metric": "fit.error", "limit": 0.01, "tolerance": -0.1}, path)])
