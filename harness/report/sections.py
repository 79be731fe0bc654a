"""The report's sections, top to bottom, one function each: results (and the recording) in,
an HTML fragment out. Numbers are formatted here; figures come from report.plots. A measured log's
own sections are harness/report/log_sections.py's."""

from __future__ import annotations

import numpy as np
from markupsafe import Markup

from harness.base.series import TimeSeries
from harness.report import plots
from harness.report.html import DASH, code, esc, figure, mark, num, page, section, table
from harness.runner.gates import summary_line
from harness.runner.results import said_first


def identifiability(p: dict) -> str:
    """A parameter's verdict: yes, weak (with its sensitivity) or no (with the reason)."""
    if not p.get("identifiable", True):
        return mark(False, "no") + Markup(" <small>{}</small>").format(p.get("reason", ""))
    if p.get("weakly_identifiable"):
        return mark(False, "weak") + Markup(" <small>sensitivity {}</small>").format(num(p.get("sensitivity")))
    return mark(True, "yes")


def verdict(r: dict) -> str:
    ok = r["passed"]
    badge = f'<div class="verdict {"pass" if ok else "fail"}" id="verdict">{"PASSED" if ok else "FAILED"}</div>'
    failing = [g for g in r["gates"] if not g["passed"]]
    summary = esc(summary_line(r["scenario"]["name"], r["gates"])) + (
        Markup(": ") + Markup(", ").join(esc(g["name"]) for g in failing) if failing else "")
    versions = r["run"]["versions"]
    made = esc(f"harness {versions.get('harness', '?')}, MuJoCo {versions.get('mujoco', '?')}, Pinocchio "
               f"{versions.get('pinocchio', '?')}; run {r['run'].get('id', '(no id)')} at {r['run']['time']} (UTC)")
    said = [*r["scenario"].get("model_notes", []), *said_first(r)]
    warnings = ("<p>What reading the model and the data assumed or found (each also said on the terminal):</p><ul>"
                + "".join(f'<li class="warn">{esc(w)}</li>' for w in said) + "</ul>") if said else ""
    rows = [
        [
            esc(g["name"]),
            code(g["metric"]),
            num(g["value"]),
            ("\u2264 " if g["direction"] == "at_most" else "\u2265 ") + num(g["limit"]),
            (esc("skip") if g.get("skipped") else mark(g["passed"], "pass" if g["passed"] else "FAIL"))
            + (f" ({g['reason']})" if g["reason"] else ""),
            esc(g.get("where") or ""),
        ]
        for g in r["gates"]
    ]
    answers = []
    tq = r.get("torques", {})
    for name in tq.get("models", {}):
        m, p = tq[f"{name}_vs_mujoco"], tq[f"{name}_vs_pinocchio"]
        answers.append(
            f"<li><b>Does model {esc(name)} agree with MuJoCo and Pinocchio?</b> Largest relative torque error "
            f"{num(m['max_rel_error'])} against MuJoCo (joint {esc(m['max_rel_joint'])}, t = {num(m['max_rel_t'])} s), "
            f"{num(p['max_rel_error'])} against Pinocchio.</li>")
    if "pinocchio_vs_mujoco" in tq:
        answers.append(f"<li><b>Do the reference engines agree?</b> Pinocchio vs MuJoCo "
                       f"{num(tq['pinocchio_vs_mujoco']['max_rel_error'])}.</li>")
    for name, m in r.get("identification_methods", {}).items():
        if m.get("skipped") or "data" in r:  # skipped, or a row of a log's table
            answers.append(f"<li><b>How well does identification method {esc(name)} work?</b> "
                           + (f"Skipped: {esc(m['skipped'])}" if m.get("skipped") else
                              f"Held-out torque error {num(m.get('validation_rel_error', m.get('training_rel_error')))}"
                              + (f", against the truth's torques {num(m['truth']['validation_rel_error'])}"
                                 if m.get("truth") else "") + ".") + "</li>")
            continue
        v, b = m.get("validation"), m.get("base_parameters")
        answers.append(
            f"<li><b>How well does identification method {esc(name)} work?</b> "
            + (f"Base parameters: largest relative error {num(b['max_rel_error'])}. " if b else "")
            + (f"Torques predicted on {esc(v['scenario'])}: largest relative error {num(v['max_rel_error'])}."
               if v else "") + "</li>")
    return section(
        "verdict",
        "Verdict",
        badge + f"<p>{summary}</p><p><small>{made}</small></p>" + warnings
        + (f"<ul>{''.join(answers)}</ul>" if answers else "")
        + table(["gate", "metric", "value", "limit", "result", "worst case"], rows, "gates"),
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
            esc(", ".join(f"{k} {v:g}" for k, v in j["friction"].items() if v)) if j.get("friction") else "",
        ]
        for j in m["joints"]
    ]
    tested = r["run"].get("models_under_test", {})
    note = "".join(
        f'<p class="warn">Model under test {esc(k)} is built from <code>{esc(v["model_file"])}</code>; MuJoCo and '
        f"Pinocchio from <code>{esc(m['file'])}</code>.</p>"
        for k, v in tested.items() if v["model_file"] != m["file"])
    return section(
        "model",
        f"Model: {m['name']}",
        f"<p>{esc(m['description'])} (<code>{esc(m['file'])}</code>)</p>"
        + note
        + "<h3>Bodies (masses and principal moments of inertia about the centre of mass)</h3>"
        + table(["body", "shape", "l [m]", "R [m]", "rho [kg/m^3]", "m [kg]", "J11 [kg m^2]", "J22", "J33"], rows)
        + "<h3>Joints (world frame, initial pose)</h3>"
        + table(["joint", "type", "inner body", "outer body", "point [m]", "axis", "drive (friction, rotor)"],
                joints)
        + _drives(m.get("transmission")),
    )


