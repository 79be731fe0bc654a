"""report.html: one self-contained file (figures inline as SVG, no scripts, nothing fetched),
read top to bottom: verdict and gates, model, motion, one section per stage that ran (the core's,
then each study's: the core's drawn by RENDERERS, a study's by its stage's own renderer), how the run was made."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from harness.base.series import TimeSeries, read_csv
from harness.report import log_sections, sections
from harness.report.html import page

# The core stages' sections, by the stage's key; a study's stages bring their own (Stage.render).
RENDERERS = {
    "torques": lambda r, rec: sections.torques(r),
    "torque_identification": lambda r, rec: sections.torque_identification(r),
    # on a measured log, the table of harness/stages/log_methods.py
    "identification_methods": lambda r, rec: (log_sections.log_methods(r) if "data" in r
                                               else sections.identification_methods(r)),
    "estimators": lambda r, rec: sections.estimator_comparison(r),
    "payload": lambda r, rec: sections.payload(r),
    "log_identification": log_sections.log_identification,
    "floating_log": log_sections.floating_log,
    "refinement": lambda r, rec: log_sections.refinement(r),
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


def render(results: dict, rec: TimeSeries, stages: list | None = None) -> str:
    """The report of a results.json and its recording. `stages` (default: the registered ones
    of the studies the results name) give the sections after the motion, one per stage result."""
    with np.errstate(invalid="ignore", divide="ignore"):  # an undefined error is drawn as a gap
        return _render(results, rec, stages)


def _render(results: dict, rec: TimeSeries, stages: list | None) -> str:
    name = results["scenario"]["name"]
    if "data" in results:  # a measured log: its conditioning and signals in place of the motion
        parts = [sections.verdict(results), sections.model(results), log_sections.data(results, rec)]
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
    return page(f"{name}: {'PASSED' if results['passed'] else 'FAILED'}", name, "".join(parts),
                results["scenario"]["description"], nav)


def render_report(results: dict, results_dir: Path) -> str:
    """The report of a results.json's content, with the recording (or log) beside it."""
    kind = "data" if "data" in results else "recording"
    rec = read_csv(Path(results_dir) / results[kind]["file"], bodies=kind == "recording")
    return render(results, rec)

