"""report.html: one self-contained file (figures inline as SVG, no scripts, nothing fetched),
read top to bottom: verdict and gates, model, motion, one section per stage that ran (the core's,
then each study's: the core's drawn by RENDERERS, a study's by its stage's own renderer), how the run was made."""

from __future__ import annotations

import html
from pathlib import Path

import numpy as np

from harness.engines.recording import Recording, read_csv
from harness.report import sections

STYLE = """
body { font-family: system-ui, sans-serif; max-width: 60rem; margin: 1rem auto; padding: 0 1rem; color: #222; }
h1 { font-size: 1.5rem; } h2 { border-bottom: 1px solid #ccc; margin-top: 2rem; } h3 { font-size: 1rem; }
table { border-collapse: collapse; font-size: 0.8rem; margin: 0.5rem 0; }
th, td { border: 1px solid #ddd; padding: 0.15rem 0.4rem; text-align: right; vertical-align: top; }
th { background: #f4f4f4; } td:first-child, th:first-child { text-align: left; }
td { white-space: nowrap; } table.wrap td, td:first-child, td small { white-space: normal; }
td code { font-size: 0.7rem; }
.verdict { font-size: 2rem; font-weight: bold; padding: 0.4rem 1rem; display: inline-block; border-radius: 0.3rem; }
.pass { background: #d8f5d8; color: #145214; } .fail { background: #fbd9d9; color: #7a1010; }
.ok { color: #145214; } .bad { color: #9b1111; font-weight: bold; } .warn { color: #7a4b00; }
figure { margin: 0.8rem 0; } figure svg { max-width: 100%; height: auto; }
figcaption { font-size: 0.8rem; color: #555; }
pre { background: #f7f7f7; padding: 0.5rem; font-size: 0.75rem; overflow-x: auto; }
nav a { margin-right: 0.8rem; font-size: 0.85rem; }
"""

# The core stages' sections, by the stage's key; a study's stages bring their own (Stage.render).
RENDERERS = {
    "torques": lambda r, rec: sections.torques(r),
    "torque_identification": lambda r, rec: sections.torque_identification(r),
    "identification_methods": lambda r, rec: sections.identification_methods(r),
    "estimators": lambda r, rec: sections.estimator_comparison(r),
    "payload": lambda r, rec: sections.payload(r),
    "log_identification": sections.log_identification,
}


def _registered_stages(results: dict) -> list:
    """The core's stages, then those of the studies that ran, found through the same registry the
    run used (a study that is no longer installed: its sections are left out, the rest is drawn)."""
    from harness.base.plugins import PluginError, load_study
    from harness.stages import core_stages, log_stages

    stages = list(log_stages() if "data" in results else core_stages())
    for name in results["run"].get("studies", []):
        try:
            stages += load_study(name).stages
        except PluginError:
            continue
    return stages


def render(results: dict, rec: Recording, stages: list | None = None) -> str:
    """The report of a results.json and its recording. `stages` (default: the registered ones
    of the studies the results name) give the sections after the motion, one per stage result."""
    with np.errstate(invalid="ignore", divide="ignore"):  # an undefined error is drawn as a gap
        return _render(results, rec, stages)


def _render(results: dict, rec: Recording, stages: list | None) -> str:
    name = results["scenario"]["name"]
    if "data" in results:  # a measured log: its conditioning and signals in place of the motion
        parts = [sections.verdict(results), sections.model(results), sections.data(results, rec)]
        nav = [("verdict", "Verdict"), ("model", "Model"), ("data", "Measured log")]
    else:
        parts = [sections.verdict(results), sections.model(results), sections.motion(results, rec)]
        nav = [("verdict", "Verdict"), ("model", "Model"), ("motion", "Motion")]
    if "excitation" in results:
        parts.append(sections.excitation(results))
        nav.append(("excitation", "Excitation"))
    for stage in stages if stages is not None else _registered_stages(results):
        draw = stage.render or RENDERERS.get(stage.key)
        if draw is not None and stage.key in results:
            parts.append(draw(results, rec))
            nav.append((stage.key, stage.title))
    parts.append(sections.how(results))
    nav.append(("how", "How the run was made"))
    body = "".join(parts)
    nav = "".join(f'<a href="#{a}">{t}</a>' for a, t in nav)
    return (
        f'<!DOCTYPE html><html lang="en"><head><meta charset="utf-8"><title>{html.escape(name)}: '
        f"{'PASSED' if results['passed'] else 'FAILED'}</title><style>{STYLE}</style></head><body>"
        f"<h1>{html.escape(name)}</h1><p>{html.escape(results['scenario']['description'])}</p>"
        f"<nav>{nav}</nav>{body}</body></html>\n"
    )


def render_report(results: dict, results_dir: Path) -> str:
    """The report of a results.json's content, with the recording (or log) beside it."""
    if "data" in results:
        from harness.sources.log import read_log_csv

        rec = read_log_csv(Path(results_dir) / results["data"]["file"])
    else:
        rec = read_csv(Path(results_dir) / results["recording"]["file"])
    return render(results, rec)

