"""Figures as inline SVG text (matplotlib, Agg), deterministic for the same data."""

from __future__ import annotations

import io

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

plt.rcParams.update({
    "svg.fonttype": "none",  # text stays text: small and searchable
    "svg.hashsalt": "harness",  # stable element ids
    "font.size": 9,
    "axes.grid": True,
    "grid.alpha": 0.3,
    "figure.dpi": 100,
})


def to_svg(fig) -> str:
    buf = io.StringIO()
    fig.savefig(buf, format="svg", bbox_inches="tight", metadata={"Date": None})
    plt.close(fig)
    text = buf.getvalue()
    return text[text.index("<svg"):]


def mark_rows(ax, t: np.ndarray, flags: np.ndarray, label: str = "near gimbal lock") -> None:
    """Shade the samples where `flags` is set."""
    dt = (t[1] - t[0]) if len(t) > 1 else 1.0
    first = True
    for k in np.flatnonzero(flags):
        ax.axvspan(t[k] - dt / 2, t[k] + dt / 2, color="tab:red", alpha=0.15, lw=0,
                   label=label if first else None)
        first = False


def _draw(ax, t, series: dict[str, np.ndarray], flags, styles, logy: bool, lw: float, ms: float) -> None:
    for name, y in series.items():
        ax.plot(t, y, (styles or {}).get(name, "-"), label=name, lw=lw, ms=ms)
    if flags is not None and flags.any():
        mark_rows(ax, t, flags)
    if logy:
        ax.set_yscale("log")


def lines(t, series: dict[str, np.ndarray], ylabel: str, title: str, logy: bool = False,
          flags: np.ndarray | None = None, styles: dict[str, str] | None = None, height: float = 2.6) -> str:
    fig, ax = plt.subplots(figsize=(7.5, height))
    _draw(ax, t, series, flags, styles, logy, lw=1.2, ms=3)
    ax.set_xlabel("t [s]")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.legend(fontsize=7, ncol=min(4, max(1, len(series))), loc="best")
    return to_svg(fig)


def grid(t, panels: list[tuple[str, dict[str, np.ndarray], np.ndarray | None]], ylabel: str,
         logy: bool = False, styles: dict[str, str] | None = None, ncols: int = 2) -> str:
    """Small multiples: one panel per (title, series, flags)."""
    nrows = -(-len(panels) // ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(7.5, 1.9 * nrows), sharex=True, squeeze=False)
    for ax, (title, series, flags) in zip(axes.flat, panels, strict=False):
        _draw(ax, t, series, flags, styles, logy, lw=1.1, ms=2.5)
        ax.set_title(title, fontsize=8)
        ax.set_ylabel(ylabel, fontsize=7)
    for ax in axes.flat[len(panels):]:
        ax.set_visible(False)
    handles, labels = axes.flat[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="upper center", ncol=len(labels), fontsize=7, bbox_to_anchor=(0.5, 1.02))
    for ax in axes[-1]:
        ax.set_xlabel("t [s]")
    fig.tight_layout()
    return to_svg(fig)


def bars(labels: list[str], series: dict[str, list[float | None]], ylabel: str, title: str,
         logy: bool = True) -> str:
    fig, ax = plt.subplots(figsize=(7.5, 2.8))
    x = np.arange(len(labels))
    width = 0.8 / max(1, len(series))
    for k, (name, values) in enumerate(series.items()):
        v = np.array([np.nan if y is None else abs(y) for y in values], dtype=float)
        ax.bar(x + (k - (len(series) - 1) / 2) * width, np.where(v > 0, v, np.nan), width, label=name)
    ax.set_xticks(x, labels, rotation=90, fontsize=6)
    if logy:
        ax.set_yscale("log")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.legend(fontsize=7)
    return to_svg(fig)
