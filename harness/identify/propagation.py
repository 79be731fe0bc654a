"""The covariance of a joint-torque identification from the sensors' specification: first-order
propagation of the measurement's declared errors (harness/sources/measurement.py) through the regressor,
as the GUM propagates an instrument's uncertainty, for the instrumental-variable estimator
(harness/identify/estimators.py, `iv`).

The IV estimate is beta_hat - beta = (Z^T W)^-1 Z^T e with e = tau_read - W(x_read) beta, the
residual at the true parameters. To first order in the reading errors
    e = eps_tau - D_q dq - D_q' dq' - D_q'' dq'',
D_x = d(W(x) beta) / dx the sensitivity of the model's joint torques to each measured signal,
evaluated on the instruments' (reference) motion with the model's own parameters (Pinocchio's
RNEA derivatives, plus the drives' viscous f_v and rotor inertia I_a; the Coulomb columns are taken
from the instruments and depend on no measured signal). Where the velocities and accelerations are
differentiated from the encoders, dq' = S_1 dq and dq'' = S_2 dq with S_k the Savitzky-Golay
filter's matrices. Then Cov(Z^T e) = sum_j G_j K_j G_j^T + Z^T Sigma_tau Z (+ white q', q'' noise),
G_j = Z^T (D_q[:, j] + D_q'[:, j] S_1 + D_q''[:, j] S_2) the map from joint j's position errors.

Encoder counts: an encoder's zero falls anywhere within a count, so its error at a position y is
the sawtooth round(y) - y with a uniformly random phase, whose covariance between two readings
depends on how far apart they are in counts, d: K = res^2 (1/12 - phi (1 - phi) / 2),
phi = frac(d). Two readings within a count of each other (a joint at rest, or slow) share nearly
all their error; this is what a residual-based (HAC) estimate of the covariance cannot see in a
few hundred samples, and why its intervals covered 75 % to 97 % by parameter where these cover
93 % to 97 % (README, "Estimators side by side").

Time O(r N^2) and memory O(N^2) for N samples (the encoder's covariance is dense): meant for the
bench's trials, not for a log of a million samples.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from harness.engines.pinocchio import PinocchioModel
from harness.model import friction
from harness.sources.measurement import GROUPS, Measurement, savgol


def propagates(m: Measurement) -> bool:
    """Whether the measurement's errors are all of kinds propagated here (significant-digit rounding
    is not: its error follows the value's decimal exponent)."""
    return m.significant_digits is None


def encoder_covariance(q: np.ndarray, resolution: float) -> np.ndarray:
    """(N, N) covariance of one encoder's quantisation errors at positions q (N,), its zero uniform
    within a count: resolution^2 (1/12 - phi (1 - phi) / 2), phi = frac((q_t - q_s) / resolution)."""
    d = (q[:, None] - q[None, :]) / resolution
    phi = d - np.floor(d)
    return resolution**2 * (1.0 / 12.0 - 0.5 * phi * (1.0 - phi))


def torque_sensitivities(pm: PinocchioModel, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray
                         ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """d tau / dq, d tau / dq', d tau / dq'' (each (N, n, n), spec joint order) of the model's joint
    torques with its drives' viscous friction and rotor inertia (the Coulomb shape excluded: see the
    module's docstring)."""
    model, data, idx = pm.model, pm.model.createData(), pm.q_index
    N, n = q.shape
    Dq, Dv, Da = (np.empty((N, n, n)) for _ in range(3))
    qq, vv, aa = np.zeros(model.nq), np.zeros(model.nv), np.zeros(model.nv)
    sel = np.ix_(idx, idx)
    for k in range(N):  # Pinocchio's derivatives are per state
        qq[idx], vv[idx], aa[idx] = q[k], qd[k], qdd[k]
        dq, dv, da = pin.computeRNEADerivatives(model, data, qq, vv, aa)
        Dq[k], Dv[k] = dq[sel], dv[sel]
        Da[k] = np.triu(da)[sel] + np.triu(da, 1)[sel].T  # the mass matrix: its upper triangle is filled
    if pm.frictions:
        k = friction.values(pm.frictions)  # (n, 4): armature, viscous, coulomb, offset
        Dv += np.diag(k[:, 1])
        Da += np.diag(k[:, 0])
    return Dq, Dv, Da


def score_covariance(pm: PinocchioModel, Z1: np.ndarray, t: np.ndarray, keep: slice, q: np.ndarray,
                     qd: np.ndarray, qdd: np.ndarray, tau: np.ndarray, m: Measurement) -> np.ndarray:
    """(r, r) Cov(Z1^T e) under the measurement `m` (module docstring). Z1: (N n, r) instruments,
    rows sample by sample, on the samples `keep` of the sampled times t (N_all,); q, qd, qdd, tau:
    (N_all, n) the reference motion and its torques, whose errors are read."""
    Nk, n = len(t[keep]), q.shape[1]
    Zr = Z1.reshape(Nk, n, -1)
    Dq, Dv, Da = torque_sensitivities(pm, q[keep], qd[keep], qdd[keep])
    omega = np.zeros((Z1.shape[1], Z1.shape[1]))
    joints_noise = m.noise.get("joints")

    def spread(x: np.ndarray, group) -> np.ndarray:
        return group.absolute**2 + (group.relative * x) ** 2

    if m.differentiate:
        S1, S2 = (savgol(np.eye(len(t)), t, m.filter_window, k)[keep] for k in (1, 2))
    for j in range(n):
        # Z^T D[:, :, j] sample by sample: how joint j's error at each sample moves the scores
        a, b, c = (np.einsum("tir,ti->tr", Zr, D[:, :, j]) for D in (Dq, Dv, Da))
        var_q = spread(q[:, j], joints_noise) if joints_noise else np.zeros(len(t))
        if m.differentiate:
            G = S1.T @ b + S2.T @ c  # (N_all, r): from every position read, through the filter
            G[keep] += a
            K = encoder_covariance(q[:, j], m.encoder_resolution) if m.encoder_resolution else 0.0
            omega += G.T @ (K + np.diag(var_q)) @ G if np.ndim(K) else (G * var_q[:, None]).T @ G
        else:
            K = encoder_covariance(q[keep, j], m.encoder_resolution) if m.encoder_resolution else 0.0
            if np.ndim(K):
                omega += a.T @ K @ a
            omega += (a * var_q[keep, None]).T @ a
            if joints_noise:  # velocities and accelerations read with their own white noise
                omega += (b * spread(qd[keep, j], joints_noise)[:, None]).T @ b
                omega += (c * spread(qdd[keep, j], joints_noise)[:, None]).T @ c
    var_tau = np.zeros_like(tau[keep])
    for group, noise in m.noise.items():  # a later group's noise replaces an earlier one's (measurement.py)
        if "tau" in GROUPS[group]:
            var_tau = spread(tau[keep], noise)
    return omega + (Z1 * var_tau.reshape(-1)[:, None]).T @ Z1
