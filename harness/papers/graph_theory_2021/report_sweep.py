"""sweep.html: the Monte Carlo study of one scenario's measurement noise, self-contained."""

from __future__ import annotations

import html
import io

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # histograms and a log-log plot: the sweep's own figures
import numpy as np

from harness.report import STYLE
from harness.report.sections import esc, figure, num, section, table

plt.rcParams.update({"svg.fonttype": "none", "svg.hashsalt": "harness", "font.size": 9, "axes.grid": True,
                     "grid.alpha": 0.3, "figure.dpi": 100})


def to_svg(fig) -> str:
    """The figure as inline SVG text, deterministic for the same data."""
    buf = io.StringIO()
    fig.savefig(buf, format="svg", bbox_inches="tight", metadata={"Date": None})
    plt.close(fig)
    text = buf.getvalue()
    return text[text.index("<svg"):]


def _histograms(params: list[dict]) -> str:
    shown = [p for p in params if p["trials"] > 1]
    ncols = 6
    nrows = -(-len(shown) // ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(7.5, 1.25 * nrows), squeeze=False)
    for ax, p in zip(axes.flat, shown, strict=False):
        ax.hist(p["errors"], bins=30, color="tab:blue")
        ax.axvline(0.0, color="k", lw=0.8)
        ax.set_title(f"{p['body']}.{p['name']}", fontsize=7)
        ax.tick_params(labelsize=5)
    for ax in axes.flat[len(shown) :]:
        ax.set_visible(False)
    fig.tight_layout()
    return to_svg(fig)


def _levels(levels: list[dict]) -> str:
    fig, ax = plt.subplots(figsize=(7.5, 3.0))
    names = [k for k, v in levels[0]["median_rel_error"].items() if v is not None]
    f = np.array([lv["level"] for lv in levels])
    for name in names:
        y = np.array([lv["median_rel_error"][name] or np.nan for lv in levels])
        ax.plot(f, y, "-o", ms=2, lw=0.8, label=name)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("noise level (multiple of the scenario's)")
    ax.set_ylabel("median |relative error|")
    ax.set_title("Error against noise level")
    ax.legend(fontsize=5, ncol=6, loc="upper left")
    return to_svg(fig)


def render_sweep(s: dict) -> str:
    rows = []
    for p in s["parameters"]:
        cov = p["coverage_ci95"]
        ok = cov is not None and 0.92 <= cov <= 0.98
        rows.append(
            [
                esc(p["body"]),
                esc(p["name"]),
                num(p["true"]),
                num(p["identifiable_fraction"]),
                num(p["error_mean"]),
                num(p["error_std"]),
                num(p["stated_std_mean"]),
                num(p["rel_error_rms"]),
                f'<span class="{"ok" if ok else "bad"}">{num(cov)}</span>' if cov is not None else "&ndash;",
            ]
        )
    body = section(
        "coverage",
        "Coverage of the 95 % intervals",
        (
            f"<p>{s['trials']} trials, seeds {s['seeds'][0]} to {s['seeds'][1]}; measurement "
            f"<code>{esc(s['measurement'])}</code>. A parameter's intervals are honest when they contain the true "
            "value in about 95 % of trials (92 to 98 % is the band a 1000-trial sweep should fall in). Coverage "
            "over the parameters "
            f"identified in every trial: {num(s['coverage_min'])} to {num(s['coverage_max'])}.</p>"
            + table(
                [
                    "body",
                    "parameter",
                    "true",
                    "identified in",
                    "mean error",
                    "error std",
                    "stated std (mean)",
                    "rms rel error",
                    "coverage",
                ],
                rows,
            )
        ),
    )
    body += section(
        "errors",
        "Error distributions",
        figure(_histograms(s["parameters"]), "Relative errors of each parameter over the trials (true value at 0)."),
    )
    body += section(
        "levels",
        "Error against noise level",
        figure(
            _levels(s["levels"]), "Median relative error at multiples of the scenario's noise (fewer trials per level)."
        ),
    )
    name = html.escape(s["scenario"])
    return (
        f'<!DOCTYPE html><html lang="en"><head><meta charset="utf-8"><title>{name}: noise sweep</title>'
        f"<style>{STYLE}</style></head><body><h1>{name}: noise sweep</h1>{body}</body></html>\n"
    )
