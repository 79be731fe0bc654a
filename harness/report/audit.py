"""audit.html: `harness audit`'s table (harness/runner/audit.py), a row per robot in the order they
were audited: robot, verdict, then the figures."""

from __future__ import annotations

from markupsafe import Markup

from harness.report.html import DASH, esc, mark, num, page, table


def _identified(ident: dict | None):
    if ident is None:
        return DASH
    if "failed" in ident:
        return esc(ident["failed"])
    e = ident["validation_rel_error"]
    return esc(f"least squares {e['least squares']:.2g}, consistent {e['consistent']:.2g} ({ident['seconds']:.1f} s)")


def _floating(figures: dict | None):
    if not figures:
        return DASH
    f = figures
    return esc(f"{num(f['floating_engines'])}, {num(f['floating_mass_matrix'])}; "
               f"{num(f.get('floating_vs_pinocchio_parser'))}; {num(f.get('floating_vs_mujoco_file'))}")


def render_audit(document: dict) -> str:
    t = document["totals"]
    rows = []
    for r in document["robots"]:
        verdict = (mark(r["verdict"] == "agrees", r["verdict"]) if r["verdict"] in ("agrees", "disagrees")
                   else Markup('<span class="warn">{}</span>').format(r["verdict"]))
        rank = r["pinocchio_regressor_rank"]
        base = DASH if r["base_parameters"] is None else f"{r['base_parameters']} / {'-' if rank is None else rank}"
        rows.append([esc(r["robot"]), verdict, DASH if r["dof"] is None else str(r["dof"]), esc(r["root"] or "-"),
                     num(r["torques_vs_pinocchio"]), num(r["mass_matrix_vs_pinocchio"]), num(r["torques_vs_mujoco"]),
                     num(r.get("drives_vs_pinocchio")),
                     DASH if not r.get("couplings") else f"{r['couplings']}: {num(r['couplings_vs_pinocchio'])}",
                     _floating(r.get("floating")),
                     num(r["torques_urdf_vs_mjcf"] if r["torques_urdf_vs_mjcf"] is not None
                         else r.get("torques_vs_mujoco_file")) if r["mjcf"] in ("read", "the file itself")
                     else esc(r["mjcf"] or "-"),
                     esc(base), esc("; ".join(r["invalid_bodies"]) or "-"), _identified(r.get("identified")),
                     esc(r["reason"] or "")])
    head = (f"<p>{t['robots']} robots: {t['read']} read, {t['agree']} agree, {t['disagree']} disagree, "
            f"{t['not_compared']} not compared (a reference parser cannot represent the file: the last column says "
            f"which and why), {t['refused']} refused by the harness's reader; MuJoCo's MJCF conversion read back for "
            f"{t['mjcf_read']}. A robot agrees when each figure is within {t['tolerance']:g}: the largest error over "
            "each joint's largest |torque| "
            "(the mass matrix: over its largest entry) at 100 random states within the limits, rigid bodies only, "
            "and with the model file's drives or friction (MuJoCo's bench against Pinocchio's RNEA with their law); "
            "base parameters: the harness's structural count / the rank of Pinocchio's own regressor. "
            f"{t['seconds']:.1f} s.</p>")
    body = head + table(["robot", "verdict", "dof", "root", "torques vs Pinocchio's parser", "mass matrix",
                         "torques vs MuJoCo", "with drives, MuJoCo vs Pinocchio",
                         "couplings: through G vs Pinocchio's mimic joints",
                         "floating base, free: MuJoCo vs Pinocchio (torques, mass matrix); vs Pinocchio's parser; "
                         "vs MuJoCo's file",
                         "vs MuJoCo's reading of the file (URDF: its MJCF conversion)",
                         "base parameters", "bodies not physical",
                         "identified from its bench log (held out)", "why"], rows)
    return page("harness audit", "Robot descriptions audited", body, wide=True)
