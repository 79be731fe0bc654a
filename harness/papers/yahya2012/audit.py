"""The second seed's printed closed-form inertia matrix (Yahya et al. 2012, Appendix, Eq. A27 ff.),
transcribed to be audited against Pinocchio's CRBA.

Reading of the extracted text. The extraction keeps "+" but drops every minus sign, and it prints
powers as plain digits ("cos 2 (x)" is cos^2 x). The entries below use this reading:
- where two terms stand side by side with no operator, a minus sign was lost: "(cos(4 th1) 1)" is
  cos(4 th1) - 1, "32 (cos(4 th1) 1) cos(2 S)" is 32 - (cos(4 th1) - 1) cos(2 S). (Read as a product,
  32 (cos(4 th1) - 1) cos(2 S), M66 would vanish at th1 = 0, which a rod turning about its end
  cannot do; that reading is reported with the others, see `READINGS`.)
- a leading minus sign of a whole entry cannot be seen; the audit therefore also tries the
  negated entry and says so when only that agrees.
- M11 prints "12 m s" where m5 belongs; read as m5. M34 prints its m5 term as
  cos(th2 + th3 + th4 + th5) where all its neighbours have cos(2 (...)), with an unbalanced
  parenthesis; transcribed as printed. M16 prints no "= M61"; the matrix is taken as symmetric.

Symbols: th = (th1..th6); l = (l1..l5), the rod lengths; d1, the offset of the second row; m =
(m1..m6), the link masses; S2 = th2, S23 = th2 + th3, ..., S23456 = th2 + ... + th6.
"""

from __future__ import annotations

import numpy as np
from numpy import cos, sin

READINGS = {
    "lost minus": "juxtaposed terms are separated by a lost minus sign (used)",
    "product": "'32 (cos(4 th1) 1) cos(2 S)' read as the product 32 (cos(4 th1) - 1) cos(2 S)",
}


