"""Judging a model on a measured log, shared by the log's stages (harness/stages/log_identification.py,
harness/stages/refinement.py): forward simulation from measured states under the measured torques
(`prediction`: how far each model drifts at each horizon)."""

from __future__ import annotations

import numpy as np

from harness.base.numerics import evenly_spaced, finite_or_null
from harness.base.series import room
from harness.engines.rollout import PREDICTION_TIMESTEP, predict

HORIZONS = (0.02, 0.05, 0.1, 0.2)  # s: how far ahead a model is judged by forward simulation
PREDICTION_STARTS = 20  # starts spread evenly over the span


def _starts(t: np.ndarray, reach: float, count: int) -> np.ndarray:
    """Rows from which `reach` seconds lie within the same stretch of the span (no gap crossed)."""
    usable = np.flatnonzero(room(t)[1] >= reach)
    if not len(usable):
        return usable
    return usable[evenly_spaced(len(usable), count)]


def prediction(gravity_W: np.ndarray, models: dict, t: np.ndarray, q: np.ndarray, qd: np.ndarray,
               tau: np.ndarray, span: str, joints: list[str], delays: dict | None = None) -> dict:
    """Each model forward-simulated in MuJoCo from measured states of a span (t (N,), q, q', tau (N, n))
    under the measured torques (harness/engines/rollout.py, predict), each channel read delays[model]
    (n,) s later where given: per horizon the RMS and largest position and velocity error."""
    starts = _starts(t, HORIZONS[-1], PREDICTION_STARTS)
    out = {"definition": f"from {len(starts)} measured states along the {span} span, each model forward-simulated "
                         "in MuJoCo (RK4, 1 ms) under the measured joint torques less its dry friction (Coulomb, "
                         "offset and its family's terms); at each horizon q_sim - q_meas [rad or m] and "
                         "q'_sim - q'_meas: RMS over the starts and joints, the largest joint's RMS, per joint RMS. "
                         "The least-squares fit is not "
                         "simulated: its base parameters are not a full set of physical parameters",
           "span": span, "starts": len(starts), "timestep_s": PREDICTION_TIMESTEP,
           "horizons_s": list(HORIZONS), "models": {}}
    if not len(starts):
        out["note"] = f"no stretch of the {span} span is {HORIZONS[-1]:g} s long"
        return out
    for name, spec in models.items():
        q_err, qd_err = predict(spec, gravity_W, t, q, qd, tau, starts, HORIZONS,
                                delay=(delays or {}).get(name))
        per = {}
        for h, horizon in enumerate(HORIZONS):
            e, ed = q_err[:, h], qd_err[:, h]
            diverged = int(np.sum(~np.all(np.isfinite(e), axis=1)))
            per[f"h{round(horizon * 1e3)}ms"] = {
                "q_rms": finite_or_null(float(np.sqrt(np.mean(e**2)))),
                "q_rms_largest_joint": finite_or_null(float(np.max(np.sqrt(np.mean(e**2, axis=0))))),
                "qd_rms": finite_or_null(float(np.sqrt(np.mean(ed**2)))),
                "q_rms_per_joint": {j: finite_or_null(float(np.sqrt(np.mean(e[:, k] ** 2))))
                                    for k, j in enumerate(joints)},
                "diverged": diverged}
        out["models"][name] = per
    return out
