"""The friction columns of a filtered log, filtered as its torques were.

A conditioned log's torques went through a zero-phase low-pass (harness/sources/log/condition.py):
the Coulomb term it measures is F[f_c tanh(q'/v_c)], the filter of the turn, where the regressor
evaluates f_c tanh(F[q']/v_c), the turn of the filtered velocity. The motion's band lies far below
the cut-off, so F[q'] = q' there and the linear columns (q'', q', 1) and the links' columns agree with
the filtered torques; the turn does not: it happens within |q'| < v_c, in a few milliseconds, and the
filter spreads it over its impulse response. A fit that compares the two picks a wider turn, a v_c
larger than the robot's (0.017 to 0.044 rad/s for a true 0.01 on a Kinova bench filtered at 5.5 Hz).
Here each nonlinear column of the velocities (the Coulomb shape s, and the families' |q'|, |s|,
s exp(-(q'/v_s)^2)) is computed at the log's full rate and filtered by the same filter before the
rows are kept: the same operation on both sides of tau = W theta (Gautier's parallel filtering). A
load-dependent column |tau_R| s takes the filtered s times tau_R at the kept rows (tau_R is the
links' torque, within the motion's band).

`columns` is the span's harness.sources.log.condition.FilteredColumns (duck-typed: `covers(t)`,
`filtered(fn, t)`); None (an unfiltered log, or a span it does not cover) leaves every column as it is.
"""

from __future__ import annotations

import numpy as np

from harness.model import friction
from harness.model.drives import Transmission


def _rates(transmission: Transmission | None):
    return (lambda qd: qd) if transmission is None else transmission.motor_rates


def coulomb(columns, t: np.ndarray, laws, transmission: Transmission | None) -> np.ndarray:
    """(N, m): each drive's Coulomb shape s(q'_m) with its law's v_c, filtered (m drives: the joints, or
    the transmission's motors)."""
    v = np.array([law.coulomb_velocity for law in laws])
    rates = _rates(transmission)
    return columns.filtered(lambda qd: friction.coulomb_shape(rates(qd), v), t)


def drive_term(columns, t: np.ndarray, law, k: int, transmission: Transmission | None, term: str) -> np.ndarray:
    """(N,): one column of drive k's law, filtered: its Coulomb shape s (`term` "coulomb") or one of its
    family's shapes (EXTRA_KEYS; the load column s itself, to be multiplied by |tau_R|). The friction
    law's search (harness/identify/friction_law.py) asks for the columns a law needs, one at a time."""
    rates = _rates(transmission)
    v, v_s = np.array([law.coulomb_velocity]), np.array([law.stribeck_velocity])

    def column(qd: np.ndarray) -> np.ndarray:
        qd_k = rates(qd)[:, k: k + 1]
        s = friction.coulomb_shape(qd_k, v)
        if term == "coulomb" or term == "load_coulomb":
            return s
        return friction.extra_shape(term, qd_k, s, v_s, None)

    return columns.filtered(column, t)[:, 0]
