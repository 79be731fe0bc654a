"""The report's sections, top to bottom, one function each: results (and the recording) in,
an HTML fragment out. Numbers are formatted here; figures come from report.plots."""

from __future__ import annotations

import numpy as np
from markupsafe import Markup

from harness.base.series import TimeSeries
from harness.report import plots
from harness.report.html import DASH, code, esc, figure, mark, num, page, section, table
from harness.runner.gates import summary_line


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
        ": " + ", ".join(esc(g["name"]) for g in failing) if failing else "")
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
        badge + f"<p>{summary}</p>" + (f"<ul>{''.join(answers)}</ul>" if answers else "")
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
                joints),
    )


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


def data(r: dict, log) -> str:
    """A measured log: where it came from, each conditioning step, and its signals."""
    d = r["data"]
    c = d["conditioning"]
    src = r["scenario"]["data"]
    def described(step: dict) -> str:
        return ", ".join(f"{k.replace('_', ' ')} {num(v) if isinstance(v, float) else v}"
                         for k, v in step.items() if k != "step" and v not in ({}, None))

    steps = "".join(f"<li><b>{esc(step['step'])}</b>: {esc(described(step))}</li>" for step in c["steps"])
    warnings = "".join(f'<p class="warn">{esc(w)}</p>' for w in c["warnings"])
    val = c.get("validation")
    split = (f"<p>Training: t &lt; {num(val['t_split'])} s ({val['training_samples']} samples); validation, never "
             f"seen by the fit: the rest ({val['validation_samples']} samples).</p>") if val else ""
    t = log.t
    figs = [figure(plots.lines(t, {j: log.q[:, k] for k, j in enumerate(log.joints)}, "q [rad]", "Joint positions"),
                   "Conditioned joint positions."),
            figure(plots.lines(t, {j: log.tau[:, k] for k, j in enumerate(log.joints)}, "tau [N m]",
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
    extra = ""
    lags = li.get("delays") or {}
    if lags.get("estimated"):
        extra += ("<h3>Torque channels' delays behind the encoders</h3>"
                  f"<p>{esc(lags['definition'])}; {esc(lags['found_definition'])}. "
                  f"{'Corrected' if lags['corrected'] else 'Not corrected'}.</p>"
                  + table(["joint", "delay [ms]", "found", "residual at it", "at zero delay"],
                          [[esc(j), num(v["delay_s"] * 1e3), mark(v["found"], "yes" if v["found"] else "no"),
                            num(v["residual"]), num(v["residual_at_zero"])] for j, v in lags["per_joint"].items()]))
    pred = li.get("prediction") or {}
    if pred.get("models"):
        hs = list(next(iter(pred["models"].values())))
        extra += ("<h3>Forward simulation under the measured torques</h3>"
                  f"<p>{esc(pred['definition'])}. RMS position error [rad or m] per horizon:</p>"
                  + table(["model", *hs], [[esc(m), *(num(v[h]["q_rms"]) for h in hs)]
                                           for m, v in pred["models"].items()]))
    constants = li.get("torque_constants")
    if constants:
        extra += ("<h3>Torque constants (motor currents)</h3>"
                  f"<p>{esc(constants['definition'])}; the scale fixed by the {esc(constants['fixed_by'])}.</p>"
                  + table(["joint", "nominal [N m/A]", "factor", "identified [N m/A]", "factor's std"],
                          [[esc(j), num(v["nominal"]), num(v["factor"]), num(v["identified"]), num(v["factor_std"])]
                           for j, v in constants["per_joint"].items()]))
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
        links += f"<p>Plausibility: {esc(pl['definition'])}.</p>" + table(
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
                       for m in ("consistent", "refined") if m in pm]))
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
        if m.get("skipped"):
            rows.append([esc(name), code(m["plugin"]), Markup("<i>skipped</i>"), *([DASH] * (len(header) - 4)),
                         esc(m["skipped"])])
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


def identification_methods(r: dict) -> str:
    if "data" in r:  # a measured log's run: the table of harness/stages/log_methods.py
        return log_methods(r)
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
    stages = table(["stage", "seconds"], [[esc(k), f"{v:.2f}"] for k, v in timings.items()]) if timings else ""
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
    return section(
        "torque_identification",
        "Identification from joint torques alone",
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
