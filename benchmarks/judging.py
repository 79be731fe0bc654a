"""What the real-log benchmarks (panda.py, tx40.py) share: the relative torque error, and FIGAROH's two
fits made on a benchmark's own training rows through harness/adapters/figaroh.py."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def rel(pred: np.ndarray, measured: np.ndarray) -> float:
    """||pred - measured|| / ||measured|| over every sample and joint."""
    return float(np.linalg.norm(pred - measured) / np.linalg.norm(measured))


def figaroh_fits(model_file: Path, gravity: float, q, qd, qdd, tau) -> dict:
    """FIGAROH's least squares and physical fit of the model file's robot (gravity along -z) on the rows
    given: each its fitted model, or what it raised (a tool's failure is its row)."""
    try:
        from harness.adapters import figaroh
        from harness.model.load import load_spec
    except ImportError as exc:  # pragma: no cover
        return {"least_squares": str(exc), "physical": str(exc)}
    spec = load_spec(model_file)
    out = {}
    for kind in ("least_squares", "physical"):
        try:
            out[kind] = figaroh.make(spec, np.array([0.0, 0.0, -gravity]), {"fit": kind}).fit(q, qd, qdd, tau)
        except Exception as exc:  # a tool's failure is its row
            out[kind] = f"{type(exc).__name__}: {exc}"
    return out
