"""`harness report RESULTS --figures DIR` (harness/report/figures.py): every chart of the HTML report as
PNG and PDF, drawn by matplotlib from the same data, while the HTML stays the same self-contained page."""

from __future__ import annotations

import importlib.util
import json
import re
import shutil

import numpy as np
import pytest

from harness.cli import main
from harness.report.figures import charts_of, figure


@pytest.fixture(scope="module")
def drawn(fast_run, tmp_path_factory):
    """kr500_rail_7digits's run re-rendered twice: without figures, and with them."""
    folder = tmp_path_factory.mktemp("figures")
    shutil.copytree(fast_run, folder / "run")
    assert main(["report", str(folder / "run" / "results.json"), "--out", str(folder / "plain.html")]) == 0
    assert main(["report", str(folder / "run" / "results.json"), "--out", str(folder / "with.html"),
                 "--figures", str(folder / "figs")]) == 0
    return folder


@pytest.mark.slow  # every chart drawn and written twice: seconds of matplotlib
def test_every_chart_of_the_report_is_a_png_and_a_pdf_and_the_html_is_unchanged(drawn):
    html = (drawn / "with.html").read_text()
    assert html == (drawn / "plain.html").read_text()
    charts = len(re.findall(r"<svg\b", html))
    pngs, pdfs = sorted((drawn / "figs").glob("*.png")), sorted((drawn / "figs").glob("*.pdf"))
    assert charts > 0 and len(pngs) == len(pdfs) == charts
    assert [p.stem for p in pngs] == [p.stem for p in pdfs]
    assert all(p.read_bytes().startswith(b"\x89PNG\r\n\x1a\n") for p in pngs)
    assert all(p.read_bytes().startswith(b"%PDF-") for p in pdfs)
    assert pngs[0].name.startswith("01-")


def test_a_figure_draws_the_charts_own_numbers_with_its_axes_units(fast_run):
    """Each line chart's curves are its series to the bit (no thinning: the HTML's SVG thins to its pixel
    columns, a figure for print keeps every sample), its axes labelled with their units."""
    results = json.loads((fast_run / "results.json").read_text())
    charts = charts_of(results, fast_run)
    lines = [c for c in charts if c.kind == "lines"]
    assert lines
    for chart in lines:
        t, series, ylabel = chart.args[:3]
        ax = figure(chart).axes[0]
        drawn = {line.get_label(): line for line in ax.get_lines()}
        for name, y in series.items():
            np.testing.assert_array_equal(drawn[name].get_xdata(), np.asarray(t, dtype=float))
            y = np.asarray(y, dtype=float)
            expected = np.where(y > 0, y, np.nan) if chart.kwargs.get("logy") else y
            np.testing.assert_array_equal(drawn[name].get_ydata(), expected)
        assert ax.get_ylabel() == ylabel and "[" in ax.get_xlabel() + ax.get_ylabel()


def test_figures_without_matplotlib_are_refused_naming_the_option(fast_run, tmp_path, capsys, monkeypatch):
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "matplotlib" else real(name, *a))
    shutil.copytree(fast_run, tmp_path / "run")
    status = main(["report", str(tmp_path / "run" / "results.json"), "--out", str(tmp_path / "r.html"),
                   "--figures", str(tmp_path / "figs")])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and len(err) == 1 and "--figures" in err[0] and "matplotlib" in err[0]
    assert not (tmp_path / "figs").exists() and not (tmp_path / "r.html").exists()