def _drives(tr: dict | None) -> str:
    """The model's drives: each motor's row of N (q_m = N q + offset), its offset and its law."""
    if tr is None:
        return ""
    rows = [[esc(motor), esc(np.round(row, 6).tolist()), num(offset),
             esc(", ".join(f"{k} {v:g}" for k, v in tr["laws"][motor].items() if v))]
            for motor, row, offset in zip(tr["motors"], tr["N"], tr["offset"], strict=True)]
    return ("<h3>Drives (q_m = N q + offset; each motor's law in motor units, reaching the joints as N^T tau_m)</h3>"
            + table(["motor", "row of N", "offset [rad]", "law (friction, rotor)"], rows))


def motion(r: dict, rec: TimeSeries) -> str:
    t = rec.t
    rev = {j: rec.q[:, k] for k, j in enumerate(rec.joints) if r["model"]["joints"][k]["type"] == "revolute"}
    pri = {j: rec.q[:, k] for k, j in enumerate(rec.joints) if r["model"]["joints"][k]["type"] != "revolute"}
    figs = [figure(plots.lines(t, rev, "q [rad]", "Revolute joint angles"), "Joint angles as recorded.")]
    if pri:
        figs.append(figure(plots.lines(t, pri, "q [m]", "Prismatic joint positions"), "Joint positions."))
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
    lim = r.get("motion", {})
    limits = ""
    if lim:
        limits = (f"<h3>Against the model's limits</h3><p>{esc(lim['definition'])}.</p>"
                  + (f'<p class="warn">Beyond a limit: {esc(", ".join(lim["beyond"]))}.</p>' if lim["beyond"] else "")
                  + table(["joint", "position", "velocity", "effort"],
                          [[esc(j), *(num(v[k]) if v[k] is not None else DASH
                                      for k in ("position", "velocity", "effort"))] for j, v in lim["limits"].items()]))
    return section("motion", "Motion", mot + limits + "".join(figs) + "<h3>Tracking of the prescribed motion</h3>"
                   + track)


