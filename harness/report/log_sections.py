"""The report's sections of a run on a measured log: the log and its conditioning, the identification
from it, the field's methods beside it and the refinement by simulation. Results in, an HTML fragment out."""

from __future__ import annotations

import numpy as np
from markupsafe import Markup

from harness.report import plots
from harness.report.html import DASH, code, esc, figure, mark, num, section, table
from harness.report.sections import identifiability


def data(r: dict, log) -> str:
    """A measured log: where it came from, each conditioning step, and its signals."""
    d = r["data"]
    c = d["conditioning"]
    src = r["scenario"]["data"]
    def value(v) -> str:
        if isinstance(v, float):
            return num(v)
        if isinstance(v, list | tuple):
            return "[" + ", ".join(value(x) for x in v) + "]"
        if isinstance(v, dict):
            return "(" + "; ".join(f"{k.replace('_', ' ')} {value(x)}" for k, x in v.items()) + ")"
        return str(v)

    def described(step: dict) -> str:
        return ", ".join(f"{k.replace('_', ' ')} {value(v)}" for k, v in step.items()
                         if k != "step" and v not in ({}, None))

    steps = "".join(f"<li><b>{esc(step['step'])}</b>: {esc(described(step))}</li>" for step in c["steps"])
    warnings = "".join(f'<p class="warn">{esc(w)}</p>' for w in c["warnings"])
    val = c.get("validation")
    split = (f"<p>Training: t &lt; {num(val['t_split'])} s ({val['training_samples']} samples); validation, never "
             f"seen by the fit: the rest ({val['validation_samples']} samples).</p>") if val else ""
    passive = c.get("passive_joints")  # a closed chain's: from its loops, no torque of their own
    if passive:
        split += f"<p>Passive joints {esc(', '.join(passive['joints']))}: {esc(passive['from'])}.</p>"
    unread = set(src.get("unmeasured") or ()) | set(passive["joints"] if passive else ())  # no channel of theirs
    if src.get("unmeasured"):
        split += (f"<p>Unmeasured joints {esc(', '.join(src['unmeasured']))}: no torque channel read; their motion "
                  "kept.</p>")
    t = log.t
    figs = [figure(plots.lines(t, {j: log.q[:, k] for k, j in enumerate(log.joints)}, "q [rad]", "Joint positions"),
                   "Conditioned joint positions."),
            figure(plots.lines(t, {j: log.tau[:, k] for k, j in enumerate(log.joints) if j not in unread}, "tau [N m]",
                               "Measured joint torques"), "Conditioned (filtered) joint torques."),
            figure(plots.lines(t, {j: log.qdd[:, k] for k, j in enumerate(log.joints)}, "q'' [rad/s^2]",
                               "Joint accelerations"), "Accelerations by differences of the filtered velocities.")]
    return section(
        "data", "Measured log",
        f"<p><code>{esc(src['file'])}</code>, sha256 <code>{esc(c['sha256'])}</code>; {d['rows']} conditioned "
        f"samples from t = {num(d['t_start'])} s to {num(d['t_end'])} s.</p><ol>{steps}</ol>{warnings}{split}"
        + "".join(figs))


