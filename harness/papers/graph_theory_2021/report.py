"""The graph-theory paper's report sections: the bodies' Cardano angles, its identification (section
2.3, Tables 3 and 4), all 10 parameters per body, and constraints and multipliers (sections 2.4,
2.5, 3.2)."""

from __future__ import annotations

import numpy as np

from harness.base.series import TimeSeries
from harness.papers.graph_theory_2021.cardano import GIMBAL_COND_D, body_angles, gimbal_flags
from harness.report import plots
from harness.report.html import DASH, esc, figure, num, section, table
from harness.report.sections import identifiability


def cardano_angles(r: dict, rec: TimeSeries) -> str:
    """Each body's Cardano angles along the run, derived from its recorded orientation, with the
    rows near gimbal lock shaded."""
    theta = body_angles(rec.R_WB)
    flags = gimbal_flags(theta)
    panels = [(b, {"alpha": theta[:, i, 0], "beta": theta[:, i, 1], "gamma": theta[:, i, 2]}, flags[:, i])
              for i, b in enumerate(rec.bodies)]
    return section("graph", "Cardano angles", figure(
        plots.grid(rec.t, panels, "[rad]"),
        "Cardano angles A(0i) = Rx(alpha) Ry(beta) Rz(gamma) (Eq. 29), from each body's recorded orientation; "
        f"shaded: rows near gimbal lock (cond(D) > {GIMBAL_COND_D:g}, or cos(beta) changing sign between rows)."))


def _larger(p: dict) -> str:
    """Whose absolute error is larger, ours or the paper's (Table 4), where both exist."""
    if p["abs_error"] is None or p["paper_abs_error"] is None:
        return DASH
    ours, theirs = abs(p["abs_error"]), abs(p["paper_abs_error"])
    return "ours" if ours > theirs else "paper's" if theirs > ours else "equal"


def identification(r: dict) -> str:
    ident = r["identification"]
    rows = []
    for p in ident["parameters"]:
        rows.append(
            [
                esc(p["body"]),
                esc(p["name"]),
                f"{p['true']:.4f}",
                f"{p['identified']:.6f}" if p["identified"] is not None else DASH,
                num(p["abs_error"]),
                num(p["rel_error"]),
                num(p.get("std")),
                DASH if not p.get("ci95") else f"[{num(p['ci95'][0])}, {num(p['ci95'][1])}]",
                num(p["paper_identified"]),
                num(p["paper_abs_error"]),
                _larger(p),
                identifiability(p),
            ]
        )
    labels = [f"{p['body']}.{p['name']}" for p in ident["parameters"]]
    series = {"ours |abs error|": [p["abs_error"] for p in ident["parameters"]]}
    if any(p["paper_abs_error"] is not None for p in ident["parameters"]):
        series["paper (Table 4) |abs error|"] = [p["paper_abs_error"] for p in ident["parameters"]]
    fig = figure(
        plots.bars(labels, series, "|identified - true|", "Absolute errors of the identified parameters"),
        "Missing bars: not identifiable, or zero. Paper values from its Tables 3 and 4.",
    )
    digits = ident["significant_digits"]
    noise = r["scenario"]["measurement"].get("noise") or {}
    noisy = ", ".join(f"{g} {n['relative']:g} relative, {n['absolute']:g} absolute" for g, n in noise.items())
    intro = (
        f"<p>{esc(ident['method'].capitalize())}; {len(ident['sample_times'])} samples at t = "
        f"{esc(', '.join(f'{t:g}' for t in ident['sample_times'][:12]))}"
        f"{' ...' if len(ident['sample_times']) > 12 else ''} s; measurements "
        f"{'rounded to ' + str(digits) + ' significant digits' if digits else 'not rounded'}"
        f"{esc('; noise: ' + noisy) if noisy else ''}. {esc(ident['excitation'])}. {esc(ident['uncertainty'])}; "
        f"{esc(ident['rel_error_definition'])}.</p>"
    )
    return section(
        "identification",
        "Identification (paper section 2.3, Tables 3 and 4)",
        intro
        + fig
        + table(
            [
                "body",
                "parameter",
                "true",
                "identified",
                "abs error",
                "rel error",
                "std",
                "95 % interval",
                "paper identified",
                "paper abs error",
                "larger error",
                "identifiable",
            ],
            rows,
        ),
    )


def identification_full(r: dict) -> str:
    f = r["identification_full"]
    rows = [
        [
            esc(p["body"]),
            esc(p["name"]),
            num(p["true"]),
            num(p["identified"]),
            num(p["rel_error"]),
            num(p["std"]),
            identifiability(p),
        ]
        for p in f["parameters"]
    ]
    return section(
        "identification_full",
        "All 10 inertial parameters per body",
        (
            f"<p>{esc(f['method'])}; {esc(f['rel_error_definition'])}. Largest relative error "
            f"{num(f['max_abs_rel_error'])}; not identifiable: {esc(', '.join(f['not_identifiable']) or 'none')}; "
            f"weakly identifiable: {esc(', '.join(f['weakly_identifiable']) or 'none')} ({esc(f['weak_definition'])}), "
            f"largest error {num(f['max_abs_rel_error_weak'])}.</p>"
            + table(["body", "parameter", "true", "identified", "rel error", "std", "identifiable"], rows)
        ),
    )