def printed_inertia_matrix(th: np.ndarray, l: np.ndarray, d1: float, m: np.ndarray,
                           reading: str = "lost minus") -> np.ndarray:
    """M(th) as printed, (N, 6) -> (N, 6, 6), symmetric; `reading` one of READINGS."""
    th = np.atleast_2d(th)
    t1, t2, t3, t4, t5, t6 = th.T
    l1, l2, l3, l4, l5 = l
    _, m2, m3, m4, m5, m6 = m  # m1 sits on the first axis: it enters no entry
    S23, S234 = t2 + t3, t2 + t3 + t4
    S2345, S23456 = S234 + t5, S234 + t5 + t6
    c2, c23, c234, c2345, c23456 = cos(t2), cos(S23), cos(S234), cos(S2345), cos(S23456)
    def q(S, twice=True):
        """The printed bracket '32 (cos(4 th1) 1) cos(2 S)' in the chosen reading."""
        c = cos(2 * S) if twice else cos(S)
        return 32.0 - (cos(4 * t1) - 1.0) * c if reading == "lost minus" else 32.0 * (cos(4 * t1) - 1.0) * c

    M = np.zeros((len(th), 6, 6))

    M[:, 0, 0] = (1 / 12) * (
        4 * m2 * (3 * d1**2 + l1**2 * c2**2)
        + 4 * m3 * (3 * d1**2 + 3 * l1**2 * c2**2 + l2**2 * c23**2 + 3 * l1 * l2 * c2 * c23)
        + 12 * m4 * (d1**2 + 0.25 * (2 * l1 * c2 + 2 * l2 * c23 + l3 * c234) ** 2)
        + 12 * m5 * (d1**2 + 0.25 * (2 * l1 * c2 + 2 * l2 * c23 + 2 * l3 * c234 + l4 * c2345) ** 2)
        + 12 * m6 * (d1**2 + 0.25 * (2 * (l1 * c2 + l2 * c23 + l3 * c234 + l4 * c2345) + l5 * c23456) ** 2)
        + l3**2 * m4 * c234**2 + l4**2 * m5 * c2345**2 + l5**2 * m6 * c23456**2)
    M[:, 0, 1] = 0.5 * d1 * (
        l3 * m4 * sin(S234) + 2 * l3 * m5 * sin(S234) + l4 * m5 * sin(S2345)
        + m6 * (2 * l3 * sin(S234) + 2 * l4 * sin(S2345) + l5 * sin(S23456))
        + l2 * (m2 + 2 * (m4 + m5 + m6)) * sin(S23) + l1 * (m3 + 2 * (m3 + m4 + m5 + m6)) * sin(t2))
    M[:, 0, 2] = 0.5 * d1 * (
        l4 * m5 * sin(S2345) + m6 * (2 * l4 * sin(S2345) + l5 * sin(S23456))
        + l3 * (m4 + 2 * (m5 + m6)) * sin(S234) + l2 * (m3 + 2 * (m4 + m5 + m6)) * sin(S23))
    M[:, 0, 3] = 0.5 * d1 * (l5 * m6 * sin(S23456) + l4 * (m5 + 2 * m6) * sin(S2345)
                             + l3 * (m4 + 2 * (m5 + m6)) * sin(S234))
    M[:, 0, 4] = 0.5 * d1 * (l5 * m6 * sin(S23456) + l4 * (m5 + 2 * m6) * sin(S2345))
    M[:, 0, 5] = 0.5 * d1 * l5 * m6 * sin(S23456)

    # shared pieces of M22, M23, M24
    rods34 = (2 * l3**2 * m4 * cos(2 * S234) - l3**2 * m4 * cos(2 * (2 * t1 + S234))
              - l3**2 * m4 * cos(4 * t1 - 2 * S234)
              + 2 * l4**2 * m5 * cos(2 * S2345) - l4**2 * m5 * cos(2 * (2 * t1 + S2345))
              - l4**2 * m5 * cos(4 * t1 - 2 * S2345))
    tip = 2 * m6 * (l5**2 * q(S23456) + 96 * l5 * (l3 * cos(t5 + t6) + l4 * cos(t6))
                    + 96 * (2 * l4 * l3 * cos(t5) + l3**2 + l4**2))
    from_l1 = (l4 * m5 * cos(t3 + t4 + t5) + m6 * (2 * l4 * cos(t3 + t4 + t5) + l5 * cos(t3 + t4 + t5 + t6))
               + l3 * (m4 + 2 * (m5 + m6)) * cos(t3 + t4) + l2 * (m3 + 2 * (m4 + m5 + m6)) * cos(t3))
    from_l2 = (l5 * m6 * cos(t4 + t5 + t6) + l4 * (m5 + 2 * m6) * cos(t4 + t5)
               + l3 * (m4 + 2 * (m5 + m6)) * cos(t4))
    const = 64 * l3**2 * m4 + 192 * l3**2 * m5 + 64 * l4**2 * m5
    l2sq = 4 * l2**2 * (m3 * (sin(2 * t1) ** 2 * cos(2 * S23) + 16) + 48 * (m4 + m5 + m6))
    M[:, 1, 1] = (1 / 192) * (
        192 * l1 * from_l1 + rods34 + 192 * l3 * l4 * m5 * cos(t5) + tip + 192 * l2 * from_l2
        + 4 * l1**2 * (m2 * (sin(2 * t1) ** 2 * cos(2 * t2) + 16) + 48 * (m3 + m4 + m5 + m6)) + l2sq + const)
    M[:, 1, 2] = (1 / 192) * (
        192 * l2 * from_l2 + rods34 + 192 * l3 * l4 * m5 * cos(t5) + tip + 96 * l1 * from_l1 + l2sq + const)
    from_l1_4 = (l5 * m6 * cos(t3 + t4 + t5 + t6) + l4 * (m5 + 2 * m6) * cos(t3 + t4 + t5)
                 + l3 * (m4 + 2 * (m5 + m6)) * cos(t3 + t4))
    M[:, 1, 3] = (1 / 192) * (rods34 + 192 * l4 * l3 * m5 * cos(t5) + tip + 96 * l2 * from_l2
                              + 96 * l1 * from_l1_4 + const)
    M[:, 1, 4] = (1 / 96) * (
        l4 * m5 * (48 * (l1 * cos(t3 + t4 + t5) + l2 * cos(t4 + t5) + l3 * cos(t5)) + l4 * q(S2345))
        + m6 * (l5**2 * q(S23456) + 48 * l5 * (l1 * cos(t3 + t4 + t5 + t6) + l2 * cos(t4 + t5 + t6)
                                              + l3 * cos(t5 + t6) + 2 * l4 * cos(t6))
                + 96 * l4 * (l1 * cos(t3 + t4 + t5) + l2 * cos(t4 + t5) + l3 * cos(t5) + l4)))
    M[:, 1, 5] = (1 / 96) * l5 * m6 * (
        48 * (l1 * cos(t3 + t4 + t5 + t6) + l2 * cos(t4 + t5 + t6) + l3 * cos(t5 + t6) + l4 * cos(t6))
        + l5 * q(S23456))
    tip3 = m6 * (96 * l5 * l4 * cos(t6) + l5**2 * q(S23456) + 96 * l4**2)
    M[:, 2, 2] = (1 / 96) * (
        96 * l2 * from_l2 + l4**2 * m5 * q(S2345) + tip3
        + l3**2 * (m4 * q(S234) + 96 * (m5 + m6))
        + 96 * l3 * (l5 * m6 * cos(t5 + t6) + l4 * (m5 + 2 * m6) * cos(t5))
        + l2**2 * (2 * m3 * (sin(2 * t1) ** 2 * cos(2 * S23) + 16) + 96 * (m4 + m5 + m6)))
    M[:, 2, 3] = (1 / 96) * (
        l3**2 * (m4 * q(S234) + 96 * (m5 + m6))
        + 96 * l3 * (l5 * m6 * cos(t5 + t6) + l4 * (m5 + 2 * m6) * cos(t5))
        + l4**2 * m5 * q(S2345, twice=False)  # printed without the 2 (see above)
        + tip3 + 48 * l2 * from_l2)
    M[:, 2, 4] = (1 / 96) * (
        l4 * m5 * (48 * l2 * cos(t4 + t5) + 48 * l3 * cos(t5) + l4 * q(S2345))
        + m6 * (l5**2 * q(S23456) + 48 * l5 * (l2 * cos(t4 + t5 + t6) + l3 * cos(t5 + t6) + 2 * l4 * cos(t6))
                + 96 * l4 * (l2 * cos(t4 + t5) + l3 * cos(t5) + l4)))
    M[:, 2, 5] = (1 / 96) * l5 * m6 * (48 * (l2 * cos(t4 + t5 + t6) + l3 * cos(t5 + t6) + l4 * cos(t6))
                                       + l5 * q(S23456))
    M[:, 3, 3] = (1 / 96) * (
        l3**2 * (m4 * q(S234) + 96 * (m5 + m6))
        + 96 * l3 * (l5 * m6 * cos(t5 + t6) + l4 * (m5 + 2 * m6) * cos(t5))
        + l4**2 * m5 * q(S2345) + tip3)
    M[:, 3, 4] = (1 / 96) * (
        l4 * m5 * (48 * l3 * cos(t5) + l4 * q(S2345))
        + m6 * (l5**2 * q(S23456) + 48 * l5 * (l3 * cos(t5 + t6) + 2 * l4 * cos(t6)) + 96 * l4 * (l3 * cos(t5) + l4)))
    M[:, 3, 5] = (1 / 96) * l5 * m6 * (48 * l3 * cos(t5 + t6) + 48 * l4 * cos(t6) + l5 * q(S23456))
    M[:, 4, 4] = (1 / 96) * (l4**2 * m5 * q(S2345) + tip3)
    M[:, 4, 5] = (1 / 96) * l5 * m6 * (48 * l4 * cos(t6) + l5 * q(S23456))
    M[:, 5, 5] = (1 / 96) * l5**2 * m6 * q(S23456)
    upper = np.triu_indices(6, 1)
    M[:, upper[1], upper[0]] = M[:, upper[0], upper[1]]
    return M


