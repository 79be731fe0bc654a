"""The report's sections, top to bottom, one function each: results (and the recording) in,
an HTML fragment out. Numbers are formatted here; figures come from report.plots."""

from __future__ import annotations

import html

import numpy as np

from harness.cardano import GIMBAL_COND_D
from harness.recording import Recording
from harness.report import plots


def esc(x) -> str:
    return html.escape(str(x))


def num(x, digits: int = 3) -> str:
    if x is None:
        return "&ndash;"
    if isinstance(x, bool):
        return "yes" if x else "no"
    if isinstance(x, int):
        return str(x)
    x = float(x)
    if x == 0.0:
        return "0"
    if 1e-3 <= abs(x) < 1e6:
        return f"{x:.{digits + 3}g}"
    return f"{x:.{digits}e}"


def table(header: list[str], rows: list[list], cls: str = "") -> str:
    head = "".join(f"<th>{esc(h)}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{c}</td>" for c in row) + "</tr>" for row in rows)
    return f'<table class="{cls}"><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>'


def figure(svg: str, caption: str) -> str:
    return f"<figure>{svg}<figcaption>{esc(caption)}</figcaption></figure>"


def section(anchor: str, title: str, body: str) -> str:
    return f'<section id="{anchor}"><h2>{esc(title)}</h2>{body}</section>'


def verdict(r: dict) -> str:
    ok = r["passed"]
    badge = f'<div class="verdict {"pass" if ok else "fail"}" id="verdict">{"PASSED" if ok else "FAILED"}</div>'
    failing = [g for g in r["gates"] if not g["passed"]]
    summary = (
        f"All {len(r['gates'])} gates pass."
        if ok
        else f"{len(failing)} of {len(r['gates'])} gates fail: " + ", ".join(esc(g["name"]) for g in failing)
    )
    if not r["gates"]:
        summary = "This scenario declares no gates."
    rows = [
        [
            esc(g["name"]),
            f"<code>{esc(g['metric'])}</code>",
            num(g["value"]),
            ("&le; " if g["direction"] == "at_most" else "&ge; ") + num(g["limit"]),
            f'<span class="{"ok" if g["passed"] else "bad"}">{"pass" if g["passed"] else "FAIL"}</span>'
            + (f" ({esc(g['reason'])})" if g["reason"] else ""),
        ]
        for g in r["gates"]
    ]
    tq, ident = r["torques"], r["identification"]
    digits = ident["significant_digits"]
    measured = f" at {digits} significant digits" if digits else " with ideal measurements"
    res = r["graph"]["unconstrained_residual"]
    answers = (
        "<ul>"
        f"<li><b>Does the graph model agree with MuJoCo and Pinocchio?</b> Joint torques: graph vs "
        f"Pinocchio {num(tq['graph_vs_pinocchio']['max_rel_error'])}, graph vs MuJoCo "
        f"{num(tq['graph_vs_mujoco']['max_rel_error'])}, Pinocchio vs MuJoCo "
        f"{num(tq['pinocchio_vs_mujoco']['max_rel_error'])} (largest relative error, worst at joint "
        f"{esc(tq['graph_vs_mujoco']['max_rel_joint'])}, t = {num(tq['graph_vs_mujoco']['max_rel_t'])} s). "
        f"Unconstrained dynamics residual: {num(res['max_translational'])} (forces), "
        f"{num(res['max_rotational'])} (moments).</li>"
        f"<li><b>How well does the identification work?</b> Largest relative error of an identified "
        f"parameter: {num(ident['max_abs_rel_error'])}"
        f"{measured}"
        f"; not identifiable: {esc(', '.join(ident['not_identifiable']) or 'none')}.</li></ul>"
    )
    return section(
        "verdict",
        "Verdict",
        badge + f"<p>{summary}</p>" + answers + table(["gate", "metric", "value", "limit", "result"], rows, "gates"),
    )