def log_identification(r: dict, log) -> str:
    li = r["log_identification"]
    models = list(li["validation_rel_error"])
    span = li["series"]["span"]
    truth = li.get("truth")
    if truth:
        headline = table(["model", f"{span}: against the measured torques", "against the truth's torques"],
                         [[esc(m), num(li["validation_rel_error"][m]), num(truth["validation_rel_error"][m])]
                          for m in models] + [[esc("the measured torques themselves"), DASH,
                                               num(truth["validation_rel_error"]["measured"])]])
        headline += f"<p>The truth: {esc(truth['model'])}; {esc(truth['definition'])}.</p>"
    else:
        headline = table(["model", f"{span}: ||tau_pred - tau|| / ||tau||"],
                         [[esc(m), num(li["validation_rel_error"][m])] for m in models])
    floor = li.get("validation_floor")
    if floor:
        headline += (f"<p>The model class's floor on the validation span: {num(floor['rel_error'])}, "
                     f"{esc(floor['definition'])}.</p>")
    if li.get("validation_cannot_see"):
        headline += f"<p><strong>What this figure cannot see</strong>: {esc(li['validation_cannot_see'])}.</p>"
    extra = gravity(li.get("gravity")) + delays(li.get("delays") or {})
    pred = li.get("prediction") or {}
    if pred.get("models"):
        hs = list(next(iter(pred["models"].values())))
        extra += ("<h3>Forward simulation under the measured torques</h3>"
                  f"<p>{esc(pred['definition'])}. RMS position error [rad or m] per horizon:</p>"
                  + table(["model", *hs], [[esc(m), *(num(v[h]["q_rms"]) for h in hs)]
                                           for m, v in pred["models"].items()]))
    elif pred.get("note"):
        extra += f"<h3>Forward simulation under the measured torques</h3><p>{esc(pred['note'])}.</p>"
    extra += torque_constants(li.get("torque_constants"))
    joints = list(li["errors"][span][models[0]]["per_joint"])
    per_joint = table(["joint", *(f"{m}: RMS [N m] / relative" for m in models)],
                      [[esc(j), *(f"{num(li['errors'][span][m]['per_joint'][j]['rms_error'])} / "
                                  f"{num(li['errors'][span][m]['per_joint'][j]['rel_error'])}" for m in models)]
                       for j in joints])
    s = li["series"]
    t = np.array(s["t"])
    panels = [(j, {"measured": np.array(s["measured"][j]), "consistent": np.array(s["consistent"][j]),
                   "model as given": np.array(s["model as given"][j])}, None) for j in joints]
    fig = figure(plots.grid(t, panels, "tau [N m]"),
                 f"Measured torques against those the identified (physically consistent) model and the model as "
                 f"given predict, along the {span} span.")
    ls = li["least_squares"]
    con = li["consistent"]
    links = table(["link", "m [kg]", "principal moments about the centre of mass", "triangle slack",
                   "min eig J", "consistent"],
                  [[esc(k), num(v["mass"]), esc(", ".join(num(x) for x in v.get("principal_moments", []))),
                    num(v.get("triangle_slack")), num(v["min_eig_pseudo_inertia"]),
                    mark(v["consistent"], "yes" if v["consistent"] else "no")]
                   for k, v in con["links"].items()])
    pl = li.get("plausibility")
    if pl:
        links += (f"<p>Plausibility: {esc(pl['definition'])}. A link is physically consistent (the table above, and "
                  "the gate on <code>log_identification.consistent.inconsistent_links</code>) when some rigid body has "
                  "its parameters: its pseudo-inertia positive definite, by at least the fit's margin. That says "
                  "nothing of whether the body is this robot's: a link on the margin is consistent because the fit "
                  "holds it at that boundary, where the data alone would take it past physical (the data do not "
                  "determine it, or the model's kinematics or friction law are not the robot's), and a link far from "
                  "the model's is consistent with a mass or inertia the model does not expect. Both are findings of "
                  "the data against the model, not failures of consistency.</p>") + table(
            ["link (by its joint)", "mass ratio", "inertia ratio", "plausible", "on the margin"],
            [[esc(j), num(v["mass"]), num(v["inertia_trace"]),
              mark(j not in pl["implausible"], "no" if j in pl["implausible"] else "yes"),
              mark(j not in pl["on_margin"], "yes" if j in pl["on_margin"] else "no")]
             for j, v in pl["ratios"].items()])
    keys = [k for k in next(iter(con["friction"].values())) if k != "family"]
    used = [k for k in keys if any(v[k] for v in con["friction"].values())]  # the families' zero terms left out
    fric = table(["joint", "family", *used], [[esc(j), esc(v["family"]), *(num(v[k]) for k in used)]
                                              for j, v in con["friction"].items()])
    base = table(["base parameter", "model", "identified", "std", "std [%]", "identifiable"],
                 [[esc(b["expression"]), num(b["model"]), num(b["identified"]), num(b["std"]),
                   num(b["rel_std_percent"]), identifiability(b)] for b in ls["base"]], "wrap")
    costs = ", ".join(f"{k} {num(v)}" for k, v in li["consistent_costs"].items())
    return section(
        "log_identification", "Identification from the log",
        f"<p>{esc(li['method'])}. Relative error: {esc(li['rel_error_definition'])}.</p>" + headline + fig
        + "<h3>Per joint</h3>" + per_joint + _friction_law(li["friction_law"]) + extra
        + f"<h3>Physically consistent parameters</h3><p>Solver: {_solver(con)}; what consistency "
        f"costs in relative torque error (consistent minus least squares): {esc(costs)}. Exported: "
        f"{esc(', '.join(li['export']))}.</p>" + links + fric
        + f"<h3>Least squares: {ls['base_parameters']} base parameters of {ls['parameters']}</h3>"
        + f"<p>Condition number of the scaled base regressor {num(ls['condition_number'])}.</p>" + base)


