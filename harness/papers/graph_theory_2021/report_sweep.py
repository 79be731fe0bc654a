"""sweep.html: the Monte Carlo study of one scenario's measurement noise, self-contained."""

from __future__ import annotations

import numpy as np

from harness.report import plots
from harness.report.html import DASH, esc, figure, mark, num, page, section, table


def _histograms(params: list[dict]) -> str:
    shown = [p for p in params if p["trials"] > 1]
    return plots.histograms([(f"{p['body']}.{p['name']}", np.asarray(p["errors"], dtype=float)) for p in shown],
                            "relative error")


def _levels(levels: list[dict]) -> str:
    names = [k for k, v in levels[0]["median_rel_error"].items() if v is not None]
    f = np.array([lv["level"] for lv in levels], dtype=float)
    series = {name: np.array([lv["median_rel_error"][name] or np.nan for lv in levels], dtype=float) for name in names}
    return plots.lines(f, series, "median |relative error|", "Error against noise level", logy=True,
                       styles={name: "-o" for name in names}, xlabel="noise level (multiple of the scenario's)",
                       logx=True)


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
                mark(ok, num(cov)) if cov is not None else DASH,
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
    return page(f"{s['scenario']}: noise sweep", f"{s['scenario']}: noise sweep", body)
