"""What the paper's bench reads beyond the harness's recording (section 3.1: ADAMS reports each
body's Cardano angles and the accelerations of its joint points), derived from the recording and
measured under the scenario's `[measurement]`.

From a recording's poses and twists, per massive body B:
- theta_B = (alpha, beta, gamma) with A(0i) = R_WB (Eq. 29), extracted continuously along the run
  (harness/papers/graph_theory_2021/cardano.py, angles_from_rotation);
- the rows near gimbal lock, cond(D) > GIMBAL_COND_D (Eq. 33's D loses its inverse there);
- aO_W, the acceleration of B's inner joint point O: a_W + omega'_W x r + omega_W x (omega_W x r),
  r = R_WB r_B the arm from the centre of mass to O (r_B from the model, as a sensor's place on a
  bench is known).

Measured as the bench's other channels are (harness/sources/measurement.py): the same rows
(`every`), Gaussian noise of the `angles` group on theta and of the `accelerations` group on aO_W,
drawn from the study's own stream, then rounding to `significant_digits`. With `differentiate`,
the angular velocities and accelerations and aO_W are re-derived from what was read: omega^(i) =
D theta', omega'^(i) = D theta'' + D' theta' (Eq. 33, which needs no inverse of D and so passes
gimbal lock) and aO_W from the points' positions p_W + A(theta) r_B, all by the cubic
Savitzky-Golay filter over `filter_window` samples. On kr500_rail the error falls at second order
with the step (3 to 4 times per halving); near gimbal lock of a body whose alpha and gamma then
change fast the angle rates are large and the filter loses accuracy: sample finer there. The
gimbal flags are the truth's, not a measurement.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, fields

import numpy as np

from harness.base.series import TimeSeries
from harness.model.kinematics import cross
from harness.papers.graph_theory_2021.cardano import A_0i, D, D_dot, body_angles, gimbal_flags
from harness.sources.measurement import (
    Measurement,
    add_noise_to,
    moved_by_resolution,
    round_significant,
    savgol,
    study_stream,
)
from harness.sources.measurement import dither as dither_recording

STREAM = "graph_theory_2021"  # this study's random stream (harness/sources/measurement.py, study_stream)


@dataclass(frozen=True, eq=False)
class Readings(TimeSeries):
    """A recording with what the paper's bench reads beyond it."""

    theta: np.ndarray | None = None  # (n, nb, 3) Cardano angles (alpha, beta, gamma), Eq. 29
    aO_W: np.ndarray | None = None  # (n, nb, 3) acceleration of each body's inner joint point O
    gimbal: np.ndarray | None = None  # (n, nb) bool: near gimbal lock, cond(D) > GIMBAL_COND_D


ANGLES_FILE = "cardano.csv"  # the bodies' Cardano angles, row by row beside recording.csv
ANGLE_NAMES = ("alpha", "beta", "gamma")


def angles_csv(readings: Readings) -> str:
    """The Cardano angles (Eq. 29) of every body, row by row as the recording's: t, then
    <body>_alpha, <body>_beta, <body>_gamma for each massive body in the recording's order, rad, to
    17 significant digits (a double read back is the same double)."""
    from harness.base.csvtext import csv_text

    theta = readings.theta.reshape(len(readings.t), -1)
    names = (f"{b}_{a}" for b in readings.bodies for a in ANGLE_NAMES)
    return csv_text({"t": readings.t, **{name: theta[:, k] for k, name in enumerate(names)}})


def joint_point_accelerations(rec: TimeSeries, arm_O_B: np.ndarray) -> np.ndarray:
    """(n, nb, 3) the acceleration of each body's inner joint point, from its centre of mass's."""
    r_W = np.einsum("nbij,bj->nbi", rec.R_WB, arm_O_B)
    return rec.a_W + cross(rec.omegadot_W, r_W) + cross(rec.omega_W, cross(rec.omega_W, r_W))


def exact(rec: TimeSeries, arm_O_B: np.ndarray) -> Readings:
    """The readings of a recording as they are (the truth)."""
    theta = body_angles(rec.R_WB)
    return _with(rec, theta=theta, aO_W=joint_point_accelerations(rec, arm_O_B), gimbal=gimbal_flags(theta))


def read(ideal: Readings, measured: TimeSeries, m: Measurement, arm_O_B: np.ndarray) -> Readings:
    """The truth's readings (`exact`) under the measurement `m`, beside the channels `measured`
    (the harness's measurement of the same truth) holds."""
    if m.ideal:
        return _with(measured, theta=ideal.theta, aO_W=ideal.aO_W, gimbal=ideal.gimbal)
    rows = np.arange(0, len(ideal.t), m.every)
    values = {"theta": ideal.theta[rows], "aO_W": ideal.aO_W[rows]}
    rng = study_stream(m, STREAM)
    values.update(add_noise_to(values, {"angles": ("theta",), "accelerations": ("aO_W",)}, m.noise, rng))
    if m.significant_digits is not None:
        values = {c: round_significant(v, m.significant_digits) for c, v in values.items()}
    if m.differentiate:
        values.update(differentiate(measured.t, measured.p_W, values["theta"], m.filter_window, arm_O_B))
    return _with(measured, gimbal=ideal.gimbal[rows], **values)


def differentiate(t: np.ndarray, p_W: np.ndarray, theta: np.ndarray, window: int,
                  arm_O_B: np.ndarray) -> dict[str, np.ndarray]:
    """omega_W, omegadot_W from the measured Cardano angles (Eq. 33) and aO_W from the measured
    positions of the joint points (cubic Savitzky-Golay)."""
    def sg(x: np.ndarray, k: int) -> np.ndarray:
        return savgol(x, t, window, k)

    theta_d, theta_dd = sg(theta, 1), sg(theta, 2)
    th = sg(theta, 0)
    Dm = D(th)
    omega_B = np.einsum("...ab,...b->...a", Dm, theta_d)
    omegadot_B = (np.einsum("...ab,...b->...a", Dm, theta_dd)
                  + np.einsum("...ab,...b->...a", D_dot(th, theta_d), theta_d))
    A = A_0i(th)
    pO_W = p_W + np.einsum("...ab,...b->...a", A_0i(theta), arm_O_B)  # the point where it was read
    return {"aO_W": sg(pO_W, 2), "omega_W": np.einsum("...ab,...b->...a", A, omega_B),
            "omegadot_W": np.einsum("...ab,...b->...a", A, omegadot_B)}


def dither(readings: Readings, m: Measurement, rng: np.random.Generator) -> Readings:
    """Readings as different from `readings` as the measurement allows (harness/sources/measurement.py,
    dither), the angles and joint-point accelerations with the rest."""
    moved = dither_recording(readings, m, rng)
    values = {"theta": readings.theta, "aO_W": readings.aO_W}
    values.update(add_noise_to(values, {"angles": ("theta",), "accelerations": ("aO_W",)}, m.noise, rng))
    return dataclasses.replace(moved, **moved_by_resolution(values, m.resolution, rng))


def _with(rec: TimeSeries, **values) -> Readings:
    """`rec`'s channels, those named in `values` replaced, and the readings in `values`."""
    return Readings(**{**{f.name: getattr(rec, f.name) for f in fields(TimeSeries)}, **values})
