"""The planar manipulator paper's report sections: its design claims and the audit of its printed
inertia matrix."""

from __future__ import annotations

import numpy as np

from harness.report import plots
from harness.report.html import esc, figure, mark, num, section, table


def design_comparison(r: dict) -> str:
    dc = r["design_comparison"]
    t = np.array(dc["t"])
    prop, conv = np.array(dc["proposed"]), np.array(dc["conventional"])
    joints = r["torques"]["joints"]
    styles = {"proposed": "-", "conventional": "--"}
    panels = [(j, {"proposed": prop[:, k], "conventional": conv[:, k]}, None) for k, j in enumerate(joints)]
    motor = {
        f"proposed: shared motor {' + '.join(dc['shared'])}": np.array(dc["shared_motor"]),
        f"conventional: {dc['baseline_joint']}": conv[:, joints.index(dc["baseline_joint"])],
    }

    def show(v):
        if isinstance(v, list):
            return ", ".join(map(str, v)) or "none"
        return num(v) if isinstance(v, float) else str(v)

    claims = [
        [
            esc(c["claim"]),
            mark(c["holds"], "holds" if c["holds"] else "does not hold"),
            esc("; ".join(f"{k.replace('_', ' ')}: {show(v)}" for k, v in c["numbers"].items())),
        ]
        for c in dc["claims"]
    ]
    per_joint = [
        [
            esc(p["joint"]),
            num(p["proposed_peak"]),
            num(p["conventional_peak"]),
            num(p["peak_ratio"]),
            num(p["proposed_rms"]),
            num(p["conventional_rms"]),
            num(p["rms_ratio"]),
            esc(p["proposed_is"]),
        ]
        for p in dc["per_joint"]
    ]
    return section(
        "design_comparison",
        "The paper's claims: proposed against conventional design",
        (
            f"<p>Both designs follow the same joint path; the conventional one is scenario "
            f"<code>{esc(dc['baseline'])}</code>. Torques are MuJoCo's (Pinocchio and the graph model agree with them, "
            "see Joint torques).</p>"
            + table(["claim", "verdict", "numbers"], claims, "wrap")
            + figure(
                plots.grid(t, panels, "tau [N m]", styles=styles),
                "Joint torques of both designs (as the paper's Figures 10-15 and 20-25).",
            )
            + figure(
                plots.lines(t, motor, "tau [N m]", "Shared motor against the conventional third joint"),
                "The proposed design's shared motor carries tau_3 + ... + tau_6 (as the paper's Figures 16 and 26).",
            )
            + table(
                [
                    "joint",
                    "peak, proposed",
                    "peak, conventional",
                    "ratio",
                    "RMS, proposed",
                    "RMS, conventional",
                    "ratio",
                    "proposed is",
                ],
                per_joint,
            )
        ),
    )


def inertia_audit(r: dict) -> str:
    a = r["inertia_matrix_audit"]
    rows = [
        [
            esc(e["entry"]),
            mark(e["verdict"] != "disagrees", e["verdict"]),
            num(e["max_rel_difference"]),
            num(e["max_rel_difference_negated"]),
            num(e["max_rel_difference_at_theta1_zero"]),
            num(e["max_rel_difference_product_reading"]),
            num(e["printed_depends_on_theta1"]),
            num(e["correct_depends_on_theta1"]),
            num(e["correct_depends_on_theta2"]),
        ]
        for e in a["entries"]
    ]
    wrong = a["printed_depend_on_theta1_wrongly"]
    fixes = "".join(
        f"<li>{esc(c['entry'])}: {esc(c['correction'])}: agrees to {num(c['max_rel_difference'])}</li>"
        for c in a["corrections"]
    )
    return section(
        "inertia_matrix_audit",
        "Audit of the paper's printed inertia matrix (Appendix, Eq. A27 ff.)",
        (
            f"<p>Each printed entry, transcribed from the extracted text ({esc(a['reading'])}), against Pinocchio's "
            f"CRBA of the same model at {a['configurations']} random configurations. Differences are relative to the "
            "entry's largest value. Entries that agree, or agree once a lost leading minus is restored: "
            f"{esc(', '.join(a['agreeing']) or 'none')}. "
            f"Entries that disagree: {esc(', '.join(a['disagreeing']) or 'none')}."
            "</p>"
            + (
                f"<p>The printed {esc(', '.join(wrong))} depend on theta1, and the correct entries cannot: turning "
                "the whole arm about the base axis leaves the inertia seen by joints 2..6 unchanged (nor can they "
                "depend on "
                "theta2, the joints 2..6 being parallel). Where the printed theta1 terms vanish (theta1 = 0) those "
                "entries agree to round-off: the printed theta1 terms are the error.</p>"
                if wrong
                else ""
            )
            + (f"<p>Corrections that make a disagreeing entry agree:</p><ul>{fixes}</ul>" if fixes else "")
            + table(
                [
                    "entry",
                    "verdict",
                    "max rel difference",
                    "negated",
                    "at theta1 = 0",
                    "other reading",
                    "printed depends on theta1",
                    "correct depends on theta1",
                    "correct depends on theta2",
                ],
                rows,
            )
        ),
    )


