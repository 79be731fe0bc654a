"""The scenario suite, the gates, and the commands around results.json (report, gate, list)."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from harness.cli import main
from harness.runner.gates import Gate, check
from tests.conftest import MODELS, ROOT, SCENARIOS, results_of

ALL_SCENARIOS = sorted(SCENARIOS.glob("*.toml"))


@pytest.mark.parametrize("path", ALL_SCENARIOS, ids=[p.stem for p in ALL_SCENARIOS])
def test_every_scenario_loads_and_declares_gates(path):
    """Every scenario is valid and checks something. Whether each passes its gates is what
    `harness run scenarios/*.toml` decides in .ci/run, once (exit status 1 on a failed gate); running
    them all here too would run every scenario twice."""
    from harness.runner.scenario import load_scenario

    assert load_scenario(path).gates, "a scenario without gates checks nothing"


def test_a_built_in_gate_set_is_named_from_any_folder(tmp_path):
    """kr500_rail copied alone into an empty folder, its gate sets named as built-ins ("harness:engines")
    instead of by path: the same gates as the package's own scenario, in the same order."""
    from harness.runner.scenario import load_scenario

    text = (SCENARIOS / "kr500_rail.toml").read_text()
    old = 'gate_sets = ["gates/engines.toml", "gates/graph_theory_2021.toml"]'
    assert old in text
    (tmp_path / "s.toml").write_text(text.replace(old, 'gate_sets = ["harness:engines", "harness:graph_theory_2021"]')
                                     .replace('"../models/kr500.toml"', f'"{MODELS / "kr500.toml"}"'))
    assert load_scenario(tmp_path / "s.toml").gates == load_scenario(SCENARIOS / "kr500_rail.toml").gates


def test_gates_fail_closed():
    results = {"a": {"b": 1e-12, "nan": float("nan"), "text": "x", "null": None}}
    rows, passed = check(
        [
            Gate("ok", "a.b", 1e-9),
            Gate("null", "a.null", 1e-9),
            Gate("nan", "a.nan", 1e-9),
            Gate("text", "a.text", 1e-9),
            Gate("floor", "a.b", 1e-6, "at_least"),
        ],
        results,
    )
    assert [r["passed"] for r in rows] == [True, False, False, False, False]
    assert rows[1]["reason"] == "no value (nothing was evaluated)" and not passed


def test_same_scenario_twice_gives_the_same_results_but_for_the_time_and_the_run_id(run_scenario):
    from harness.runner.pipeline import run
    from harness.runner.scenario import load_scenario

    path = SCENARIOS / "kr500_rail_7digits.toml"
    first = results_of(run_scenario(path), when="first")
    second = results_of(run(load_scenario(path)), when="second")
    assert first["run"]["id"] != second["run"]["id"]
    for r in (first, second):
        r["run"]["time"] = r["run"]["timings"] = r["run"]["id"] = None
    assert json.dumps(first, sort_keys=True) == json.dumps(second, sort_keys=True)


def test_report_command_re_renders_the_same_report(fast_run, tmp_path):
    again = tmp_path / "again.html"
    assert main(["report", str(fast_run / "results.json"), "--out", str(again)]) == 0
    assert again.read_text() == (fast_run / "report.html").read_text()