def estimator_comparison(r: dict) -> str:
    e = r["estimators"]
    methods = e["methods"]
    rows = [[esc(name), esc(m["description"]), num(m["max_bias_in_sd"]), num(m["median_bias_in_sd"]),
             str(m["significant_biases"]), f"{num(m['coverage_min'])} / {num(m['coverage_median'])} / "
             f"{num(m['coverage_max'])}", str(m["coverage_outside_band"]), num(m["median_rms_rel_error"]),
             num(m["validation_rel_error_mean"]),
             num(m["seconds_per_fit"])] for name, m in methods.items()]
    labels = [str(k) for k in range(len(next(iter(methods.values()))["per_parameter"]["bias_in_sd"]))]
    fig_bias = figure(plots.bars(labels, {k: m["per_parameter"]["bias_in_sd"] for k, m in methods.items()},
                                 "|bias| / sd", "Bias of each base parameter, in standard deviations"),
                      "Per base parameter (numbered as in the torque identification's table): the mean error over "
                      "the trials relative to the error's spread.")
    coverage = {k: m["per_parameter"]["coverage"] for k, m in methods.items()}
    residual = methods.get("iv", {}).get("coverage_from_residuals")
    if residual:
        coverage["iv, intervals from the residuals"] = residual["per_parameter"]
    lo, hi = e["coverage_band"]
    fig_cov = figure(plots.bars(labels, coverage, "coverage", "Coverage of the 95 % intervals", logy=False),
                     f"Fraction of the {e['trials']} trials whose 95 % interval holds the truth; a calibrated "
                     f"interval falls within {num(lo)} to {num(hi)} (3 binomial standard errors).")
    source = {"sensors": "propagated from the sensors' specification (harness/identify/propagation.py)",
              "residuals": "estimated from the residuals"}[e["iv_intervals_from"]]
    iv_note = ""
    if residual:
        iv_note = (f" Estimated from the residuals instead, the same estimates' intervals cover "
                   f"{num(residual['min'])} / {num(residual['median'])} / {num(residual['max'])} (min / median / "
                   f"max), {residual['outside_band']} parameters outside the band.")
    return section(
        "estimators", "Estimators side by side",
        f"<p>{e['trials']} measurements of the same recording under the scenario's noise, "
        f"{e['samples_per_trial']} samples each; {esc(e['definition'])}. Binomial standard error of a coverage at "
        f"this trial count: {num(e['coverage_binomial_standard_error'])}. The instrumental variables' intervals are "
        f"{source}.{iv_note}</p>"
        + table(["estimator", "method", "max |bias|/sd", "median |bias|/sd", "significant biases",
                 "coverage min / median / max", f"outside {num(lo)}-{num(hi)}", "median RMS rel error",
                 "validation error", "s per fit"], rows)
        + fig_bias + fig_cov)


def _floating(fl: dict | None) -> str:
    """A floating base's part of the torques section: the robot judged with its base free."""
    if not fl:
        return ""
    return (f"<h3>A floating base</h3><p>The base {esc(fl['base'])} (joint {esc(fl['joint'])}) judged free at "
            f"{fl['states']} states: the engines differ by {num(fl['engines_max_rel_error'])} in the base's rows and "
            f"the joints' torques and by {num(fl['mass_matrix_max_rel_error'])} in the mass matrix "
            f"({esc(fl['definition'])}).</p>" + _moved(fl))


def _moved(fl: dict) -> str:
    """A floating base the bench moved: how closely, and each model's finding of the world's wrench on it."""
    if "base_tracking_position_m" not in fl:
        return ""
    found = "; ".join(f"{esc(k.removeprefix('base_wrench_').removesuffix('_vs_mujoco_max_rel_error'))} "
                      f"{num(v)}" for k, v in fl.items() if k.startswith("base_wrench_"))
    return (f"<p>The bench moved the base along [base_motion] to within {num(fl['base_tracking_position_m'])} m and "
            f"{num(fl['base_tracking_angle_rad'])} rad, and recorded the world's wrench on it; found again from the "
            f"recorded states by {found} ({esc(fl['moved_definition'])}).</p>" + _standing(fl))


