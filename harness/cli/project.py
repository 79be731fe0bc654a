"""`harness audit`, `harness list` and `harness init`: a collection of robots checked, what is
installed listed, a project of one's own started."""

from __future__ import annotations

import argparse
import json
import shutil
import tempfile
from contextlib import closing
from pathlib import Path

from harness.base.tomlio import InputError, read_toml
from harness.cli.common import EXIT_GATE_FAILED, EXIT_OK, write_atomically


def cmd_audit(args: argparse.Namespace) -> int:
    import time

    from harness.base.progress import Progress
    from harness.report.audit import render_audit
    from harness.runner.audit import IDENTIFY_TOLERANCE, TOLERANCE, audit, resolve, totals
    from harness.runner.folder import claim, new_id, place

    robots = resolve(args.robots)
    out = args.out or args.reports / "audit"
    claim(out, "audit", "audit", args.replace)
    t0 = time.perf_counter()
    rows = []
    with closing(Progress("audit", args.quiet)) as progress, tempfile.TemporaryDirectory() as scratch:
        for k, (name, path) in enumerate(robots.items()):
            progress(f"robot {k + 1} of {len(robots)}: {name}", k / len(robots))
            rows.append(audit(name, path, Path(scratch) if args.identify else None))
            if rows[-1].verdict == "refused" and args.robots:  # a robot asked for by name is bad input when refused
                raise InputError(path, "", rows[-1].reason)
    summary = {**totals(rows), "tolerance": TOLERANCE,
               "identify_tolerance": IDENTIFY_TOLERANCE if args.identify else None,
               "seconds": round(time.perf_counter() - t0, 3)}
    document = {"schema": {"name": "harness-audit", "version": 1}, "totals": summary,
                "robots": [r.as_dict() for r in rows]}
    from harness.runner.results import with_nulls

    document, _ = with_nulls(document)
    text = render_audit(document)
    try:
        place(out, {"audit.json": lambda p: p.write_text(json.dumps(document, indent=1, allow_nan=False) + "\n"),
                    "audit.html": lambda p: p.write_text(text)}, "audit", "audit", new_id(), args.replace)
    except OSError as exc:
        raise InputError(out, "--out", f"cannot write output ({exc.strerror or exc})") from None
    for r in rows:
        if r.verdict != "agrees":
            print(f"  {r.verdict:12s} {r.robot}: {r.reason}")
    print(f"audit: {summary['robots']} robots, {summary['read']} read, {summary['agree']} agree, "
          f"{summary['disagree']} disagree, {summary['not_compared']} not compared, {summary['refused']} refused; "
          f"MuJoCo's MJCF conversion read back for {summary['mjcf_read']} ({summary['seconds']:.1f} s)")
    print(f"  report: {out / 'audit.html'}")
    return EXIT_GATE_FAILED if summary["disagree"] else EXIT_OK


def cmd_list(args: argparse.Namespace) -> int:
    from harness.base.builtin import listing

    for kind, key in (("models", "model"), ("scenarios", "scenario")):
        for where, files in listing(kind):
            print(f"{where} ({len(files)})")
            for f in files:
                print(f"  {f.stem:<24} {_description(f, key)}")
    from importlib.metadata import entry_points

    from harness.base.plugins import METHOD_GROUP, MODEL_GROUP, STUDY_GROUP

    for title, group in (("model plugins", MODEL_GROUP), ("identification plugins", METHOD_GROUP),
                         ("studies", STUDY_GROUP)):
        found = sorted(entry_points(group=group), key=lambda ep: ep.name)
        print(f"{title} installed ({len(found)})")
        for ep in found:
            print(f"  {ep.name:<24} {ep.value}")
    return EXIT_OK


def cmd_init(args: argparse.Namespace) -> int:
    from harness.init import project

    out: Path = args.dir
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise InputError(out, "DIR", "exists and is not an empty folder: init writes a new project")
    flag = next((f for f in ("urdf", "mjcf", "robot") if getattr(args, f, None) is not None), None)
    if args.floating and flag is None:
        raise InputError(out, "--floating", "needs your robot's URDF (--urdf, --robot): the two-link arm is "
                                            "bolted down")
    files = project(getattr(args, flag) if flag else None, f"--{flag}", args.floating)
    try:  # a file's text, or a file the robot file names, copied
        write_atomically(out, {name: (lambda p, v=value: shutil.copyfile(v, p) if isinstance(v, Path)
                                      else p.write_text(v)) for name, value in files.items()})
    except OSError as exc:
        raise InputError(out, "DIR", f"cannot write ({exc.strerror or exc})") from None
    shown = [name for name in files if "/" not in name]
    print(f"wrote {out}/: {', '.join(shown)}" + (f" and {len(files) - len(shown)} file(s) the robot file names"
                                                 if len(files) > len(shown) else ""))
    print(f"  cd {out} && harness run scenario.toml --out reports && python -m pytest")
    return EXIT_OK


def _description(path: Path, key: str) -> str:
    """The file's [key] description, or why it cannot be read (a listing never stops at one bad file)."""
    try:
        section = read_toml(path).get(key, {})
    except InputError as exc:
        return f"(unreadable: {exc.message})"
    if not isinstance(section, dict):
        return f"(unreadable: {key!r} is not a table)"
    text = section.get("description", "")
    return text if isinstance(text, str) else f"(unreadable: {key}.description is not a string)"


