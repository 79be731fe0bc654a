"""Torque constants from motor currents: each joint's factor between the torque its currents give
with the nominal constant and the torque it carries.

A log of currents read with nominal constants gives tau_nom = i k_nom N; the joint carries
f_j tau_nom,j, with f_j unknown. The base parameters beta and the factors f solve, by least squares,

    W_1 beta - f o tau_nom,1 = 0                  (the log)
    W_2 beta - f o tau_nom,2 = -W_b,2 theta_p      (a log of the robot carrying a known payload)

(o: each joint's rows times its factor; W_b,2 theta_p the torques the payload's ten known parameters
add, on the columns of the body carrying it). The payload's known torques fix the scale. Without
them the first equations alone fix (beta, f) only up to one common scale: the smallest right singular
vector of [W_1, -tau_nom,1], scaled by the median ratio of the model's own base parameters to its
beta (over those the model gives a size), and said so. Columns are scaled to unit norm (harness/base/numerics.py).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from harness.base.numerics import column_scale, relative_residual
from harness.base.series import TimeSeries

SIZED = 1e-3  # of the largest: a model's base parameter below it gives no scale


@dataclass(frozen=True)
class TorqueScales:
    factor: np.ndarray  # (n,) the carried torque over the torque the nominal constant gives, per joint
    std: np.ndarray | None  # (n,) its standard deviation (the payload's least squares), None up to a scale
    fixed_by: str  # "payload" or "model"
    relative_residual: float  # of the stacked equations


def _per_joint(tau: np.ndarray) -> np.ndarray:
    """(N n, n): row (k, j) holds tau[k, j] in column j."""
    N, n = tau.shape
    D = np.zeros((N * n, n))
    D[np.arange(N * n), np.tile(np.arange(n), N)] = tau.ravel()
    return D


def torque_scales(W1: np.ndarray, tau1: np.ndarray, beta_model: np.ndarray, W2: np.ndarray | None = None,
                  tau2: np.ndarray | None = None, known2: np.ndarray | None = None) -> TorqueScales:
    """W1 (N1 n, r) the base regressor of the log and tau1 (N1, n) its torques at the nominal constants;
    with a payload log, W2, tau2 and known2 (N2, n), the torques the payload adds."""
    r = W1.shape[1]
    if W2 is None:
        A = np.hstack([W1, -_per_joint(tau1)])
        col = column_scale(A)
        _, sv, Vt = np.linalg.svd(A / col, full_matrices=False)
        x = Vt[-1] / col
        beta, f = x[:r], x[r:]
        # the scale: the median ratio of the model's base parameters to these, over those the model
        # gives a size (a friction term the model leaves at zero says nothing of the scale)
        sized = (np.abs(beta_model) > SIZED * np.max(np.abs(beta_model))) & (beta != 0)
        alpha = float(np.median(beta_model[sized] / beta[sized]))
        return TorqueScales(alpha * f, None, "model", float(sv[-1] / sv[0]))
    A = np.vstack([np.hstack([W1, -_per_joint(tau1)]), np.hstack([W2, -_per_joint(tau2)])])
    b = np.concatenate([np.zeros(len(W1)), -known2.ravel()])
    col = column_scale(A)
    z, *_ = np.linalg.lstsq(A / col, b, rcond=None)
    x = z / col
    residual = A @ x - b
    dof = max(len(b) - A.shape[1], 1)
    sigma2 = float(residual @ residual) / dof
    cov = sigma2 * np.linalg.pinv((A / col).T @ (A / col))
    std = np.sqrt(np.diag(cov))[r:] / col[r:]
    return TorqueScales(x[r:], std, "payload", relative_residual(residual, b))


def payload_parameters(mass: float, com_W: np.ndarray, inertia_c: np.ndarray, p_J: np.ndarray) -> np.ndarray:
    """(10,) a load's parameters in the joint frame of the body carrying it (at the joint point p_J,
    world axes at q = 0): m, m d, the inertia about p_J (harness/model/inertia.py's layout), from its
    mass, centre of mass and inertia about it [Ixx, Iyy, Izz, Ixy, Ixz, Iyz] in the world frame at q = 0."""
    from harness.model.inertia import parallel_axis

    xx, yy, zz, xy, xz, yz = inertia_c
    d = np.asarray(com_W, dtype=float) - np.asarray(p_J, dtype=float)
    I = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]]) + parallel_axis(mass, d)
    return np.array([mass, *(mass * d), I[0, 0], I[0, 1], I[1, 1], I[0, 2], I[1, 2], I[2, 2]])


def torque_constants(pm, base, W: np.ndarray, tau: np.ndarray, beta_model: np.ndarray, robot, payload=None,
                     loaded: TimeSeries | None = None) -> TorqueScales:
    """Each joint's factor on its nominal torque constant, from the training span's regressor W (N n,
    14 n: harness/identify/torque_id.py, with friction) and torques tau (N, n) at the nominal
    constants: fixed by `loaded`, a log of the robot carrying `payload` (the scenario's
    `[data.payload]`, a harness.sources.log.KnownPayload, conditioned as the log), where given; else
    by the model's own base parameters `beta_model` (`base` the structural base parameters)."""
    from harness.identify.torque_id import regressor

    if payload is None:
        return torque_scales(W[:, base.independent], tau, beta_model)
    joints = robot.joint_names
    q2, qd2, qdd2, tau2 = loaded.joint_data(joints)
    W2 = regressor(pm, q2, qd2, qdd2, with_friction=True)
    k = joints.index(robot.inner_joint(payload.body).name)
    theta_p = payload_parameters(payload.mass, payload.com_W, payload.inertia, robot.joints[k].p_W0)
    known = (W2[:, 10 * k: 10 * k + 10] @ theta_p).reshape(tau2.shape)
    return torque_scales(W[:, base.independent], tau, beta_model, W2[:, base.independent], tau2, known)


def scaled(series: TimeSeries, factor: np.ndarray, joints) -> TimeSeries:
    """The series with each joint's torque times its factor (joints in `joints`' order)."""
    cols = [series.joint_index(j) for j in joints]
    tau = series.tau.copy()
    tau[:, cols] *= factor
    return dataclasses.replace(series, tau=tau)