def _standing(fl: dict) -> str:
    """A floating base that stood on contacts: what held it, and how firmly."""
    if "contacts" not in fl:
        return ""
    held = ", ".join(f"{esc(c)} ({n} rows)" for c, n in zip(fl["contacts"], fl["contacts_held_rows"], strict=True))
    return (f"<p>It stood on its contacts, held: {held}. Besides them the world applied at most "
            f"{num(fl['base_wrench_besides_contacts_max_rel'])} of its whole wrench on the base, and a held point "
            f"slipped at most {num(fl['contact_slip_m'])} m; the least a held point pressed on the ground was "
            f"{num(fl['contact_least_normal_force_N'])} N and the motion needs a friction coefficient of "
            f"{num(fl['contact_friction_needed'])}; a pressing contact's centre of pressure lay at most "
            f"{num(fl.get('contact_centre_of_pressure_m'))} m from its point ({esc(fl['standing_definition'])}).</p>")


def _closed_chain(cc: dict | None) -> str:
    """A closed chain's part of the torques section: what the actuated torques are, and its loops."""
    if not cc:
        return ""
    loops = [[esc(name), esc(v["type"]), *((esc(v["body1"]), esc(v["body2"])) if "body1" in v else (
                 esc(f"joint {v['follower']}"), esc(f"joint {v['leader']} (ratio {num(v['ratio'])}, offset "
                                                    f"{num(v['offset'])})"))), num(cc["loop_gap_per_loop"][name])]
             for name, v in cc["loops"].items()]
    settings = cc.get("loop_settings") or {}
    return (
        "<h3>A closed chain</h3>"
        f"<p>Actuated joints: {esc(', '.join(cc['actuated']))}; passive: {esc(', '.join(cc['passive']))}. "
        f"The torques compared are the actuated joints': {esc(cc['projection'])}. Here the tree's own torques at "
        f"the actuated joints differ from the chain's by up to {num(cc['raw_tree_vs_actuated_max_rel_error'])} "
        "of the joint's load. With the loops' forces (the multipliers) applied to Pinocchio's bodies (a "
        "coupling's to its two joints) its passive "
        f"joints need at most {num(cc['passive_torque_with_loop_forces_max'])} N m; the loops' generalised "
        f"forces agree with MuJoCo's to {num(cc['loop_forces_vs_mujoco_max_rel_error'])} "
        f"({esc(cc['loop_forces_definition'])}). MuJoCo's loops are soft constraints (solref "
        f"{esc(' '.join(num(x) for x in settings.get('solref', [])))}, solimp "
        f"{esc(' '.join(num(x) for x in settings.get('solimp', [])))}): each stays open by its gap"
        + _against_rigid_loops(cc.get("mujoco_vs_rigid_loops"))
        + ".</p>" + _forward_of_models(cc.get("forward"))
        + table(["loop", "type", "body 1 (a coupling: follower)", "body 2 (leader)",
                 "largest gap [m; a coupling of hinges: rad]"], loops)
    )


def _against_rigid_loops(rigid: dict | None) -> str:
    if not rigid:
        return ""
    if "skipped" in rigid:
        return f"; not compared with rigid loops ({esc(rigid['skipped'])})"
    return (f"; against rigid loops (Pinocchio's constraintDynamics under the same torques) the run moves by up to "
            f"{num(rigid['max_rel_range'])} of a joint's range ({esc(rigid['max_rel_joint'])})")


def _forward_of_models(fw: dict | None) -> str:
    """The closed-chain models' forward runs against Pinocchio's rigid loops, a sentence each."""
    if not fw:
        return ""
    if "definition" not in fw:  # skipped, each model saying why
        return "<p>Forward dynamics of the models under test: not compared (" + "; ".join(
            f"{esc(name)}: {esc(v['skipped'])}" for name, v in fw.items()) + ").</p>"
    said = [f"{esc(name)}: failed ({esc(v['failed'])})" if "failed" in v else
            f"{esc(name)}: within {num(v['max_rel_range'])} of a joint's range ({esc(v['max_rel_range_joint'])} at "
            f"t = {num(v['max_rel_range_t'])} s)"
            for name, v in fw.items() if isinstance(v, dict)]
    return (f"<p>Forward dynamics of each model under test, {fw['segments']} runs of {num(fw['segment_s'])} s: "
            f"{esc(fw['definition'])}. " + "; ".join(said) + ".</p>")


