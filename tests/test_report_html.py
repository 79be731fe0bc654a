"""The pages' HTML (harness/report/html.py): every value from results.json is escaped once, never
twice, and markup the renderers build passes through as markup."""

from __future__ import annotations

import json
import re

import pytest

from harness.cli import main
from harness.report import render_report
from harness.report.html import DASH, code, esc, mark, num, page, table

# what the renderers write as markup: seen escaped in a page, it was escaped twice
DOUBLE = re.compile(r"&lt;/?(?:span|code|small|b|li|ol|ul|p|h\d|table|tr|td|th|div|figure|section|svg)\b"
                    r"|&amp;(?:[a-z]+|#\d+);")


def test_a_table_escapes_every_cell_that_is_not_markup_already():
    html = table(["<h>"], [["<script>alert(1)</script>", code("a<b"), mark(False, "no & never"), num(None),
                            esc("x&y")]])
    assert "<script>" not in html and "&lt;script&gt;alert(1)&lt;/script&gt;" in html
    assert "<th>&lt;h&gt;</th>" in html
    assert "<td><code>a&lt;b</code></td>" in html
    assert '<td><span class="bad">no &amp; never</span></td>' in html
    assert f"<td>{DASH}</td>" in html and "<td>x&amp;y</td>" in html


def test_a_page_escapes_its_title_heading_description_and_navigation():
    text = page("<t>", "<h>", "<body-is-markup/>", description="a < b", nav=[("x", "<n>")])
    assert "<title>&lt;t&gt;</title>" in text and "<h1>&lt;h&gt;</h1>" in text and "<p>a &lt; b</p>" in text
    assert '<a href="#x">&lt;n&gt;</a>' in text and "<body-is-markup/>" in text


def test_a_scenarios_own_text_is_escaped_once_in_its_report(fast_run, tmp_path):
    """The results' free text (the scenario's description, a gate's name) made hostile: the report
    shows it as text, and nothing the renderers write as markup is escaped twice."""
    results = json.loads((fast_run / "results.json").read_text())
    results["scenario"]["description"] = "<script>alert('description')</script>"
    results["gates"][0]["name"] = "<img src=x onerror=alert(1)>"
    results["gates"][1].update(name="graph-theory model's forward dynamics", passed=False)  # in the verdict's line
    results["passed"] = False
    (tmp_path / "recording.csv").write_bytes((fast_run / "recording.csv").read_bytes())
    text = render_report(results, tmp_path)
    assert "<script>" not in text and "<img" not in text
    assert "&lt;script&gt;alert(&#39;description&#39;)&lt;/script&gt;" in text
    assert "FAILED (1 of" in text and ": graph-theory model&#39;s forward dynamics</p>" in text
    assert not DOUBLE.findall(text)
    assert not DOUBLE.findall((fast_run / "report.html").read_text())


@pytest.mark.slow  # a sweep of runs (2.3 s)
def test_a_sweep_page_has_nothing_escaped_twice(tmp_path):
    assert main(["sweep", "kr500_noise", "--trials", "2", "--out", str(tmp_path / "sweep")]) == 0
    assert not DOUBLE.findall((tmp_path / "sweep" / "sweep.html").read_text())


def test_the_report_says_where_the_time_went_stage_by_stage_with_its_share(fast_run):
    """The how-the-run-was-made section lists every stage of run.timings with its seconds and its
    share of their sum; the shares add up to 100 % (to their rounding, 0.05 point a row)."""
    import re

    results = json.loads((fast_run / "results.json").read_text())
    timings = results["run"]["timings"]
    page = (fast_run / "report.html").read_text()
    shares = [float(x) for x in re.findall(r"<td>([0-9.]+) %</td>", page[page.index('id="how"'):])]
    assert len(shares) == len(timings) and abs(sum(shares) - 100) <= 0.05 * len(shares), shares


def test_the_verdict_says_with_what_the_run_was_made_and_what_reading_it_assumed(fast_run, tmp_path):
    """At the head of the report: the harness's, MuJoCo's and Pinocchio's versions and the run's id, and
    every note of the model's reading and warning of the data's (a floating base taken as fixed, said
    on the terminal alone before), each once."""
    results = json.loads((fast_run / "results.json").read_text())
    note = "biped.xml: free joint 'floating_base_joint' of body 'pelvis': the floating base is taken as fixed"
    results["scenario"]["model_notes"] = [note]
    (tmp_path / "recording.csv").write_bytes((fast_run / "recording.csv").read_bytes())
    text = render_report(results, tmp_path)
    verdict = text[text.index('id="verdict"'):text.index('id="model"')]
    v = results["run"]["versions"]
    assert (f"harness {v['harness']}, MuJoCo {v['mujoco']}, Pinocchio {v['pinocchio']}; run {results['run']['id']} "
            f"at {results['run']['time']} (UTC)") in verdict
    assert verdict.count("floating base is taken as fixed") == 1 and '<li class="warn">' in verdict


def test_every_table_scrolls_inside_its_own_box_and_its_long_cells_wrap():
    """A table wider than the page keeps the page's width: it scrolls inside its box (div.table), and
    a cell of more than LONG_CELL characters (a gate's reason, where its worst case lies) wraps."""
    from harness.report.html import LONG_CELL, STYLE

    html = table(["gate", "result"], [["short", "x" * (LONG_CELL + 1)]])
    assert html.startswith('<div class="table"><table') and html.rstrip().endswith("</table></div>")
    assert f'<td class="text">{"x" * (LONG_CELL + 1)}</td>' in html and "<td>short</td>" in html
    assert "div.table { overflow-x: auto; max-width: 100%; }" in STYLE and "td.text" in STYLE
