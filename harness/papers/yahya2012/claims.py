"""The second seed's claims about its two designs (Yahya et al. 2012, section 4), checked on the
torques MuJoCo applied (which Pinocchio and the graph model reproduce to 1e-9 or better).

1. The torque of the last joint is the same in both designs (its link carries no motor in either).
2. Each joint's torque is smaller in the proposed design: peak |tau| and RMS over the run (a joint
   whose torque is the same in both, within 1e-9, counts as equal, not as smaller or larger).
3. The shared motor of the proposed design, tau_3 + tau_4 + tau_5 + tau_6 (joints driven through
   gears at one speed: the motor's power is the sum of theirs), needs less torque than joint 3 of
   the conventional design.
"""

from __future__ import annotations

import numpy as np

from harness.base.series import TimeSeries
from harness.model.spec import RobotSpec
from harness.stages.metrics import joint_load_scale


def _peak_rms(x: np.ndarray) -> tuple[float, float]:
    return float(np.max(np.abs(x))), float(np.sqrt(np.mean(x**2)))


def design_claims(spec: RobotSpec, proposed: TimeSeries, baseline: TimeSeries, shared: list[str],
                  baseline_joint: str) -> dict:
    joints = spec.joint_names
    tau_p = proposed.tau[:, [proposed.joint_index(j) for j in joints]]
    tau_c = baseline.tau[:, [baseline.joint_index(j) for j in joints]]
    claims = []
    last = joints[-1]
    scale = joint_load_scale(spec, baseline)[-1]
    diff = float(np.max(np.abs(tau_p[:, -1] - tau_c[:, -1])) / scale)
    claims.append({"claim": f"joint {last} torque is the same in both designs", "holds": diff <= 1e-9,
                   "numbers": {"max_rel_difference": diff}})
    per_joint = []
    for k, j in enumerate(joints):
        pp, pr = _peak_rms(tau_p[:, k])
        cp, cr = _peak_rms(tau_c[:, k])
        ratios = (pp / cp, pr / cr)
        verdict = ("equal" if all(abs(x - 1) <= 1e-9 for x in ratios) else
                   "smaller" if all(x < 1 for x in ratios) else "larger")
        per_joint.append({"joint": j, "proposed_peak": pp, "conventional_peak": cp, "proposed_rms": pr,
                          "conventional_rms": cr, "peak_ratio": ratios[0], "rms_ratio": ratios[1],
                          "proposed_is": verdict})
    by = {v: [r["joint"] for r in per_joint if r["proposed_is"] == v] for v in ("smaller", "equal", "larger")}
    claims.append({"claim": "every joint needs less torque in the proposed design (peak and RMS), but for the "
                            "joints whose torque is the same in both",
                   "holds": not by["larger"],
                   "numbers": {f"{v}_at": js for v, js in by.items()}})
    motor = tau_p[:, [joints.index(j) for j in shared]].sum(axis=1)
    mp, mr = _peak_rms(motor)
    bp, br = _peak_rms(tau_c[:, joints.index(baseline_joint)])
    claims.append({"claim": f"the shared motor ({' + '.join(shared)}) needs less torque than joint "
                            f"{baseline_joint} of the conventional design",
                   "holds": mp < bp and mr < br,
                   "numbers": {"motor_peak": mp, "motor_rms": mr, "conventional_peak": bp, "conventional_rms": br,
                               "peak_ratio": mp / bp, "rms_ratio": mr / br}})
    return {"claims": claims, "per_joint": per_joint, "t": proposed.t.tolist(),
            "proposed": tau_p.tolist(), "conventional": tau_c.tolist(), "shared_motor": motor.tolist(),
            "shared": list(shared), "baseline_joint": baseline_joint}