def torques(r: dict) -> str:
    tq = r["torques"]
    t = np.array([s["t"] for s in tq["samples"]])
    names = ["mujoco", "pinocchio", *tq.get("models", {})]
    src = {k: np.array([s[k] for s in tq["samples"]]) for k in names}
    styles = {"mujoco": "-", "pinocchio": "--", **{k: "o" for k in tq.get("models", {})}}
    panels = [(j, {k: v[:, n] for k, v in src.items()}, None) for n, j in enumerate(tq["joints"])]
    scale = np.array([tq["load_scale"][j] for j in tq["joints"]])
    pairs = [k for k in tq if "_vs_" in k and all(side in src for side in k.split("_vs_"))]
    random = {k.removesuffix("_random_vs_pinocchio"): v for k, v in tq.items() if k.endswith("_random_vs_pinocchio")}
    err = [
        (j, {k.replace("_vs_", " vs "): np.abs(src[a][:, n] - src[b][:, n]) / scale[n]
             for k in pairs for a, b in [k.split("_vs_")]}, None)
        for n, j in enumerate(tq["joints"])
    ]
    floor = lambda p: [(a, {k: np.maximum(v, 1e-18) for k, v in s.items()}, f) for a, s, f in p]  # noqa: E731
    rows = [
        [
            esc(k.replace("_vs_", " vs ")),
            num(tq[k]["max_abs_error"]),
            f"{esc(tq[k]['max_abs_joint'])} at {num(tq[k]['max_abs_t'])} s",
            num(tq[k]["max_rel_error"]),
            f"{esc(tq[k]['max_rel_joint'])} at {num(tq[k]['max_rel_t'])} s",
        ]
        for k in pairs
    ]
    per_joint = [[esc(k.replace("_vs_", " vs ")), *(num(tq[k]["max_rel_error_per_joint"][j]) for j in tq["joints"])]
                 for k in pairs]
    react = tq["reactions"]
    rrows = [
        [esc(src_name.replace("_vs_", " vs ")), esc(part), num(v["max_rel_error"]),
         f"{esc(v['max_rel_joint'])} at {num(v['max_rel_t'])} s"]
        for src_name, parts in react.items()
        if src_name != "definition"
        for part, v in parts.items()
    ]
    mm = tq.get("mass_matrix", {})
    mrows = [[esc(k.replace("_vs_", " vs ")), num(v["max_rel_error"]), esc(v.get("max_rel_entry", "")),
              num(v.get("max_rel_t"))] for k, v in mm.items() if k != "definition"]
    rand_rows = [[esc(k), num(v["states"]), num(v["seed"]), num(v["max_rel_error"]), esc(v["max_rel_joint"]),
                  esc(", ".join(f"{j} {num(x)}" for j, x in v["worst_state"]["q"].items()))]
                 for k, v in random.items()]
    models = tq.get("models", {})
    intro = (
        "<p>Drive torque (force for a prismatic joint) of every joint from MuJoCo (what drove the simulation), "
        "Pinocchio RNEA (built from the same robot description) and each model under test ("
        + (", ".join(f"{esc(k)}: <code>{esc(v['plugin'])}</code>" for k, v in models.items()) or "none")
        + f"), all on the recorded motion. <b>Definition:</b> {esc(tq['definition'])}.</p>"
    )
    return section(
        "torques",
        "Joint torques",
        intro
        + _closed_chain(tq.get("closed_chain")) + _floating(tq.get("floating"))
        + table(["pair", "largest abs error", "where", "largest rel error", "where"], rows)
        + "<h3>Largest relative error per joint</h3>"
        + table(["pair", *tq["joints"]], per_joint)
        + _model_differences(r)
        + figure(plots.grid(t, panels, "tau [N m | N]", styles=styles), "Drive torques of each joint, every source.")
        + figure(plots.grid(t, floor(err), "rel. error", logy=True),
                 "Relative errors |a - b| / L_J (floored at 1e-18).")
        + f"<h3>Joint reaction wrenches</h3><p>{esc(react['definition'])}.</p>"
        + table(["sources", "part", "largest rel error", "where"], rrows)
        + (f"<h3>Mass matrix</h3><p>{esc(mm['definition'])}.</p>"
           + table(["pair", "largest rel error", "entry", "at t [s]"], mrows) if mrows else "")
        + (f"<h3>At random states, against Pinocchio</h3><p>{esc(next(iter(random.values()))['definition'])}.</p>"
           + table(["model", "states", "seed", "largest rel error", "joint", "q at that state"], rand_rows)
           if rand_rows else ""),
    )