def refinement(r: dict) -> str:
    """The refinement by simulation (harness/stages/refinement.py): what it adjusted, the candidates it
    made, the model kept, how that does on the validation span, and what it cost beside the methods
    that report their own rollouts."""
    rf = r["refinement"]
    head = f"<p>{esc(rf['definition'])}.</p>"
    if "note" in rf:
        return section("refinement", "Refinement by simulation", head + f"<p>{esc(rf['note'])}.</p>")
    kept = rf["kept"]
    head += f"<p><b>Kept: {esc(kept)}.</b> Why: {esc(rf['reason'])}.</p>"
    params = table(["quantity", "consistent fit", "kept"],
                   [[esc(k), num(v["consistent"]), num(v["refined"])] for k, v in rf["parameters"].items()])
    cands = table(["candidate", "training: prediction residual (RMS)", "training: torque error", "kept"],
                  [[esc(k), num(v["prediction_cost"]), num(v["torque_rel_error"]), mark(k == kept, "kept") if k == kept
                    else ""] for k, v in rf["candidates"].items()])
    v = rf["validation"]
    pm = v["prediction"].get("models", {})
    hs = list(next(iter(pm.values()))) if pm else []
    judged = (f"<h3>On the {esc(v['span'])} span, which the refinement never reads</h3>"
              + table(["model", "torque error", *(f"q RMS at {h[1:]}" for h in hs)],
                      [[esc(m), num(v["torque_rel_error"][m]), *(num(pm[m][h]["q_rms"]) for h in hs)]
                       for m in ("consistent", "refined")])
              + (f"<p>{esc(v['prediction']['note'])}.</p>" if not pm and v["prediction"].get("note") else ""))
    cost_rows = [[f"pass {k + 1}", num(p["rollouts"]), num(p["steps"]), num(p["evaluations"]), num(p["seconds"]),
                  esc(p["optimiser"])] for k, p in enumerate(rf["passes"])]
    cost_rows += [[esc(f"{name} ({m['plugin']})"), num(m["rollouts"]), DASH, DASH, num(m["seconds"]), ""]
                  for name, m in rf.get("beside", {}).items()]
    cost = ("<h3>What it cost</h3><p>Rollouts of the refinement (RK4, 1 ms) beside those of the identification "
            "methods that report theirs (each from its own start).</p>"
            + table(["run", "rollouts", "steps", "batches", "seconds", "optimiser"], cost_rows))
    return section("refinement", "Refinement by simulation", head + params + cands + judged + cost)


MODELS_LAW = "model's law"  # the key of the model's own law in friction_law.held_out_rel_error


def _friction_law(law: dict) -> str:
    """Each joint's friction law: chosen by the data (every family's held-out figure beside the
    choice) or the model's own."""
    head = f"<h3>Friction law</h3><p>{esc(law['law'])}. {esc(law['definition'])}.</p>"
    if not law["chosen"]:
        return head + table(["joint", "family", "coulomb_velocity"],
                            [[esc(j), esc(f), num(law["coulomb_velocity"][j])] for j, f in law["families"].items()])
    held = law["held_out_rel_error"]
    head += (f"<p>Held-out error: the model's own law {num(held[MODELS_LAW])}, the chosen laws "
             f"{num(held['chosen'])}. Per joint, each family's at its best v_c (the chosen in bold):</p>")
    families = list(dict.fromkeys(f for s in law["per_joint"].values() for f in s))

    def cell(j: str, f: str, score: dict) -> Markup:
        text = Markup("{} ({})").format(num(score["held_out_rel_error"]), num(score["coulomb_velocity"]))
        return Markup("<b>{}</b>").format(text) if f == law["families"][j] else text

    return head + table(["joint", "chosen", "v_c", *(f"{f}: held-out (v_c)" for f in families)],
                        [[esc(j), esc(law["families"][j]), num(law["coulomb_velocity"][j]),
                          *(cell(j, f, s[f]) if f in s else DASH for f in families)]
                         for j, s in law["per_joint"].items()])


def _solver(con: dict) -> str:
    """The consistent fit's solver and status, marked where a fallback gave the fit."""
    text = f"{con.get('solver', 'CLARABEL')} ({con['solver_status']})"
    if con.get("fallback", 0) == 0:
        return esc(text)
    return mark(False, f"{text}, fallback {con['fallback']}: " + "; ".join(con.get("solver_attempts", [])))