def model(r: dict) -> str:
    m = r["model"]
    rows = []
    for b in m["bodies"]:
        if b["massless"]:
            rows.append([esc(b["name"]), "massless", "", "", "", "0", "", "", ""])
            continue
        rows.append(
            [
                esc(b["name"]),
                esc(b.get("shape", "explicit")),
                num(b.get("length")),
                num(b.get("radius")),
                num(b.get("density")),
                f"{b['mass']:.4f}",
                f"{b['J11']:.4f}",
                f"{b['J22']:.4f}",
                f"{b['J33']:.4f}",
            ]
        )
    joints = [
        [
            esc(j["name"]),
            esc(j["type"]),
            esc(j["parent"]),
            esc(j["child"]),
            esc(np.round(j["point"], 6).tolist()),
            esc(np.round(j["axis"], 6).tolist()),
        ]
        for j in m["joints"]
    ]
    tested = r["run"]["model_under_test"]
    note = (
        ""
        if tested == m["file"]
        else (
            f'<p class="warn">The graph model is built from <code>{esc(tested)}</code>; MuJoCo and Pinocchio from '
            f"<code>{esc(m['file'])}</code>.</p>"
        )
    )
    return section(
        "model",
        f"Model: {m['name']}",
        f"<p>{esc(m['description'])} (<code>{esc(m['file'])}</code>)</p>"
        + note
        + "<h3>Bodies (masses and principal inertias as computed; the paper's Table 2 prints "
        "them to 4 decimals)</h3>"
        + table(["body", "shape", "l [m]", "R [m]", "rho [kg/m^3]", "m [kg]", "J11 [kg m^2]", "J22", "J33"], rows)
        + "<h3>Joints (world frame, initial pose)</h3>"
        + table(["joint", "type", "inner body", "outer body", "point [m]", "axis"], joints),
    )


def motion(r: dict, rec: Recording) -> str:
    t = rec.t
    rev = {j: rec.q[:, k] for k, j in enumerate(rec.joints) if r["model"]["joints"][k]["type"] == "revolute"}
    pri = {j: rec.q[:, k] for k, j in enumerate(rec.joints) if r["model"]["joints"][k]["type"] != "revolute"}
    figs = [figure(plots.lines(t, rev, "q [rad]", "Revolute joint angles"), "Joint angles as recorded.")]
    if pri:
        figs.append(figure(plots.lines(t, pri, "q [m]", "Prismatic joint positions"), "Joint positions."))
    panels = [
        (b, {"alpha": rec.theta[:, i, 0], "beta": rec.theta[:, i, 1], "gamma": rec.theta[:, i, 2]}, rec.gimbal[:, i])
        for i, b in enumerate(rec.bodies)
    ]
    figs.append(
        figure(
            plots.grid(t, panels, "[rad]"),
            "Cardano angles A(0i) = Rx(alpha) Ry(beta) Rz(gamma); shaded: rows near gimbal lock "
            f"(cond(D) > {GIMBAL_COND_D:g}, or cos(beta) changing sign between rows).",
        )
    )
    acc = {b: np.linalg.norm(rec.a_W[:, i], axis=1) for i, b in enumerate(rec.bodies)}
    figs.append(
        figure(
            plots.lines(t, acc, "|a| [m/s^2]", "Centre-of-mass accelerations"),
            "Magnitude of each body's centre-of-mass acceleration (world frame).",
        )
    )
    rec_s = r["recording"]
    track = table(
        ["joint", "max |q - q_d|", "max |q' - q'_d|", "max |q'' - q''_d|"],
        [
            [esc(j), num(v["q_max_abs_error"]), num(v["qd_max_abs_error"]), num(v["qdd_max_abs_error"])]
            for j, v in rec_s["tracking_error"].items()
        ],
    )
    sc = r["scenario"]
    mot = table(["joint", "motion"], [[esc(j), esc(m["description"])] for j, m in sc["motion"].items()])
    return section("motion", "Motion", mot + "".join(figs) + "<h3>Tracking of the prescribed motion</h3>" + track)