def _model_differences(r: dict) -> str:
    """For a model under test built from another parameter file: its parameters that differ from
    the robot's (the truth), with the identified value where a stage identified that parameter."""
    out = []
    identified = {}
    for sec in r.values():
        if isinstance(sec, dict) and isinstance(sec.get("parameters"), list):
            for p in sec["parameters"]:
                if isinstance(p, dict) and "body" in p and p.get("identified") is not None:
                    identified.setdefault((p["body"], p["name"]), p["identified"])
    for name, diff in r["torques"].get("parameter_differences", {}).items():
        if not diff:
            continue
        rows = [[esc(d["body"]), esc(d["parameter"]), num(d["model"]), num(d["reference"]),
                 num(d["rel_difference"]), num(identified.get((d["body"], d["identification_name"])))]
                for d in diff]
        out.append(f"<h3>Parameters of {esc(name)} that differ from the robot's</h3>"
                   + table(["body", "parameter", name, "robot (reference)", "rel difference", "identified"], rows))
    return "".join(out)


def _interval(ci: list | None) -> Markup:
    return Markup("[{}, {}]").format(num(ci[0]), num(ci[1])) if ci else DASH


def identification_methods(r: dict) -> str:
    rows, tables = [], []
    for name, m in r["identification_methods"].items():
        if m.get("skipped"):
            rows.append([esc(name), code(m["plugin"]), Markup("<i>skipped</i>"), *([DASH] * 4), esc(m["skipped"])])
            continue
        b, v = m.get("base_parameters"), m.get("validation")
        rows.append([esc(name), code(m["plugin"]), num(b["count"]) if b else DASH,
                     num(b["max_rel_error"]) if b else DASH, esc(v["scenario"]) if v else DASH,
                     num(v["max_rel_error"]) if v else DASH, esc(v["max_rel_joint"]) if v else DASH,
                     num(v["rms_rel_error"]) if v else DASH])
        if b and b.get("base"):
            tables.append(
                f"<h3>{esc(name)}: base parameters</h3><p>{esc(b['rel_error_definition'])}; {esc(b['uncertainty'])}"
                + (f"; the 95 % intervals hold the true value for {num(b['coverage_ci95'])} of them"
                   if b.get("coverage_ci95") is not None else "") + ".</p>"
                + table(["base parameter", "true", "identified", "rel error", "std", "95 % interval"],
                        [[esc(p["expression"]), num(p["true"]), num(p["identified"]), num(p["rel_error"]),
                          num(p["std"]) if p["std"] is not None else DASH, _interval(p["ci95"])]
                         for p in b["base"]],
                        "wrap"))
    return section(
        "identification_methods",
        "Identification methods under test",
        "<p>Each method is fitted on the measured joint data of this run (q, q', q'', tau) and judged on the "
        "base parameters the torques determine (against the robot's, where the method reports parameters) and on "
        "the torques it predicts for a validation trajectory it never saw, relative to each joint's load L_J.</p>"
        + table(["method", "plugin", "base parameters", "largest rel error", "validation", "largest rel error",
                 "at joint", "RMS rel error"], rows) + "".join(tables),
    )