def _physical_cell(ph: dict) -> Markup:
    links, negative = ph["inconsistent_links"], ph["negative_count"]
    if links is None and negative is None:
        return DASH
    parts = []
    if links is not None:
        parts.append(f"{links} link(s) not physical" if links else "links physical")
    if negative:
        parts.append(f"negative: {', '.join(ph['negative'])}")
    elif negative is not None:
        parts.append("no negative drive terms")
    return mark(not links and not negative, "; ".join(parts))


def log_methods(r: dict) -> str:
    """The log's method table (harness/stages/log_methods.py): the harness's fits and every method side by side."""
    rows_in = r["identification_methods"]
    bench = any(m.get("truth") for m in rows_in.values())
    header = ["method", "plugin", "held-out error", "training error",
              *(["vs truth's torques", "base parameters vs truth: median (max) rel error"] if bench else []),
              "physical validity", "friction and rotor inertia", "seconds", "notes"]
    rows = []
    for name, m in rows_in.items():
        if m.get("skipped") or m.get("failed"):
            word = "skipped" if m.get("skipped") else "failed"
            rows.append([esc(name), code(m["plugin"]), Markup(f"<i>{word}</i>"), *([DASH] * (len(header) - 4)),
                         esc(m[word])])
            continue
        b = m.get("base_parameters")
        friction = m.get("friction")
        rows.append([esc(name), code(m["plugin"]), num(m.get("validation_rel_error")), num(m.get("training_rel_error")),
                     *([num(m["truth"]["validation_rel_error"]) if m.get("truth") else DASH,
                        Markup("{} ({}){}").format(num(b["median_rel_error"]), num(b["max_rel_error"]),
                                                   ", with friction" if b["with_friction"] else "") if b else DASH]
                       if bench else []),
                     _physical_cell(m["physical"]),
                     esc("identified (armature, viscous, Coulomb, offset)") if friction else
                     esc("in the base parameters" if name == "harness_least_squares" else "not reported"),
                     num(m["seconds"]) if m.get("seconds") is not None else DASH,
                     esc("; ".join(m.get("notes") or ()))])
    return section(
        "identification_methods", "Identification methods on the log",
        "<p>Every method is fitted on the training span exactly as the harness's own fit read it (the same "
        "conditioning and delay correction) and predicts the validation span, which no fit sees: held-out error "
        "||tau_pred - tau||_F / ||tau||_F. On a bench log the predicted torques are also compared with those of the "
        "robot that made the log, and reported parameters with its base parameters. Physical validity: links whose "
        "pseudo-inertia is not positive semidefinite, and negative rotor inertia, viscous or Coulomb coefficients. "
        "Seconds: each method's fit; the harness's steps are timed in 'How the run was made'.</p>"
        + table(header, rows, "wrap"))


def gravity(g: dict | None) -> str:
    """Gravity's direction in the base's axes as the log's torques give it (results.json's
    `log_identification.gravity`), where it was looked for; else nothing."""
    if not g or not g.get("folds_rel_error"):
        return ""
    return ("<h3>Gravity's direction in the base's axes</h3>"
            f"<p>{esc(g['definition'])}. {'Taken' if g['chosen'] else 'Not taken'}: {esc(g['reason'])}.</p>"
            + table(["gravity", "m/s^2, base axes", "folds' held-out error", "training error"],
                    [[esc(name), _vector(g[name]), num(g["folds_rel_error"][name]), num(g["training_rel_error"][name])]
                     for name in ("declared", "identified")]
                    + [[esc("used"), _vector(g["used"]), DASH, DASH]]))


def _vector(v) -> str:
    return "[" + ", ".join(str(num(x)) for x in v) + "]"


def delays(lags: dict) -> str:
    """The torque channels' delays behind the encoders (results.json's `delays` of a log's identification, an
    arm's or a floating base's): a table where they were estimated, else nothing."""
    if not lags.get("estimated"):
        return ""
    return ("<h3>Torque channels' delays behind the encoders</h3>"
            f"<p>{esc(lags['definition'])}; {esc(lags['found_definition'])}. "
            f"{'Corrected' if lags['corrected'] else 'Not corrected'}.</p>"
            + table(["joint", "delay [ms]", "found", "residual at it", "at zero delay"],
                    [[esc(j), num(v["delay_s"] * 1e3), mark(v["found"], "yes" if v["found"] else "no"),
                      num(v["residual"]), num(v["residual_at_zero"])] for j, v in lags["per_joint"].items()]))


