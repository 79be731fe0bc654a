"""`harness report` and `harness gate`: a results.json re-rendered, or its gates checked again."""

from __future__ import annotations

import argparse
from pathlib import Path

from harness.base.tomlio import InputError
from harness.cli.common import (
    EXIT_GATE_FAILED,
    EXIT_OK,
    REPORT_FILE,
    print_gates,
    read_results,
    write_ci,
    write_file_atomically,
)
from harness.runner.gates import summary_line


def cmd_report(args: argparse.Namespace) -> int:
    from harness.report import render_report

    results = read_results(args.results)
    kind = "data" if "data" in results else "recording"  # a measured log, or the bench's recording
    rec_name = results[kind].get("file", "recording.csv")
    if not isinstance(rec_name, str) or Path(rec_name).name != rec_name:
        raise InputError(args.results, f"{kind}.file", "must name a file beside results.json")
    recording = args.results.parent / rec_name
    if not recording.is_file():
        raise InputError(recording, "", f"file not found (the report needs the {kind} beside results.json)")
    out = args.out or args.results.parent / REPORT_FILE
    from harness.base.series import read_csv

    rec = read_csv(recording, bodies=kind == "recording")
    stated = results[kind]
    if len(rec.t) != stated.get("rows") or list(rec.joints) != stated.get("joints"):
        raise InputError(recording, "", f"has {len(rec.t)} rows of joints {list(rec.joints)}; results.json "
                                        f"says {stated.get('rows')} rows of {stated.get('joints')}")
    try:
        page = render_report(results, args.results.parent)
    except (KeyError, TypeError) as exc:
        raise InputError(args.results, str(exc).strip("'"), "missing or malformed in results.json") from None
    try:
        if out.absolute() == (args.results.parent / REPORT_FILE).absolute():  # the run's own: its manifest too
            from harness.runner.folder import rewrite

            rewrite(args.results.parent, REPORT_FILE, lambda p: p.write_text(page))
        else:
            write_file_atomically(out, page)
    except OSError as exc:
        raise InputError(out, "--out", f"cannot write ({exc.strerror or exc})") from None
    print(f"wrote {out}")
    return EXIT_OK


def cmd_gate(args: argparse.Namespace) -> int:
    from harness.runner.gates import from_results, verdict
    from harness.runner.scenario import load_scenario

    gates = None if args.scenario is None else load_scenario(args.scenario).gates
    passed, verdicts = True, []
    for path in args.results:
        results = read_results(path)
        checked = verdict(gates if gates is not None else from_results(results, path), results,
                          args.scenario or path)
        rows, ok = checked["gates"], checked["passed"]
        name = results.get("scenario", {}).get("name", str(path)) if isinstance(results.get("scenario"), dict) \
            else str(path)
        print(summary_line(name, rows))
        print_gates(rows)
        passed &= ok
        verdicts.append((name, rows))
    write_ci(args, verdicts)
    return EXIT_OK if passed else EXIT_GATE_FAILED