def test_gate_command_rechecks_with_new_limits_and_refuses_a_metric_that_names_nothing(fast_run, tmp_path, capsys):
    assert main(["gate", str(fast_run / "results.json")]) == 0
    source = (SCENARIOS / "kr500_rail_7digits.toml").read_text()
    tighter = tmp_path / "kr500_rail_7digits.toml"
    tighter.write_text(source.replace('metric = "identification.max_abs_rel_error"\nlimit = 1e-3',
                                      'metric = "identification.max_abs_rel_error"\nlimit = 1e-9'))
    (tmp_path / "gates").mkdir()
    for f in (SCENARIOS / "gates").glob("*.toml"):
        shutil.copy(f, tmp_path / "gates" / f.name)
    shutil.copytree(MODELS, tmp_path.parent / "models", dirs_exist_ok=True)
    capsys.readouterr()
    assert main(["gate", str(fast_run / "results.json"), "--scenario", str(tighter)]) == 1
    assert "FAIL  identification at 7 digits" in capsys.readouterr().out
    misspelt = tmp_path / "misspelt.toml"
    misspelt.write_text(tighter.read_text() + '\n[[gates]]\nmetric = "torques.no_such_metric"\nlimit = 1.0\n')
    assert main(["gate", str(fast_run / "results.json"), "--scenario", str(misspelt)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "torques.no_such_metric" in err and "names no result" in err


def test_a_broken_model_fails_the_run_and_the_report_says_where(tmp_path, capsys):
    """The model under test has B3's J11 1 % too large; MuJoCo and Pinocchio simulate the true
    robot. The run exits 1 and the failing gates and the worst joint are in the report."""
    (tmp_path / "models").mkdir()
    (tmp_path / "scenarios").mkdir()
    truth = (MODELS / "kr500.toml").read_text()
    (tmp_path / "models" / "kr500.toml").write_text(truth)
    start = truth.index('name = "B3"')
    wrong = truth[:start] + truth[start:].replace(
        'shape = "cylinder"\nlength = 1.21\nradius = 0.2\ndensity = 7801.0',
        'shape = "explicit"\nmass = 1186.1661\ninertia = [23.96053, 156.5838, 156.5838]',
        1,
    )
    assert wrong != truth
    (tmp_path / "models" / "kr500_wrong.toml").write_text(wrong.replace('name = "kr500"', 'name = "kr500_wrong"'))
    text = (
        (SCENARIOS / "kr500_rail_all_steps.toml")
        .read_text()
        .replace(
            'plugin = "graph_theory_2021"',
            'plugin = "graph_theory_2021"\nmodel = "../models/kr500_wrong.toml"',
        )
    )
    (tmp_path / "scenarios" / "gates").mkdir()
    for f in (SCENARIOS / "gates").glob("*.toml"):
        shutil.copy(f, tmp_path / "scenarios" / "gates" / f.name)
    (tmp_path / "scenarios" / "broken.toml").write_text(text)
    out = tmp_path / "out"
    assert main(["run", str(tmp_path / "scenarios" / "broken.toml"), "--out", str(out), "--quiet"]) == 1
    printed = capsys.readouterr().out
    assert "broken: FAILED" in printed and "FAIL  torques: graph model vs MuJoCo" in printed
    assert "pass  torques: Pinocchio vs MuJoCo" in printed  # the engines agree: the model is at fault
    results = json.loads((out / "results.json").read_text())
    worst = results["torques"]["graph_vs_mujoco"]
    assert worst["max_rel_error"] > 1e-6 and worst["max_rel_joint"] in {"O1", "O2", "O3", "O4", "rail"}
    report = (out / "report.html").read_text()
    assert "FAILED" in report and "kr500_wrong.toml" in report
    differs = results["torques"]["parameter_differences"]["graph"]
    assert {d["body"] for d in differs} == {"B3"}
    # J11 is 1 % off; mass, J22 and J33 differ only by the rounding of the explicit values (about 1e-8)
    assert {d["parameter"] for d in differs if abs(d["rel_difference"]) > 1e-6} == {"J11"}
    assert "Parameters of graph that differ from the robot" in report


def test_a_sign_flipped_in_the_graph_model_fails_the_run(tmp_path, monkeypatch, capsys):
    """One sign flipped in the gyroscopic term of Eq. 37 (the skew matrix of the graph model)."""
    import harness.papers.graph_theory_2021.constrained
    import harness.papers.graph_theory_2021.dynamics

    flipped = lambda v, f=harness.papers.graph_theory_2021.dynamics.skew: -f(v)  # noqa: E731
    monkeypatch.setattr(harness.papers.graph_theory_2021.dynamics, "skew", flipped)
    monkeypatch.setattr(harness.papers.graph_theory_2021.constrained, "skew", flipped)
    out = tmp_path / "out"
    assert main(["run", str(SCENARIOS / "kr500_rail_all_steps.toml"), "--out", str(out), "--quiet"]) == 1
    printed = capsys.readouterr().out
    assert "FAIL  graph model, unconstrained dynamics: moments" in printed


def test_list_and_help(capsys):
    cwd = os.getcwd()
    try:
        os.chdir(ROOT)
        capsys.readouterr()
        assert main(["list"]) == 0
        listing = capsys.readouterr().out
    finally:
        os.chdir(cwd)
    for path in ALL_SCENARIOS:
        assert path.stem in listing
    assert "kr500" in listing
    says = {
        "": "exit status",
        "run": "report.html",
        "report": "without simulating",
        "gate": "Exit status 1",
        "list": "One line per model",
    }
    for command, phrase in says.items():
        with pytest.raises(SystemExit) as exit_:
            main([command, "--help"] if command else ["--help"])
        assert exit_.value.code == 0
        assert phrase in capsys.readouterr().out, command


def _chromium() -> str | None:
    return shutil.which("chromium") or shutil.which("chromium-browser")


@pytest.mark.slow  # a few seconds: a whole pipeline or a subprocess
def test_report_renders_in_a_headless_browser(fast_run, tmp_path):
    """Debian's Chromium opens the report offline and shows the verdict and the figures."""
    browser = _chromium()
    if browser is None:
        if os.environ.get("CI"):
            pytest.fail("chromium is required in CI (.ci/run installs it)")
        pytest.skip("chromium not installed")
    flags = [
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-quic",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        f"--user-data-dir={tmp_path / 'profile'}",
    ]
    url = (fast_run / "report.html").resolve().as_uri()
    dom = subprocess.run(
        [browser, *flags, "--dump-dom", url], capture_output=True, text=True, timeout=120, check=True
    ).stdout
    assert '<div class="verdict pass" id="verdict">PASSED</div>' in dom
    assert dom.count("<svg") >= 6
    shot = tmp_path / "report.png"
    subprocess.run(
        [browser, *flags, "--window-size=1200,3000", f"--screenshot={shot}", url],
        capture_output=True,
        timeout=120,
        check=True,
    )
    assert shot.stat().st_size > 50_000  # a rendered page, not a blank one


def _page_width(browser: str, page: Path, tmp_path: Path, width: int) -> int:
    """The width a page takes in Chromium at a window `width` px wide (document's scroll width): more than
    `width` where a column is off the page."""
    probe = tmp_path / f"{page.parent.name}_{page.name}"
    probe.write_text(page.read_text().replace(
        "</body>", "<script>document.body.dataset.width = document.documentElement.scrollWidth</script></body>"))
    dom = subprocess.run([browser, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                          "--disable-background-networking", "--disable-component-update", "--disable-sync",
                          f"--user-data-dir={tmp_path / 'profile'}", f"--window-size={width},900", "--dump-dom",
                          probe.resolve().as_uri()], capture_output=True, text=True, timeout=120, check=True).stdout
    return int(re.search(r'data-width="(\d+)"', dom).group(1))


@pytest.mark.slow  # Chromium, the TX40's run and an audit: about 10 s
def test_every_column_of_a_report_and_an_audit_is_on_the_page_at_1400_px(fast_run, tmp_path):
    """At a 1400 px window the report of a measured log with long worst cases and reasons (the TX40), the
    paper's report and an audit page (a URDF, an MJCF humanoid, a closed chain, bolt's reason) take 1400
    px: every table wraps its long cells and scrolls inside its own box (the audit page was 2492 px)."""
    from tests.conftest import humanoid_mjcf

    browser = _chromium()
    if browser is None:
        if os.environ.get("CI"):
            pytest.fail("chromium is required in CI (.ci/run installs it)")
        pytest.skip("chromium not installed")
    assert main(["run", "tx40", "--out", str(tmp_path / "tx40"), "--quiet"]) == 0
    biped = humanoid_mjcf(tmp_path / "biped")
    assert main(["audit", "bolt", "talos_reduced", str(biped), str(SCENARIOS.parent / "models" / "fourbar.xml"),
                 "--out", str(tmp_path / "audit"), "--quiet"]) == 0
    for page in (tmp_path / "tx40" / "report.html", fast_run / "report.html", tmp_path / "audit" / "audit.html"):
        assert _page_width(browser, page, tmp_path, 1400) <= 1400, page


@pytest.mark.parametrize(("edit", "phrase"), [
    (lambda r: r["gates"][0].update(direction="at_lest"), "'at_lest' is not one of at_most, at_least"),
    (lambda r: r.pop("gates"), "no gates in this results file"),
    (lambda r: r["gates"][0].update(limit="small"), "expected a number"),
    (lambda r: r["gates"].__setitem__(0, "a gate"), "expected an object"),
])
def test_gate_command_refuses_malformed_gates_in_a_results_file(fast_run, tmp_path, capsys, edit, phrase):
    """A results.json whose stored gates are malformed is bad input: it neither passes nor fails."""
    results = json.loads((fast_run / "results.json").read_text())
    edit(results)
    path = tmp_path / "results.json"
    path.write_text(json.dumps(results))
    assert main(["gate", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and phrase in err, err
