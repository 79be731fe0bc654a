"""The pages' HTML (harness/report/html.py): every value from results.json is escaped once, never
twice, and markup the renderers build passes through as markup."""

from __future__ import annotations

import json
import re

from harness.cli import main
from harness.report import render_report
from harness.report.html import DASH, code, esc, mark, num, page, table

# what the renderers write as markup: seen escaped in a page, it was escaped twice
DOUBLE = re.compile(r"&lt;/?(?:span|code|small|b|li|ol|p|h\d|table|tr|td|th|figure|section|svg)\b|&amp;[a-z]+;")


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
    (tmp_path / "recording.csv").write_bytes((fast_run / "recording.csv").read_bytes())
    text = render_report(results, tmp_path)
    assert "<script>" not in text and "<img" not in text
    assert "&lt;script&gt;alert(&#39;description&#39;)&lt;/script&gt;" in text
    assert not DOUBLE.findall(text)
    assert not DOUBLE.findall((fast_run / "report.html").read_text())


def test_a_sweep_page_has_nothing_escaped_twice(tmp_path):
    assert main(["sweep", "kr500_noise", "--trials", "3", "--out", str(tmp_path / "sweep")]) == 0
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