def identification_sweep_page(r: dict) -> str:
    """sweep.html of the core's sweep (harness/runner/sweep.py): the estimators and the identification methods."""
    title = f"{r['scenario']}: identification over {r['trials']} trials"
    return page(title, title, (estimator_comparison(r) if "estimators" in r else "")
                + (method_sweep(r) if "identification_methods" in r else ""))


def method_sweep(r: dict) -> str:
    """`harness sweep` of the identification methods (harness/stages/identification.py, sweep_methods)."""
    parts = []
    for name, m in r["identification_methods"].items():
        if m.get("skipped"):
            parts.append(f"<h3>{esc(name)} (<code>{esc(m['plugin'])}</code>)</h3><p>Skipped: {esc(m['skipped'])}</p>")
            continue
        b = m["base_parameters"]
        head = (f"<h3>{esc(name)} (<code>{esc(m['plugin'])}</code>), {m['trials']} trials</h3>"
                + (f"<p>Validation: largest relative torque error {num(m['validation_rel_error_mean'])} on average, "
                   f"{num(m['validation_rel_error_max'])} at most.</p>" if m["validation_rel_error_mean"] is not None
                   else ""))
        if b is None:
            parts.append(head + "<p>The fitted model reports no parameters.</p>")
            continue
        cov = ("no intervals: the method gives no covariance" if b["coverage_min"] is None else
               f"coverage of the 95 % intervals {num(b['coverage_min'])} to {num(b['coverage_max'])} (median "
               f"{num(b['coverage_median'])}), {b['coverage_outside_band']} of {b['count']} outside "
               f"{num(b['coverage_band'][0])} to {num(b['coverage_band'][1])}")
        parts.append(head + f"<p>{esc(b['definition'])}. Largest |bias| {num(b['max_bias_in_sd'])} sd (median "
                     f"{num(b['median_bias_in_sd'])}), {b['significant_biases']} of {b['count']} beyond 3 standard "
                     f"errors; {cov}.</p>"
                     + table(["base parameter", "true", "bias", "spread", "|bias| / sd", "RMS rel error",
                              "coverage"],
                             [[esc(p["expression"]), num(p["true"]), num(p["bias"]), num(p["spread"]),
                               num(p["bias_in_sd"]) + (" (beyond 3 s.e.)" if p["significant"] else ""),
                               num(p["rms_rel_error"]), num(p["coverage"]) if p["coverage"] is not None else DASH]
                              for p in b["base"]], "wrap"))
    return section("identification_methods", "Identification methods under measurement noise", "".join(parts))


def how(r: dict) -> str:
    run = r["run"]
    timings = run.get("timings") or {}
    total = sum(timings.values())
    stages = table(["stage", "seconds", "share"], [[esc(k), f"{v:.2f}", f"{100 * v / total:.1f} %" if total else ""]
                                                  for k, v in timings.items()]) if timings else ""
    versions = table(["package", "version"], [[esc(k), esc(v)] for k, v in run["versions"].items()])
    if "data" in r:
        source = "From the measured log of the section above, conditioned as stated there."
    else:
        sim = r["scenario"]["simulation"]
        source = (f"MuJoCo {esc(r['recording']['engine_version'])}, integrator {esc(sim['integrator'])}, time step "
                  f"{num(sim['timestep'])} s, computed-torque drive with bandwidth "
                  f"{num(sim['tracking_bandwidth'])} rad/s.")
    return section(
        "how",
        "How the run was made",
        (
            f"<p>Run at {esc(run['time'])} (UTC). {source} Scenario file <code>{esc(r['scenario']['file'])}</code>:</p>"
            f"<pre>{esc(run['scenario_text'])}</pre>"
            + (("<h3>Time spent in each stage</h3>" + stages) if stages else "")
            + versions
        ),
    )


