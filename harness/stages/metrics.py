"""Metrics between two sources of the same joint quantity.

Relative error (harness/base/numerics.py) of a joint quantity: for joint J at time t,

    rel(J, t) = |a(J, t) - b(J, t)| / L_J,

with L_J the largest load joint J carries over the run, the magnitude of the moment it transmits
(revolute) or of the force (prismatic), taken from the recording. The drive torque is one
component of the wrench the joint transmits, and every source computes it from that whole
wrench, so its round-off scales with L_J. Where the torque is a small part of the load (O4 and O6
of kr500_rail turn about the arm's own axis, about which its inertia is small: their torques
reach 1.1e-2 and 5.0e-2 of L_J), dividing by the torque would inflate round-off 20 to 100 times.
"""

from __future__ import annotations

import numpy as np

from harness.base.numerics import relative_error, relative_residual
from harness.base.series import TimeSeries
from harness.model.spec import RobotSpec

DEFINITION = ("relative error = |a - b| / L_J, L_J the largest magnitude over the run of the moment "
              "(revolute) or force (prismatic) that joint J transmits in the recording")


def joint_load_scale(spec: RobotSpec, rec: TimeSeries) -> np.ndarray:
    """L_J for each joint of the spec (spec order)."""
    out = []
    for joint in spec.joints:
        wrench = (rec.M_W if joint.revolute else rec.F_W)[:, rec.joint_index(joint.name)]
        out.append(np.max(np.linalg.norm(wrench, axis=1)))
    return np.array(out)


def pair_metrics(a: np.ndarray, b: np.ndarray, scale: np.ndarray, t: np.ndarray,
                 joints: list[str]) -> dict:
    """Largest absolute and relative error of (N, joints) series, with where they occur."""
    err = np.abs(a - b)
    rel = relative_error(a, b, scale)  # a joint that carries nothing: 0/0 is NaN, reported
    ka, ja = np.unravel_index(np.argmax(err), err.shape)
    kr, jr = np.unravel_index(np.argmax(rel), rel.shape)
    return {
        "max_abs_error": float(err[ka, ja]), "max_abs_joint": joints[ja], "max_abs_t": float(t[ka]),
        "max_rel_error": float(rel[kr, jr]), "max_rel_joint": joints[jr], "max_rel_t": float(t[kr]),
        "max_rel_error_per_joint": dict(zip(joints, (float(x) for x in rel.max(axis=0)), strict=True)),
    }


def wrench_metrics(a: np.ndarray, b: np.ndarray, t: np.ndarray, joints: list[str], floor: float = 0.0) -> dict:
    """(N, joints, 3) wrenches: largest |a - b| relative to the largest |b| of each joint, or, with a
    `floor`, to that fraction of the largest any joint carries where the joint's own is smaller (a
    passive hinge of a planar loop carries no moment: its round-off is not an error)."""
    size = np.max(np.linalg.norm(b, axis=-1), axis=0)
    if size.size:
        size = np.maximum(size, floor * size.max())
    rel = relative_error(np.linalg.norm(a - b, axis=-1), 0.0, size)
    k, j = np.unravel_index(np.argmax(rel), rel.shape)
    return {"max_rel_error": float(rel[k, j]), "max_rel_joint": joints[j], "max_rel_t": float(t[k])}


def largest(values: np.ndarray, where: np.ndarray | None = None) -> float | None:
    """The largest of `values` where `where` holds (NaN ignored), or None when there is none: a
    metric over no evaluated row is not a number, and a gate on it fails closed."""
    values = np.asarray(values, dtype=float)
    if where is not None:
        values = values[np.broadcast_to(where, values.shape)]
    values = values[~np.isnan(values)]
    return float(values.max()) if values.size else None


def torque_errors(pred: np.ndarray, tau: np.ndarray, joints: list[str]) -> dict:
    """Predicted against measured torques of a log, (N, n) each: ||e||_F / ||tau||_F over every
    sample and joint (the figure published identifications quote), the RMS error, and per joint the
    same. A log has no truth to take a joint's load from, so the measured torque is the scale."""
    e = pred - tau
    return {
        "rel_error": relative_residual(e, tau),
        "rms_error": float(np.sqrt(np.mean(e**2))),
        "per_joint": {j: {"rms_error": float(np.sqrt(np.mean(e[:, k] ** 2))),
                          "rel_error": relative_residual(e[:, k], tau[:, k])}
                      for k, j in enumerate(joints)},
    }