def corrected_M12(th: np.ndarray, l: np.ndarray, d1: float, m: np.ndarray) -> np.ndarray:
    """M12 with the leading minus restored and m2, m3 exchanged in its l1 and l2 terms."""
    t2 = th[:, 1]
    S23 = t2 + th[:, 2]
    S234, S2345 = S23 + th[:, 3], S23 + th[:, 3] + th[:, 4]
    S23456 = S2345 + th[:, 5]
    l1, l2, l3, l4, l5 = l
    _, m2, m3, m4, m5, m6 = m
    return -0.5 * d1 * (
        l3 * m4 * sin(S234) + 2 * l3 * m5 * sin(S234) + l4 * m5 * sin(S2345)
        + m6 * (2 * l3 * sin(S234) + 2 * l4 * sin(S2345) + l5 * sin(S23456))
        + l2 * (m3 + 2 * (m4 + m5 + m6)) * sin(S23) + l1 * (m2 + 2 * (m3 + m4 + m5 + m6)) * sin(t2))


def dh_symbols(spec) -> tuple[np.ndarray, float, np.ndarray]:
    """(l1..l5, d1, m1..m6) of a six-link DH model in the paper's layout."""
    if spec.dh is None or len(spec.dh) != 6:
        raise ValueError(f"model {spec.name!r} is not a six-link DH model")
    l = np.array([row[1] for row in spec.dh[1:]])
    return l, float(spec.dh[1][2]), np.array([b.mass for b in spec.bodies])


