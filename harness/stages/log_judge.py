"""Judging a model on a measured log, shared by the log's stages (harness/stages/log_identification.py,
harness/stages/refinement.py): forward simulation from measured states under the measured torques
(`prediction`: how far each model drifts at each horizon), and the model as given against the log as
read (`start`: a log whose torques are off the model's by a factor or a sign was read wrongly)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from harness.base.numerics import PREDICTION_TIMESTEP, evenly_spaced, finite_or_null, sampled
from harness.base.series import TimeSeries, room
from harness.engines.rollout import log_drives, predict
from harness.sources.log.schema import Prediction


def as_fitted(validation: TimeSeries | None, lags, factor: np.ndarray | None, joints: list[str]) -> TimeSeries | None:
    """The validation span as the fit's findings on the training span make it, applied here by the judging
    (the fit never reads it): each delay found there corrected (`lags`, harness/identify/delay.py; None
    where the fit did not correct them) and each torque constant found there applied (`factor`,
    harness/identify/scale.py; None for a log of torques), as they were to the training span."""
    from harness.identify import delay, scale

    if validation is None:
        return None
    if lags is not None:
        validation = delay.corrected(validation, lags, joints)
    return validation if factor is None else scale.scaled(validation, factor, joints)


def prediction_starts(t: np.ndarray, reach: float, count: int) -> np.ndarray:
    """Rows from which `reach` seconds lie within the same stretch of the span (no gap crossed)."""
    usable = np.flatnonzero(room(t)[1] >= reach)
    if not len(usable):
        return usable
    return usable[evenly_spaced(len(usable), count)]


def prediction(gravity_W: np.ndarray | dict, models: dict, t: np.ndarray, q: np.ndarray, qd: np.ndarray,
               tau: np.ndarray, span: str, joints: list[str], delays: dict | None = None,
               not_made: str | None = None, plan: Prediction | None = None) -> dict:
    """Each model forward-simulated in MuJoCo from `plan.starts` measured states of a span (t (N,), q,
    q', tau (N, n)) under the measured torques (harness/engines/rollout.py, predict), each channel read
    delays[model] (n,) s later where given: at each of `plan.horizons` the RMS and largest position and
    velocity error. Not made where the log's torques cannot drive the models (`not_made` says why:
    joints without a torque, a counterweight the models lack) or no start is asked for, said. `plan`:
    [data] prediction's (harness/sources/log/schema.py, Prediction; None, its defaults). `gravity_W`: one
    for every model, or each model's by name (a log's identified models at the gravity the torques give,
    the model as given at the declared one: harness/identify/gravity.py)."""
    plan = plan or Prediction()
    gravity_W = gravity_W if isinstance(gravity_W, dict) else dict.fromkeys(models, gravity_W)
    horizons = plan.horizons
    starts = prediction_starts(t, horizons[-1], plan.starts)
    out = {"definition": f"from {len(starts)} measured states along the {span} span, each model forward-simulated "
                         "in MuJoCo (RK4, 1 ms) under the measured joint torques less its dry friction (Coulomb, "
                         "offset and its family's terms); at each horizon q_sim - q_meas [rad or m] and "
                         "q'_sim - q'_meas: RMS over the starts and joints, the largest joint's RMS, per joint RMS. "
                         "The least-squares fit is not "
                         "simulated: its base parameters are not a full set of physical parameters",
           "span": span, "starts": len(starts), "timestep_s": PREDICTION_TIMESTEP,
           "horizons_s": list(horizons), "models": {}}
    note = not_predicted(plan, starts, span, not_made)
    if note is not None:
        out["note"] = note
        return out
    chains = {name: spec for name, spec in models.items() if spec.loops}
    if chains:
        out["definition"] = CHAIN_PREDICTION + out["definition"].split("; at each horizon", 1)[1]
        chains = predict_chains(chains, gravity_W, t, q, qd, tau, starts, horizons)
    for name, spec in models.items():
        q_err, qd_err = chains[name] if spec.loops else predict(spec, gravity_W[name], t, q, qd, tau, starts, horizons,
                                                                delay=(delays or {}).get(name))
        per = {}
        for h, horizon in enumerate(horizons):
            e, ed = q_err[:, h], qd_err[:, h]
            per[f"h{round(horizon * 1e3)}ms"] = {**joint_drift(e, joints),
                                                 "qd_rms": finite_or_null(float(np.sqrt(np.mean(ed**2)))),
                                                 "diverged": int(np.sum(~np.all(np.isfinite(e), axis=1)))}
        out["models"][name] = per
    return out


def not_predicted(plan: Prediction, starts: np.ndarray, span: str, not_made: str | None = None) -> str | None:
    """Why no forward prediction is made from a span (`not_made`, the caller's reason; no start asked for; no
    stretch of the span as long as the last horizon), None where one is."""
    if not_made:
        return not_made
    if not plan.starts:
        return "not made: [data] prediction.starts = 0"
    return None if len(starts) else f"no stretch of the {span} span is {plan.horizons[-1]:g} s long"


def joint_drift(e: np.ndarray, joints: list[str]) -> dict:
    """A horizon's joints' position errors e (starts, n): the RMS over every start and joint, the largest joint's
    RMS and each joint's (null where not finite)."""
    return {"q_rms": finite_or_null(float(np.sqrt(np.mean(e**2)))),
            "q_rms_largest_joint": finite_or_null(float(np.max(np.sqrt(np.mean(e**2, axis=0))))),
            "q_rms_per_joint": {j: finite_or_null(float(np.sqrt(np.mean(e[:, k] ** 2)))) for k, j in enumerate(joints)}}


