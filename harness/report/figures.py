"""The report's charts as figures for a paper or a slide (`harness report RESULTS --figures DIR`): each
chart of report.html drawn again with matplotlib from the same data (harness/report/plots.py keeps
every chart's arguments while the report renders: `collecting`), written as PNG (150 dpi) and PDF,
numbered in the report's order and named after its title. The HTML stays one self-contained file of
SVG; matplotlib is imported only here, when figures are asked for."""

from __future__ import annotations

import inspect
import re
from pathlib import Path

import numpy as np

from harness.report import plots

DPI = 150
WIDTH_IN = 7.5  # inches: the report's column (plots.WIDTH px at 100 px per inch)
FORMATS = ("png", "pdf")


def charts_of(results: dict, results_dir: Path) -> list[plots.Chart]:
    """Every chart the report of `results` draws, in its order."""
    from harness.report import render_report

    with plots.collecting() as charts:
        render_report(results, results_dir)
    return charts


def _arguments(chart: plots.Chart) -> dict:
    """The chart's arguments by name, its function's defaults filled in."""
    bound = inspect.signature(getattr(plots, chart.kind).__wrapped__).bind(*chart.args, **chart.kwargs)
    bound.apply_defaults()
    return dict(bound.arguments)


def title_of(chart: plots.Chart) -> str:
    a = _arguments(chart)
    if a.get("title"):
        return str(a["title"])
    if chart.kind == "grid":
        return f"{a['ylabel']}: {', '.join(title for title, _, _ in a['panels'][:3])}"
    return f"histograms of {a['xlabel']}" if chart.kind == "histograms" else chart.kind


def file_stem(k: int, chart: plots.Chart) -> str:
    """`03-joint-positions`: the chart's place in the report and its title, as a file name."""
    slug = re.sub(r"[^a-z0-9]+", "-", title_of(chart).lower()).strip("-")[:60].rstrip("-")
    return f"{k + 1:02d}-{slug or chart.kind}"


def _spans(ax, t: np.ndarray, flags) -> None:
    """The flagged samples shaded, consecutive ones as one band (plots.flagged_spans)."""
    if flags is not None and np.any(flags):
        for start, end in plots.flagged_spans(t, flags):
            ax.axvspan(start, end, color="#d62728", alpha=0.15, linewidth=0)


def _series(ax, t, series: dict, styles: dict | None, logy: bool, colors: dict[str, str], logx: bool = False,
            width: float = 1.1, marker: float = 3.0) -> None:
    """Each series a line in its colour (plots' own per name), a non-positive value breaking it on a
    logarithmic axis, as in the HTML."""
    t = np.asarray(t, dtype=float)
    for name, y in series.items():
        y = np.asarray(y, dtype=float)
        ax.plot(t, np.where(y > 0, y, np.nan) if logy else y, (styles or {}).get(name, "-"), color=colors[name],
                label=name, linewidth=width, markersize=marker)
    if logy:
        ax.set_yscale("log")
    if logx:
        ax.set_xscale("log")


def _lines(a: dict):
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(WIDTH_IN, a["height"] + 0.8), layout="constrained")
    _series(ax, a["t"], a["series"], a["styles"], a["logy"], plots.series_colors(a["series"]), a["logx"])
    _spans(ax, np.asarray(a["t"], dtype=float), a["flags"])
    ax.set(xlabel=a["xlabel"], ylabel=a["ylabel"], title=a["title"])
    ax.legend(fontsize=7, ncols=min(4, max(1, len(a["series"]))))
    return fig