def audit_inertia_matrix(spec, n_configurations: int = 200, seed: int = 0) -> dict:
    """Every printed entry against Pinocchio's CRBA of the same model at random configurations.

    Verdict per entry: "agrees" (largest difference <= 1e-9 of the entry's largest value),
    "agrees up to sign" (only the negated entry does: a lost leading minus), or "disagrees". The
    facts a correct entry must satisfy are read off the CRBA: whether the entry changes with th1,
    and with th2. Also: the difference at th1 = 0, where the printed th1 terms vanish."""
    from harness.engines.pinocchio import build_model, crba

    l, d1, m = dh_symbols(spec)
    pm = build_model(spec, np.array([0.0, 0.0, -9.80665]))
    rng = np.random.default_rng(seed)
    th = rng.uniform(-np.pi, np.pi, size=(n_configurations, 6))
    exact = crba(pm, th)
    printed = {r: printed_inertia_matrix(th, l, d1, m, r) for r in READINGS}
    shifted = th.copy()
    shifted[:, 0] += 0.7
    shifted2 = th.copy()
    shifted2[:, 1] += 0.7
    exact_1, exact_2 = crba(pm, shifted), crba(pm, shifted2)
    printed_1 = printed_inertia_matrix(shifted, l, d1, m)
    at_zero = th.copy()
    at_zero[:, 0] = 0.0  # where the printed theta1 terms vanish: cos(4 th1) = 1, sin(2 th1) = 0
    printed_0, exact_0 = printed_inertia_matrix(at_zero, l, d1, m), crba(pm, at_zero)
    scale_all = float(np.max(np.abs(exact)))
    rows = []
    for i in range(6):
        for j in range(i, 6):
            scale = max(float(np.max(np.abs(exact[:, i, j]))), 1e-12 * scale_all)
            err = {r: float(np.max(np.abs(p[:, i, j] - exact[:, i, j]))) / scale for r, p in printed.items()}
            neg = float(np.max(np.abs(-printed["lost minus"][:, i, j] - exact[:, i, j]))) / scale
            verdict = ("agrees" if err["lost minus"] <= 1e-9 else
                       "agrees up to sign" if neg <= 1e-9 else "disagrees")
            rows.append({
                "entry": f"M{i + 1}{j + 1}", "verdict": verdict,
                "max_rel_difference": err["lost minus"],
                "max_rel_difference_negated": neg,
                "max_rel_difference_product_reading": err["product"],
                "max_rel_difference_at_theta1_zero": min(
                    float(np.max(np.abs(printed_0[:, i, j] - exact_0[:, i, j]))),
                    float(np.max(np.abs(-printed_0[:, i, j] - exact_0[:, i, j])))) / scale,
                "printed_depends_on_theta1": bool(np.max(np.abs(printed_1[:, i, j] - printed["lost minus"][:, i, j]))
                                                  > 1e-9 * scale),
                "correct_depends_on_theta1": bool(np.max(np.abs(exact_1[:, i, j] - exact[:, i, j])) > 1e-9 * scale),
                "correct_depends_on_theta2": bool(np.max(np.abs(exact_2[:, i, j] - exact[:, i, j])) > 1e-9 * scale),
                "largest_value": float(np.max(np.abs(exact[:, i, j]))),
            })
    m12 = float(np.max(np.abs(corrected_M12(th, l, d1, m) - exact[:, 0, 1])) / np.max(np.abs(exact[:, 0, 1])))
    return {
        "configurations": n_configurations,
        "corrections": [{"entry": "M12", "correction": "leading minus restored, m2 and m3 exchanged in the l1 and "
                                                        "l2 terms", "max_rel_difference": m12}],
        "reading": READINGS["lost minus"],
        "other_reading": READINGS["product"],
        "entries": rows,
        "agreeing": [r["entry"] for r in rows if r["verdict"] != "disagrees"],
        "disagreeing": [r["entry"] for r in rows if r["verdict"] == "disagrees"],
        "printed_depend_on_theta1_wrongly": [r["entry"] for r in rows
                                             if r["printed_depends_on_theta1"] and not r["correct_depends_on_theta1"]],
    }