def torque_identification(r: dict) -> str:
    t = r["torque_identification"]
    rows = [[esc(b["expression"]), num(b["true"]), num(b["identified"]), num(b["rel_error"]), num(b["std"]),
             identifiability(b)] for b in t["base"]]
    weak = (f" Weakly identifiable ({esc(t['weak_definition'])}): {len(t['weakly_identifiable'])}, largest error "
            f"{num(t['max_rel_error_weak'])}." if t["weakly_identifiable"] else "")
    v = t["validation"]
    val = (
        (
            f"Predicted torques of the validation trajectory <code>{esc(v['scenario'])}</code>: largest error "
            f"{num(v['max_rel_error'])}, RMS {num(v['rms_rel_error'])} ({esc(v['definition'])})."
        )
        if v
        else ""
    )
    c = t.get("consistent")  # a floating robot's consistent fit (harness/stages/floating_fit.py)
    if c:
        val += (f" The consistent fit ({esc(c['method'])}; {esc(c['status'])}): training residual "
                f"{num(c['training_relative_residual'])}, the validation trajectory's largest error "
                f"{num(c['validation']['max_rel_error'])}, links not physical: "
                f"{esc(', '.join(c['inconsistent_links']) or 'none')}.")
    heading = {None: "Identification from joint torques alone",
               "base": "Identification of the floating robot from the world's wrench on its base alone",
               "all": "Identification of the floating robot from the wrench on its base and its joint torques"}
    return section(
        "torque_identification",
        heading[t.get("rows")],
        (
            f"<p>{esc(t['method'])}. {t['base_parameters']} base parameters out of {t['parameters']}; condition number "
            f"of the scaled base regressor {num(t['condition_number'])}; largest error {num(t['max_rel_error'])} "
            f"({esc(t['rel_error_definition'])}).{weak} {esc(t['uncertainty'])}. {val}</p>"
            + table(["base parameter", "true", "identified", "rel error", "std", "identifiable"], rows, "wrap")
        ),
    )


def excitation(r: dict) -> str:
    e = r["excitation"]
    used = ", ".join(f"{k} {num(v)}" for k, v in e["largest_fraction_of_limits"].items())
    shrunk = e["amplitude_shrunk_by"]
    limits = table(["joint", "position [rad or m]", "velocity", "acceleration", "effort"],
                   [[esc(j), esc(", ".join(num(x) for x in v["position"])), num(v["velocity"]),
                     num(v["acceleration"]), num(v["effort"])] for j, v in e["limits"].items()])
    return section(
        "excitation",
        "Optimised excitation",
        (
            f"<p>{e['harmonics']}-harmonic Fourier series per joint, base frequency {num(e['base_frequency'])} rad/s, "
            f"{e['evaluations']} evaluations of the objective ({esc(e['objective'])}). Condition number "
            f"{num(e['initial_condition_number'])} at the start, {num(e['optimised_condition_number'])} optimised. "
            f"Largest fraction of each limit used (checked on {esc(str(e.get('dense_samples', '')))} samples a "
            f"period): {esc(used)}{'' if shrunk == 1 else f'; amplitude scaled by {num(shrunk)} to hold them'}.</p>"
            "<h3>Limits (none where empty)</h3>" + limits
        ),
    )


def payload(results: dict) -> str:
    """The payload identified from the runs with and without it (harness/stages/payload.py)."""
    p = results["payload"]
    rows = [[esc(x["name"]), num(x["true"]), num(x["identified"]), num(x["rel_error"]), num(x["std"]),
             "yes" if x["within_ci95"] else "no"] for x in p["parameters"]]
    return section("payload", "Payload", f"<p>{esc(p['method'])}; on {esc(p['body'])} (joint {esc(p['joint'])}). "
                   f"Largest relative error {num(p['max_rel_error'])} ({esc(p['rel_error_definition'])}).</p>"
                   + table(["parameter", "true", "identified", "rel error", "std", "in 95 % interval"], rows))