CHAIN_PREDICTION = (
    "from measured states along the span, each closed-chain model forward-simulated by its own inverse "
    "dynamics (G^T rnea with every joint's friction law) in the actuated coordinates, the loops rigid and closed "
    "at every stage (harness/model/chain_forward.py; RK4, 1 ms) under the measured actuated torques")


def _geometry(spec) -> bytes:
    """What a closed chain's kinematics read of its spec: its joints' and loops' placements."""
    parts = [f"{j.name}|{j.type}|{j.parent}|{j.child}".encode() + j.p_W0.tobytes() + j.axis_W0.tobytes()
             for j in spec.joints]
    parts += [f"{lp.name}|{lp.kind}|{lp.body_a}|{lp.body_b}".encode()
              + b"".join(np.asarray(x, dtype=float).tobytes() for x in (lp.point_a_W0, lp.point_b_W0)
                         + tuple(r for r in (lp.R_W_frame_a0, lp.R_W_frame_b0) if r is not None))
              for lp in spec.loops]
    return b"/".join(parts) + "/".join(spec.actuated).encode()


def _stacked(pms: list, owners: np.ndarray):
    """The tree's inverse dynamics of a batch of runs, run r by the model pms[owners[r]]: each run's
    rows come together, in run order (harness/model/chain_forward.py, actuated_acceleration), projected
    onto the actuated joints there."""
    from harness.engines.pinocchio import joint_torques
    from harness.model.chain_forward import TreeInverseDynamics

    def torques(qq: np.ndarray, vv: np.ndarray, aa: np.ndarray) -> np.ndarray:
        of_row = np.repeat(owners, len(qq) // len(owners))
        tau = np.empty_like(qq)
        for m in np.unique(owners):
            rows = of_row == m
            tau[rows] = joint_torques(pms[m], qq[rows], vv[rows], aa[rows])
        return tau

    return TreeInverseDynamics(torques)


def predict_chains(specs: dict, gravity_W: dict, t: np.ndarray, q: np.ndarray, qd: np.ndarray,
                   tau_a: np.ndarray, starts: np.ndarray, horizons: tuple[float, ...],
                   timestep: float = PREDICTION_TIMESTEP) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """`predict` of closed chains, per model: from each start row every joint's measured (q, q')
    (consistent: the passive joints' from the loops), its actuated torques tau_a (N, n_a) read from the
    log at every stage (linear interpolation), the model's forward dynamics (chain_forward.rollout_states,
    its inverse dynamics Pinocchio's with its friction laws, projected by G); at each horizon q_sim -
    q_meas and q'_sim - q'_meas of every joint, (starts, horizons, n), NaN for a start whose run left
    the loops' reach or met a singular mass matrix. Models of one geometry (joints and loops) run as one
    batch: their kinematics are shared, only their inverse dynamics differ."""
    from harness.engines.pinocchio import build_model
    from harness.model import chain_forward
    from harness.model.closure import ClosedChain, ClosureError, motion

    steps = np.array([round(h / timestep) for h in horizons])
    drives = log_drives(t, tau_a, t[starts], int(steps[-1]), timestep)  # (B, 2 S + 1, n_a)
    k = np.arange(steps[-1])
    stage_tau = drives[:, np.stack([2 * k, 2 * k + 1, 2 * k + 1, 2 * k + 2], axis=1)]  # (B, S, 4, n_a)
    at = t[starts][:, None] + steps * timestep
    B, n = len(starts), q.shape[1]
    groups: dict[bytes, list[str]] = {}
    for name, spec in specs.items():
        groups.setdefault(_geometry(spec), []).append(name)
    out = {}
    for names in groups.values():
        chain = ClosedChain.of(specs[names[0]])
        pms = [build_model(specs[name], gravity_W[name]) for name in names]
        act = list(chain.actuated)
        model_of = np.repeat(np.arange(len(names)), B)  # rollout r: model model_of[r], start r % B
        q_h, qd_h = (np.full((len(names) * B, len(steps), n), np.nan) for _ in range(2))
        batches = [np.arange(len(names) * B)]
        while batches:  # all at once; where one run fails, each on its own
            runs = batches.pop()
            first = starts[runs % B]
            try:
                q_sim, qd_a = chain_forward.rollout_states(chain, _stacked(pms, model_of[runs]), q[first],
                                                           qd[first][:, act], stage_tau[runs % B], timestep)
            except (chain_forward.ChainForwardError, ClosureError):
                batches += [runs[i:i + 1] for i in range(len(runs))] if len(runs) > 1 else []
                continue
            q_h[runs] = q_sim[:, steps]
            qd_h[runs] = motion(chain, q_h[runs].reshape(-1, n), qd_a[:, steps].reshape(-1, len(act)),
                                np.zeros((len(runs) * len(steps), len(act)))).qd.reshape(len(runs), len(steps), n)
        q_ref, qd_ref = sampled(t, q, at), sampled(t, qd, at)
        for m, name in enumerate(names):
            out[name] = (q_h[m * B:(m + 1) * B] - q_ref, qd_h[m * B:(m + 1) * B] - qd_ref)
    return out


START_FACTOR = 3.0  # the model as given and the log as read differ by more than this factor: a reading mistake
# (a motor current is the joint torque over k_t N, tens to hundreds of times smaller; a unit's prefix is 1000),
# where a model from CAD data with its friction missing is off by tens of percent
SHAPED = 0.5  # a joint's torques and the model's torques there have a cosine of at least this: the model has
# the log's shape at that joint, so the factor between them is the reading's (a wrist the model gives no friction
# has not: its factor says nothing)


UNRELATED = 0.2  # a channel whose cosine with the model's torque is under this in magnitude does not follow it
SIZED = 0.01  # where the model's torque there is at least this share of the largest joint's RMS (a joint the
# model moves hardly at all says nothing by its cosine)


OUTLIER = 10.0  # a row whose torque lies this many robust standard deviations (1.4826 x the median absolute
# deviation) off the median-ratio line is left out of the factors: no single cell decides the diagnosis


@dataclass(frozen=True)
class Start:
    """The model as given against the log as read on the training span, from robust statistics: the
    least-squares factor s = <tau_model, tau_log> / <tau_model, tau_model> over all joints and per joint,
    and per joint the cosine of the two, each over the rows that are not outliers (OUTLIER robust
    standard deviations off the line of the median ratio tau_log / tau_model, taken where |tau_model| is
    at least its median); the findings (a factor outside [1 / START_FACTOR, START_FACTOR] or a sign
    flipped, over all joints or at a joint whose cosine is at least SHAPED in magnitude), each with its
    likely cause."""

    factor: float
    per_joint: dict[str, dict[str, float]]  # joint -> {"factor", "cosine", "outliers"}
    findings: list[dict[str, str]]  # {"joint" (or "all joints"), "finding", "likely"}
    outliers: int = 0  # over all joints: the entries left out of the overall factor
    unrelated: tuple[str, ...] = ()  # joints whose channel does not follow the model's torque (UNRELATED)

    def said(self) -> list[str]:
        """The findings as the terminal and the report's head say them, before anything else of the run."""
        out = [f"the model as given and the log as read differ at {f['joint']} by a {f['finding']}: likely "
               f"{f['likely']}" for f in self.findings]
        if self.unrelated:
            out.append(f"torque channels that do not follow the model's torque (cosine under {UNRELATED:g} where the "
                       "model's torque is not small): " + ", ".join(
                           f"{j} ({self.per_joint[j]['cosine']:.2f})" for j in self.unrelated)
                       + ": channels that measure nothing, or another joint's? The fit reads them as measured "
                         "([data] unmeasured = [...] leaves a channel out, its joint's motion kept)")
        return out

    def as_dict(self) -> dict:
        first = self.findings[0] if self.findings else {}
        return {"definition": "the model as given against the torques as read, on the training span: the least-squares "
                              "factor s = <tau_model, tau_log> / <tau_model, tau_model> over all joints and per joint "
                              "(tau_log = s tau_model at best), and per joint the cosine of the two, each over the "
                              f"rows that are not outliers (over {OUTLIER:g} robust standard deviations, 1.4826 x the "
                              "median absolute deviation, off the line of the median ratio tau_log / tau_model where "
                              "|tau_model| is at least its median); a finding is a factor beyond "
                              f"{START_FACTOR:g} either way or a sign flipped, over all joints or at a joint where the "
                              f"cosine is at least {SHAPED:g} in magnitude",
                "factor": finite_or_null(self.factor), "outliers": self.outliers, "per_joint": self.per_joint,
                "findings": len(self.findings), "findings_joint": first.get("joint", ""),
                "findings_likely": first.get("likely", ""), "list": self.findings, "said": self.said(),
                "unrelated_channels": list(self.unrelated)}


def robust_fit(m: np.ndarray, y: np.ndarray) -> tuple[float, float, int]:
    """(s, cosine, outliers): the least-squares factor of y on m and their cosine over the entries that
    are not outliers of the median-ratio line (Start's docstring), and how many were left out; NaN
    where m carries nothing."""
    m, y = m.ravel(), y.ravel()
    big = np.abs(m) >= np.median(np.abs(m))
    big &= m != 0
    if not big.any():
        return float("nan"), float("nan"), 0
    r = y - float(np.median(y[big] / m[big])) * m
    spread = np.abs(r - np.median(r))
    keep = spread <= OUTLIER * 1.4826 * np.median(spread)
    m, y = m[keep], y[keep]
    mm, norms = float(m @ m), float(np.linalg.norm(m) * np.linalg.norm(y))
    s = float(m @ y) / mm if mm > 0 else float("nan")
    return s, float(m @ y) / norms if norms > 0 else float("nan"), int(np.sum(~keep))


def _likely(s: float) -> str:
    if s < 0:
        return ("the log's torques have the opposite sign of the model's: a sign convention (a reaction torque "
                "logged), or a joint axis the other way in the model")
    if s < 1:
        return ("the log's torques are far smaller than the model's: motor currents read as torques (give units = "
                "{ tau = \"current\" } with torque_constant and gear_ratio), a motor-side torque before its gear, "
                "a unit too large (kN m?), or a model far heavier than the robot")
    return ("the log's torques are far larger than the model's: a unit too small (N mm or mN m read as N m?), or a "
            "model too light (its masses in the wrong unit, or bodies missing)")


COUNTERBALANCED = ("a counterbalanced joint: its channel carries no gravity (a spring or a counterweight holds it), "
                   "as the model's torques there less their gravity match it (declare it: [data] counterbalanced)")


def _off(s: float) -> bool:
    return s < 0 or not (1 / START_FACTOR <= s <= START_FACTOR)


def start(model: np.ndarray, log: np.ndarray, joints: list[str], weightless=None,
          counterbalanced: tuple[str, ...] = ()) -> Start:
    """`model` (N, n) the model as given's torques at the log's states as the log reads them (a joint
    declared `counterbalanced` without its gravity: harness/stages/log_model.py, LogModel.torques),
    `log` (N, n) the torques as read; `weightless`, where given, a function giving the model's torques
    there without gravity (N, n), called only where a joint is off the model's by a factor: a joint whose
    channel is that but matches them without gravity (factor within the band, their cosine at least
    SHAPED) is a counterbalanced joint, its finding's likely cause (and the overall factor judged with
    that joint's weightless torques); a declared one is said so."""
    declared = [joints.index(j) for j in counterbalanced if j in joints]
    without = None
    fits = [robust_fit(model[:, k], log[:, k]) for k in range(len(joints))]
    off = [k for k, (s, _, _) in enumerate(fits) if k not in declared and np.isfinite(s) and _off(s)]
    balanced = []
    if weightless is not None and off:
        without = weightless() if without is None else without
        for k in off:
            s0, cosine0, _ = robust_fit(without[:, k], log[:, k])
            if np.isfinite(s0) and not _off(s0) and abs(cosine0) >= SHAPED:
                balanced.append(k)
    overall, _, left_out = robust_fit(model, log)
    findings, per_joint = [], {}
    if np.isfinite(overall) and _off(overall):
        cleared = model.copy()
        cleared[:, balanced] = without[:, balanced] if balanced else cleared[:, balanced]
        cause = (COUNTERBALANCED.replace("a counterbalanced joint", "a counterbalanced joint, "
                                         + ", ".join(joints[k] for k in balanced))
                 if balanced and not _off(robust_fit(cleared, log)[0]) else _likely(overall))
        findings.append({"joint": "all joints", "finding": f"factor {overall:.3g}", "likely": cause})
    for k, j in enumerate(joints):
        s, cosine, outliers = fits[k]
        per_joint[j] = {"factor": finite_or_null(s), "cosine": finite_or_null(cosine), "outliers": outliers,
                        **({"counterbalanced": "declared"} if k in declared else
                           {"counterbalanced": "likely"} if k in balanced else {})}
        if k in balanced and not findings:
            findings.append({"joint": j, "finding": f"factor {s:.3g}", "likely": COUNTERBALANCED})
        elif np.isfinite(s) and abs(cosine) >= SHAPED and _off(s) and (s < 0 or not findings):
            findings.append({"joint": j, "finding": f"factor {s:.3g} (cosine {cosine:.2f})", "likely": _likely(s)})
    rms = np.sqrt(np.mean(model**2, axis=0))
    unrelated = tuple(j for k, j in enumerate(joints) if rms[k] >= SIZED * rms.max()
                      and np.isfinite(per_joint[j]["cosine"] if per_joint[j]["cosine"] is not None else np.nan)
                      and abs(per_joint[j]["cosine"]) < UNRELATED)
    return Start(overall, per_joint, findings, left_out, unrelated)