def lagrange(r: dict, rec: TimeSeries) -> str:
    lg = r["lagrange"]
    t = np.array(lg["t"])
    forms = lg["formulations"]
    big = 1e20  # singular rows (inf) are drawn at the top of the axis
    cond = {
        f"cond(Phi_q), {k}": np.array([big if c is None else min(c, big) for c in v["cond_Phi_q"]])
        for k, v in forms.items()
    }
    cond.update(
        {
            f"cond(Eq. 111), {k}": np.array([big if c is None else min(c, big) for c in v["cond_system"]])
            for k, v in forms.items()
        }
    )
    flags = np.zeros(len(t), dtype=bool)
    for row in lg["rows_not_evaluated"]:
        flags |= np.isclose(t, row["t"])
    fig = figure(
        plots.lines(t, cond, "condition number", "Conditioning along the trajectory", logy=True, flags=flags),
        "Shaded: rows where a body's cond(D) > 100 makes Eq. 111 singular; values above 1e20 (singular) drawn at 1e20.",
    )
    frows = [
        [
            esc(k),
            str(v["rows"]),
            f"{v['rank_Phi_q_min']} to {v['rank_Phi_q_max']}",
            num(v["max_abs_phi_on_recording"]),
            num(v["acceleration_check_max_rel_error"]),
            num(v["reaction_check_max_rel_error"]),
            esc(", ".join(f"{j}: {n}" for j, n in v["axis_rows_rank_deficient"].items() if n) or "none"),
        ]
        for k, v in forms.items()
    ]
    skipped = ", ".join(f"{x['t']:g}" for x in lg["rows_not_evaluated"]) or "none"
    body = (
        f"<p>{esc(lg['definition'])}. Rows evaluated: {lg['rows_evaluated']}; not evaluated: "
        f"{esc(skipped)} s.</p>"
        + table(
            [
                "formulation",
                "rows",
                "rank of Phi_q",
                "max |Phi| on recording",
                "accelerations vs MuJoCo",
                "reactions vs MuJoCo",
                "joints whose axis rows lose rank (rows)",
            ],
            frows,
        )
        + fig
    )
    body += _multipliers(lg["at_time"]) + _forward(lg["forward_simulation"])
    return section("lagrange", "Constraints, Eq. 111 and Lagrange multipliers (sections 2.4, 2.5, 3.2)", body)


def _multipliers(at: dict | None) -> str:
    """The multipliers at the paper's instant beside its printed ones."""
    if at is None or not at["bodies"]:
        return ""
    rows = []
    for b in at["bodies"]:
        lam = ", ".join(f"{lab} {num(v)}" for lab, v in zip(b["labels"], b["lambda"], strict=True))
        paper = (
            ", ".join(num(v) for v in b["paper_lambda_magnitudes"])
            if any(v is not None for v in b["paper_lambda_magnitudes"])
            else DASH
        )
        rows.append(
            [
                esc(b["body"]),
                esc(b["joint"]),
                lam,
                esc(np.round(b["constraint_force_W"], 1).tolist()),
                num(b["static_weight_outboard"]),
                paper,
            ]
        )
    return (
        f"<h3>Lagrange multipliers at t = {at['t']:g} s</h3><p>Well-conditioned formulation. The paper's "
        "lambda_i1..i5 are printed without signs; its lambda_i3 equal the static weight of the bodies "
        "outboard of O_i (column 'sum m g'), which the stated motion does not produce.</p>"
        + table(
            [
                "body",
                "joint",
                "lambda (ours)",
                "constraint force on B_i [N], world",
                "sum m g [N]",
                "paper |lambda_i1..5|",
            ],
            rows,
        )
    )


def _forward(fw: dict | None) -> str:
    """The constrained model integrated over the run, against MuJoCo."""
    if not fw:
        return ""
    dev = table(
        ["joint", "max deviation", "correction / drive"],
        [[esc(j), num(v), num(fw["correction_over_drive"][j])] for j, v in fw["max_joint_deviation"].items()],
    )
    ol = fw["open_loop_departure_time"]
    return (
        f"<h3>Forward simulation of the constrained model</h3><p>{esc(fw['method'])}. Largest centre-of-mass "
        f"deviation from MuJoCo {num(fw['max_position_deviation'])} m, largest |Phi| {num(fw['max_abs_phi'])}. "
        + (
            f"Open loop (recorded torques alone) the replay leaves MuJoCo's trajectory by more than 1e-6 at "
            f"t = {ol:g} s: the motion is unstable without feedback."
            if ol is not None
            else "Open loop the replay stays within 1e-6 of MuJoCo over the run."
        )
        + "</p>"
        + dev
    )