def torque_constants(constants: dict | None) -> str:
    """The motor currents' constants identified (an arm's log or a floating base's), or nothing."""
    if not constants:
        return ""
    return ("<h3>Torque constants (motor currents)</h3>"
            f"<p>{esc(constants['definition'])}. The common scale is fixed by "
            f"{esc(constants['common_scale']['fixed_by'])}.</p>"
            + table(["joint", "nominal [N m/A]", "factor", "identified [N m/A]", "95 % interval [N m/A]",
                     "factor's std"],
                    [[esc(j), num(v["nominal"]), num(v["factor"]), num(v["identified"]),
                      f"{num(v['ci95'][0])} to {num(v['ci95'][1])}", num(v["factor_std"])]
                     for j, v in constants["per_joint"].items()]))


def _floating_prediction(pred) -> str:
    """A floating base's forward simulation under the measured torques and contact wrenches: per model and horizon,
    the base's RMS position and angle errors and the joints' RMS; its note where none was made (an older run's
    results hold a sentence)."""
    head = "<h3>Forward simulation under the measured torques and contact wrenches</h3>"
    if isinstance(pred, str):
        return f"{head}<p>{esc(pred)}.</p>"
    if not pred.get("models"):
        return f"{head}<p>{esc(pred.get('note', ''))}.</p>"
    hs = list(next(iter(pred["models"].values())))
    rows = [[esc(m), *(f"{num(v[h]['base_position_rms_m'])} m, {num(v[h]['base_angle_rms_rad'])} rad, "
                       f"{num(v[h]['q_rms'])}" for h in hs)] for m, v in pred["models"].items()]
    return (f"{head}<p>{esc(pred['definition'])}. Per horizon: the base's RMS position and angle errors, the joints' "
            "RMS [rad or m]:</p>" + table(["model", *hs], rows))


def _estimator(e: dict) -> str:
    """The floating log's estimator and each read row's noise as the fit's residual shows it."""
    return (f"<p>Estimator: {esc(e['name'])} ({esc(e['definition'])}).</p>"
            + table(["row", "residual (standard deviation)", "weight"],
                    [[esc(r), num(v["residual_std"]), num(v["weight"])] for r, v in e["rows"].items()]))


def floating_log(r: dict, log) -> str:
    """A floating base's log (harness/stages/floating_log.py): what each model predicts on the judged span."""
    f = r["floating_log"]
    read = ("the contacts' wrenches alone (no joint torque)" if f["rows"] == "base"
            else "the contacts' wrenches and the joints' torques")
    rows = []
    for name, judged in f["judged"].items():
        measured, truth = judged["measured"], judged.get("truth")
        rows.append([esc(name), num(measured["max_rel_error"]), num(measured["rms_rel_error"]),
                     esc(measured["max_rel_row"]),
                     *((num(truth[k]) for k in ("max_rel_error", "rms_rel_error", "rms_rel_error_base",
                                                "rms_rel_error_joints")) if truth else (DASH,) * 4)])
    start = f["start"]
    c = f.get("consistent")
    consistent = (f"<p>The consistent fit ({esc(c['status'])}, {esc(c['solver'])}): training residual "
                  f"{num(c['training_relative_residual'])}; links not physical: "
                  f"{esc(', '.join(c['inconsistent_links']) or 'none')}.</p>") if c else ""
    body = (f"<p>The floating robot identified from {read} on the training span ({f['base_parameters']} base "
            f"parameters of {f['parameters']}, condition number {num(f['condition_number'])}), judged on the "
            f"{esc(f['span'])} span; contacts {esc(', '.join(f['contacts']) or 'none')}. The start check: "
            f"{start['findings']} finding(s) ({esc(start['definition'])}; limit {num(start['limit'])}). Unseen by "
            f"these rows: {esc(', '.join(f['unseen']) or 'nothing')}.</p>"
            + table(["model", "against the log: largest", "RMS", "where", "against the truth: largest", "RMS",
                     "RMS, base rows", "RMS, motors"], rows)
            + f"<p>{esc(f['definition'])}.</p>" + consistent + _floating_prediction(f["prediction"])
            + _estimator(f["estimator"])
            + torque_constants(f.get("torque_constants")) + delays(f["delays"]))
    return section("floating_log", "A floating base's log", body)