def _grid(a: dict):
    import matplotlib.pyplot as plt

    panels, ncols = a["panels"], a["ncols"]
    nrows = -(-len(panels) // ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(WIDTH_IN, 1.9 * nrows + 0.6), sharex=True,
                             layout="constrained", squeeze=False)
    names = dict.fromkeys(k for _, series, _ in panels for k in series)
    colors = plots.series_colors(names)  # one per name, the same in every panel
    for ax, (title, series, flags) in zip(axes.flat, panels, strict=False):
        _series(ax, a["t"], series, a["styles"], a["logy"], colors, width=1.0, marker=2.0)
        _spans(ax, np.asarray(a["t"], dtype=float), flags)
        ax.set_title(title, fontsize=8)
        ax.set_ylabel(a["ylabel"], fontsize=7)
        ax.tick_params(labelsize=7)
    for ax in axes.flat[len(panels):]:
        ax.set_visible(False)
    for ax in axes[-1]:
        ax.set_xlabel("t [s]", fontsize=7)
    handles, labels = axes.flat[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside upper center", ncols=min(5, max(1, len(labels))), fontsize=7)
    return fig


def _bars(a: dict):
    import matplotlib.pyplot as plt

    labels, series = a["labels"], a["series"]
    fig, ax = plt.subplots(figsize=(WIDTH_IN, 3.4 + 0.06 * max((len(s) for s in labels), default=1)),
                           layout="constrained")
    n, m = max(1, len(labels)), max(1, len(series))
    width = 0.8 / m
    for k, (name, values) in enumerate(series.items()):
        v = np.array([np.nan if x is None else abs(x) for x in values], dtype=float)  # magnitudes, as the HTML's
        ax.bar(np.arange(len(v)) + 0.1 + (k + 0.5) * width - 0.5, v, width, label=name,
               color=plots.COLORS[k % len(plots.COLORS)])
    ax.set_xticks(np.arange(n), labels, rotation=90, fontsize=6)
    if a["logy"]:
        ax.set_yscale("log")
    ax.set(ylabel=a["ylabel"], title=a["title"])
    ax.legend(fontsize=7)
    return fig


def _histograms(a: dict):
    import matplotlib.pyplot as plt

    panels, ncols = a["panels"], a["ncols"]
    nrows = -(-len(panels) // ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(WIDTH_IN, 1.3 * nrows + 0.3), layout="constrained",
                             squeeze=False)
    for ax, (title, values) in zip(axes.flat, panels, strict=False):
        v = np.asarray(values, dtype=float)
        v = v[np.isfinite(v)]
        ax.hist(v, bins=a["bins"], color=plots.COLORS[0])
        lo, hi = ax.get_xlim()
        if lo <= 0.0 <= hi:
            ax.axvline(0.0, color="black", linewidth=0.8)
        ax.set_title(title, fontsize=6)
        ax.tick_params(labelsize=5)
    for ax in axes.flat[len(panels):]:
        ax.set_visible(False)
    for ax in axes[-1]:
        ax.set_xlabel(a["xlabel"], fontsize=6)
    return fig


DRAW = {"lines": _lines, "grid": _grid, "bars": _bars, "histograms": _histograms}


def figure(chart: plots.Chart):
    """The chart as a matplotlib Figure (the Agg backend: nothing on screen)."""
    import matplotlib

    matplotlib.use("Agg")
    return DRAW[chart.kind](_arguments(chart))


def files(charts: list[plots.Chart]) -> dict[str, object]:
    """{file name: writer(path)} of every chart, drawn once and written in every format beside `path`
    (harness/cli/common.py writes them into a staging folder, then into the one asked for: nothing
    half-written)."""
    return {f"{file_stem(k, chart)}.{FORMATS[0]}": _writer(chart) for k, chart in enumerate(charts)}


def _writer(chart: plots.Chart):
    def write(path: Path) -> None:
        import matplotlib.pyplot as plt

        fig = figure(chart)
        try:
            for fmt in FORMATS:  # a PDF without its creation date: the same data gives the same bytes
                fig.savefig(path.with_suffix(f".{fmt}"), format=fmt, dpi=DPI,
                            metadata={"CreationDate": None} if fmt == "pdf" else None)
        finally:
            plt.close(fig)
    return write