def _larger(p: dict) -> str:
    """Whose absolute error is larger, ours or the paper's (Table 4), where both exist."""
    if p["abs_error"] is None or p["paper_abs_error"] is None:
        return "&ndash;"
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
                f"{p['identified']:.6f}" if p["identified"] is not None else "&ndash;",
                num(p["abs_error"]),
                num(p["rel_error"]),
                num(p.get("std")),
                "&ndash;" if not p.get("ci95") else f"[{num(p['ci95'][0])}, {num(p['ci95'][1])}]",
                num(p["paper_identified"]),
                num(p["paper_abs_error"]),
                _larger(p),
                '<span class="ok">yes</span>'
                if p["identifiable"]
                else f'<span class="bad">no</span> <small>{esc(p["reason"])}</small>',
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


def torques(r: dict) -> str:
    tq = r["torques"]
    t = np.array([s["t"] for s in tq["samples"]])
    src = {k: np.array([s[k] for s in tq["samples"]]) for k in ("mujoco", "pinocchio", "graph")}
    styles = {"mujoco": "-", "pinocchio": "--", "graph": "o"}
    panels = [(j, {k: v[:, n] for k, v in src.items()}, None) for n, j in enumerate(tq["joints"])]
    scale = np.array([tq["load_scale"][j] for j in tq["joints"]])
    err = [
        (
            j,
            {
                "graph vs pinocchio": np.abs(src["graph"][:, n] - src["pinocchio"][:, n]) / scale[n],
                "graph vs mujoco": np.abs(src["graph"][:, n] - src["mujoco"][:, n]) / scale[n],
                "pinocchio vs mujoco": np.abs(src["pinocchio"][:, n] - src["mujoco"][:, n]) / scale[n],
            },
            None,
        )
        for n, j in enumerate(tq["joints"])
    ]
    floor = lambda p: [(a, {k: np.maximum(v, 1e-18) for k, v in s.items()}, f) for a, s, f in p]  # noqa: E731
    rows = [
        [
            esc(k.replace("_vs_", " vs ")),
            num(v["max_abs_error"]),
            f"{esc(v['max_abs_joint'])} at {num(v['max_abs_t'])} s",
            num(v["max_rel_error"]),
            f"{esc(v['max_rel_joint'])} at {num(v['max_rel_t'])} s",
        ]
        for k, v in tq.items()
        if "_vs_" in k
    ]
    react = tq["reactions"]
    rrows = [
        [
            esc(src_name.replace("_vs_", " vs ")),
            esc(part),
            num(v["max_rel_error"]),
            f"{esc(v['joint'])} at {num(v['t'])} s",
        ]
        for src_name, parts in react.items()
        if src_name != "definition"
        for part, v in parts.items()
    ]
    return section(
        "torques",
        "Joint torques three ways",
        (
            f"<p>Drive torque (force for a prismatic joint) of every joint from MuJoCo (what drove the simulation), "
            f"Pinocchio RNEA (built from the spec) and the graph-theory model (from the recorded motion alone). "
            f"<b>Definition:</b> {esc(tq['definition'])}.</p>"
            + table(["pair", "largest abs error", "where", "largest rel error", "where"], rows)
            + figure(
                plots.grid(t, panels, "tau [N m | N]", styles=styles), "Drive torques of each joint, three sources."
            )
            + figure(
                plots.grid(t, floor(err), "rel. error", logy=True), "Relative errors |a - b| / L_J (floored at 1e-18)."
            )
            + f"<h3>Joint reaction wrenches</h3><p>{esc(react['definition'])}.</p>"
            + table(["sources", "part", "largest rel error", "where"], rrows)
        ),
    )


