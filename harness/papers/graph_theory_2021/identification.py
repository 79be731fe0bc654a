"""Section 2.3: the dynamics in identification form, Eqs. 40-64.

Per body B_i and sample j (Eq. 49-52):

    id_Y_i id_X_i = id_Z_i,
    id_Y_i = blockdiag(id_R_i, id_S_i^(i)),   id_X_i = (m_e1, m_e2, m_e3, J11, J22, J33),
    id_Z_i = (F_i^R ; M_i^(i)),

    id_R_i = diag(r_i'' - g)                          (Eq. 44; (x'', y'', z'' + g) for g = -g e3)
    id_S_i = [[w1',      -w2 w3,   w2 w3 ],
              [ w1 w3,    w2',    -w1 w3 ],
              [-w1 w2,    w1 w2,   w3'   ]]           (Eq. 48, omega^(i) components)
    F_i^R = F_i^J (world),  M_i^(i) = M_i^J in body components  (Eqs. 43-47).

The mass is identified separately along e1(0), e2(0), e3(0), as in the paper's Table 3. Stacking
the samples gives id_K_i id_X_i = id_L_i (Eqs. 53-55) per body, and the block-diagonal
id_K id_X = id_L (Eqs. 57-63) for the whole system.
"""

from __future__ import annotations

import numpy as np

from harness.papers.graph_theory_2021.dynamics import BodySeries

PARAMETERS = ("m_e1", "m_e2", "m_e3", "J11", "J22", "J33")


def id_R(a_W: np.ndarray, g_W: np.ndarray) -> np.ndarray:
    """Eq. 44: diag(r'' - g), (N, n, 3) -> (N, n, 3, 3)."""
    return (a_W - g_W)[..., :, None] * np.eye(3)


def id_S(omega_B: np.ndarray, omegadot_B: np.ndarray) -> np.ndarray:
    """Eq. 48: J omega' + omega x J omega = id_S (J11, J22, J33)."""
    w1, w2, w3 = np.moveaxis(omega_B, -1, 0)
    d1, d2, d3 = np.moveaxis(omegadot_B, -1, 0)
    return np.stack([
        np.stack([d1, -w2 * w3, w2 * w3], -1),
        np.stack([w1 * w3, d2, -w1 * w3], -1),
        np.stack([-w1 * w2, w1 * w2, d3], -1),
    ], -2)


def id_Y(s: BodySeries, g_W: np.ndarray) -> np.ndarray:
    """Eq. 51: (N, n, 6, 6)."""
    Y = np.zeros(s.a_W.shape[:2] + (6, 6))
    Y[..., :3, :3] = id_R(s.a_W, g_W)
    Y[..., 3:, 3:] = id_S(s.omega_B, s.omegadot_B)
    return Y


def id_Z(s: BodySeries) -> np.ndarray:
    """Eq. 51: (F_i^R ; M_i^(i)), (N, n, 6)."""
    return np.concatenate([s.F_J_W, s.M_J_B], axis=-1)


def stack_per_body(Y: np.ndarray, Z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Eqs. 53-55: id_K_i (n, 6N, p) and id_L_i (n, 6N), samples stacked in time order (p = 6 for
    the paper's form, 10 for the full one)."""
    N, n = Y.shape[:2]
    K = np.swapaxes(Y, 0, 1).reshape(n, N * Y.shape[2], Y.shape[3])
    L = np.swapaxes(Z, 0, 1).reshape(n, N * Z.shape[2])
    return K, L


def stack_system(Y: np.ndarray, Z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Eqs. 57-63: id_K (6nN, 6n) with id_Y = blockdiag(id_Y_1..id_Y_n) per sample, id_L (6nN,)."""
    N, n, rows, p = Y.shape
    K = np.zeros((N, n, rows, n, p))
    k = np.arange(n)
    K[:, k, :, k, :] = np.moveaxis(Y, 1, 0)  # body i's block on the diagonal, all samples at once
    return K.reshape(N * n * rows, n * p), Z.reshape(-1)
