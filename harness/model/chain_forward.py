"""A closed chain's forward dynamics from its actuated joints' inverse dynamics, integrated in the
actuated coordinates.

A closed chain's model answers tau_a(q, q', q''), the actuated joints' torques at every joint's
consistent state (harness/model/closure.py: q' = G q'_a, q'' = G q''_a + g). Its equations of
motion in the actuated coordinates,

    M_a(q) q''_a + h_a(q, q'_a) = tau_a,      M_a = G^T M G,  h_a = G^T (M g + h),

are read off the model itself, one call of n_a + 1 rows at each evaluation: h_a is its answer at
q''_a = 0 and column i of M_a its answer at q''_a = e_i (1 rad/s^2 or 1 m/s^2) less h_a (the answer
is linear in q'': a friction law that reads the load is not, and the torques stage does not compare
such a robot). Then q''_a = M_a^-1 (tau_a - h_a). The state (q_a, q'_a) is advanced by the
classical RK4 tableau (harness/base/numerics.py, RK4_A, RK4_B) with the actuated torques given at
each of a step's four stages; at every stage the passive joints close the loops (Newton's method
from the step start's configuration moved along G: closure.predicted). The motion stays on the
loops' manifold by construction, which a rigid-loop integrator in every joint's coordinates
(Pinocchio's constraintDynamics) leaves only by its step's error: what the two answer for the same
torques differs by the model's error and the two schemes' truncation errors.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from harness.base.numerics import RK4_A, RK4_B
from harness.model.closure import ClosedChain, actuated_torques, close_with_jacobian, motion, pinv_passive, predicted

ActuatedInverseDynamics = Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]  # (N, n) x3 -> (N, n_a)


@dataclass(frozen=True)
class TreeInverseDynamics:
    """A model given as its tree's joint torques, `torques`: every joint's (q, q', q'') (N, n) x3 -> tau
    (N, n). Projected onto the actuated joints by the G its states' motion already holds (tau_a = G^T tau,
    closure.actuated_torques), not by a G recomputed from q for each of the n_a + 1 rows of a state."""

    torques: Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]


class ChainForwardError(ValueError):
    """The model's actuated mass matrix is singular, or its motion leaves the loops' reach."""


def actuated_acceleration(chain: ClosedChain, inverse: ActuatedInverseDynamics | TreeInverseDynamics, q: np.ndarray,
                          qd_a: np.ndarray, tau_a: np.ndarray, J: np.ndarray | None = None,
                          P: np.ndarray | None = None) -> np.ndarray:
    """q''_a (B, n_a) at closed configurations q (B, n) with actuated velocities qd_a (B, n_a) under the
    actuated torques tau_a (B, n_a), from `inverse` (every joint's (q, q', q'') rows -> the actuated
    joints' torques, or a TreeInverseDynamics): M_a q''_a = tau_a - h_a (module docstring), the model
    called once for all B states and their n_a + 1 accelerations, state b's n_a + 1 rows together and
    the states in order (an inverse for a batch of several models reads whose rows are whose from that).
    J at q and P = J_p^+ where the caller holds them (closure.motion)."""
    B, n_a = len(q), len(chain.actuated)
    base = motion(chain, q, qd_a, np.zeros((B, n_a)), J, P)
    rows = n_a + 1
    qdd = np.repeat(base.qdd[:, None], rows, axis=1)
    qdd[:, 1:] += np.swapaxes(base.G, 1, 2)  # row 1 + i: q''_a = e_i, q'' = G e_i + g
    states = np.repeat(base.q, rows, axis=0), np.repeat(base.qd, rows, axis=0), qdd.reshape(B * rows, -1)
    if isinstance(inverse, TreeInverseDynamics):
        answer = actuated_torques(np.repeat(base.G, rows, axis=0), inverse.torques(*states))
    else:
        answer = inverse(*states)
    answer = answer.reshape(B, rows, n_a)
    h_a = answer[:, 0]
    M_a = np.swapaxes(answer[:, 1:] - h_a[:, None], 1, 2)
    try:
        return np.linalg.solve(M_a, (tau_a - h_a)[:, :, None])[:, :, 0]
    except np.linalg.LinAlgError:
        raise ChainForwardError(f"{chain.spec.name}: the model's actuated mass matrix is singular") from None


def rollout(chain: ClosedChain, inverse: ActuatedInverseDynamics | TreeInverseDynamics, q0: np.ndarray,
            qd_a0: np.ndarray, stage_tau_a: np.ndarray, timestep: float) -> np.ndarray:
    """B forward simulations of the closed chain by the model `inverse` (actuated_acceleration),
    advanced together: rollout b from the closed configuration Newton's method reaches from q0[b]
    (B, n), its actuated joints held, with actuated velocities qd_a0[b] (B, n_a), by RK4 at `timestep`
    under the actuated torques given at each of a step's four stages, stage_tau_a[b] (B, steps, 4,
    n_a). Returns every joint's q at the start and after each step, (B, steps + 1, n), the spec's
    joint order."""
    return rollout_states(chain, inverse, q0, qd_a0, stage_tau_a, timestep)[0]


def rollout_states(chain: ClosedChain, inverse: ActuatedInverseDynamics | TreeInverseDynamics, q0: np.ndarray,
                   qd_a0: np.ndarray, stage_tau_a: np.ndarray, timestep: float) -> tuple[np.ndarray, np.ndarray]:
    """`rollout`, and the actuated velocities at the start and after each step, (B, steps + 1, n_a)."""
    act = list(chain.actuated)
    q, J = close_with_jacobian(chain, np.asarray(q0, dtype=float), "the start of rollout")
    qd_a = np.array(qd_a0, dtype=float)
    h = timestep
    out, out_qd = [q], [qd_a]
    for k in range(stage_tau_a.shape[1]):
        P = pinv_passive(chain, J, f"step {k} of rollout")
        # the first stage at the step's start; every stage's J Newton's at its closed configuration
        rates = [(qd_a, actuated_acceleration(chain, inverse, q, qd_a, stage_tau_a[:, k, 0], J, P))]
        for i in range(1, 4):
            v, a = rates[-1]
            step = RK4_A[i - 1] * h
            q_i, J_i = close_with_jacobian(chain, predicted(chain, q, J, P, q[:, act] + step * v),
                                           f"stage {i + 1} of step {k}, rollout")
            qd_i = qd_a + step * a
            rates.append((qd_i, actuated_acceleration(chain, inverse, q_i, qd_i, stage_tau_a[:, k, i], J_i)))
        q_a = q[:, act] + h * sum(w * r[0] for w, r in zip(RK4_B, rates, strict=True))
        qd_a = qd_a + h * sum(w * r[1] for w, r in zip(RK4_B, rates, strict=True))
        q, J = close_with_jacobian(chain, predicted(chain, q, J, P, q_a), f"step {k + 1} of rollout")
        out.append(q)
        out_qd.append(qd_a)
    return np.stack(out, axis=1), np.stack(out_qd, axis=1)