def lagrange(r: dict, rec: Recording) -> str:
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
    at = lg["at_time"]
    if at is not None and at["bodies"]:
        rows = []
        for b in at["bodies"]:
            lam = ", ".join(f"{lab} {num(v)}" for lab, v in zip(b["labels"], b["lambda"], strict=True))
            paper = (
                ", ".join(num(v) for v in b["paper_lambda_magnitudes"])
                if any(v is not None for v in b["paper_lambda_magnitudes"])
                else "&ndash;"
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
        body += (
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
    fw = lg["forward_simulation"]
    if fw:
        dev = table(
            ["joint", "max deviation", "correction / drive"],
            [[esc(j), num(v), num(fw["correction_over_drive"][j])] for j, v in fw["max_joint_deviation"].items()],
        )
        ol = fw["open_loop_departure_time"]
        body += (
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
    return section("lagrange", "Constraints, Eq. 111 and Lagrange multipliers (sections 2.4, 2.5, 3.2)", body)


def how(r: dict) -> str:
    run = r["run"]
    timings = run.get("timings") or {}
    stages = table(["stage", "seconds"], [[esc(k), f"{v:.2f}"] for k, v in timings.items()]) if timings else ""
    versions = table(["package", "version"], [[esc(k), esc(v)] for k, v in run["versions"].items()])
    sim = r["scenario"]["simulation"]
    return section(
        "how",
        "How the run was made",
        (
            f"<p>Run at {esc(run['time'])} (UTC). MuJoCo {esc(r['recording']['engine_version'])}, integrator "
            f"{esc(sim['integrator'])}, time step {num(sim['timestep'])} s, computed-torque drive with bandwidth "
            f"{num(sim['tracking_bandwidth'])} rad/s. Scenario file <code>{esc(r['scenario']['file'])}</code>:</p>"
            f"<pre>{esc(run['scenario_text'])}</pre>"
            + (("<h3>Time spent in each stage</h3>" + stages) if stages else "")
            + versions
        ),
    )


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
            '<span class="ok">holds</span>' if c["holds"] else '<span class="bad">does not hold</span>',
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
        "design",
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
            f'<span class="{"ok" if e["verdict"] != "disagrees" else "bad"}">{esc(e["verdict"])}</span>',
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
        "audit",
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
            '<span class="ok">yes</span>'
            if p["identifiable"]
            else f'<span class="bad">no</span> <small>{esc(p["reason"])}</small>',
        ]
        for p in f["parameters"]
    ]
    return section(
        "identification_full",
        "All 10 inertial parameters per body",
        (
            f"<p>{esc(f['method'])}; {esc(f['rel_error_definition'])}. Largest relative error "
            f"{num(f['max_abs_rel_error'])}; not identifiable: {esc(', '.join(f['not_identifiable']) or 'none')}.</p>"
            + table(["body", "parameter", "true", "identified", "rel error", "std", "identifiable"], rows)
        ),
    )


def torque_identification(r: dict) -> str:
    t = r["torque_identification"]
    rows = [[esc(b["expression"]), num(b["true"]), num(b["identified"]), num(b["rel_error"])] for b in t["base"]]
    v = t["validation"]
    val = (
        (
            f"Predicted torques of the validation trajectory <code>{esc(v['scenario'])}</code>: largest error "
            f"{num(v['max_rel_error'])}, RMS {num(v['rms_rel_error'])} ({esc(v['definition'])})."
        )
        if v
        else ""
    )
    return section(
        "torque_identification",
        "Identification from joint torques alone",
        (
            f"<p>{esc(t['method'])}. {t['base_parameters']} base parameters out of {t['parameters']}; condition number "
            f"of the scaled base regressor {num(t['condition_number'])}; largest error {num(t['max_rel_error'])} "
            f"({esc(t['rel_error_definition'])}). {val}</p>"
            + table(["base parameter", "true", "identified", "rel error"], rows, "wrap")
        ),
    )


def excitation(r: dict) -> str:
    e = r["excitation"]
    return section(
        "excitation",
        "Optimised excitation",
        (
            f"<p>{e['harmonics']}-harmonic Fourier series per joint, base frequency {num(e['base_frequency'])} rad/s, "
            f"{e['evaluations']} evaluations of the objective ({esc(e['objective'])}). Condition number "
            f"{num(e['initial_condition_number'])} at the start, {num(e['optimised_condition_number'])} optimised.</p>"
        ),
    )
