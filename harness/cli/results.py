"""`harness report`, `harness gate` and `harness compare`: a results.json re-rendered, its gates checked
again, or two runs' gated metrics side by side."""

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
    write_atomically,
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
    if args.figures is not None:
        _matplotlib(args.figures)
    from harness.report import plots

    try:
        with plots.collecting() as charts:  # each chart's data, for --figures
            page = render_report(results, args.results.parent)
    except (KeyError, TypeError) as exc:
        raise InputError(args.results, str(exc).strip("'"), "missing or malformed in results.json") from None
    if args.figures is not None:
        from harness.report.figures import files

        try:
            write_atomically(args.figures, files(charts))
        except OSError as exc:
            raise InputError(args.figures, "--figures", f"cannot write ({exc.strerror or exc})") from None
        print(f"wrote {len(charts)} figures (PNG and PDF) into {args.figures}")
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


def _matplotlib(folder: Path) -> None:
    """--figures draws with matplotlib: where it is not installed, bad input naming the option."""
    import importlib.util

    if importlib.util.find_spec("matplotlib") is None:
        raise InputError(folder, "--figures", "needs matplotlib: pip install 'robot-dynamics-harness[figures]'")
    if folder.exists() and not folder.is_dir():
        raise InputError(folder, "--figures", "is a file: name a folder for the figures")


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


def _runs(path: Path) -> dict[str, tuple[Path, dict]]:
    """The results a path holds by scenario name: a results.json, or a folder holding one or one per
    subfolder (as `harness run` writes several scenarios)."""
    if path.is_file():
        files = [path]
    elif path.is_dir():
        files = [path / "results.json"] if (path / "results.json").is_file() else sorted(path.glob("*/results.json"))
        if not files:
            raise InputError(path, "", "no results.json in it or in its subfolders")
    else:
        raise InputError(path, "", "not found (a results.json, or a folder of runs)")
    out: dict[str, tuple[Path, dict]] = {}
    for f in files:
        results = read_results(f)
        name = results["scenario"].get("name")
        if not isinstance(name, str) or not name:
            raise InputError(f, "scenario.name", "missing: the run's scenario cannot be matched")
        if name in out:
            raise InputError(f, "scenario.name", f"{name!r} is also the scenario of {out[name][0]}")
        out[name] = (f, results)
    return out


def cmd_compare(args: argparse.Namespace) -> int:
    from harness.runner.compare import compare, dropped, line, markdown
    from harness.runner.gates import from_results

    baseline, candidate = _runs(args.baseline), _runs(args.candidate)
    if len(baseline) == 1 and len(candidate) == 1 and set(baseline) != set(candidate):
        (b, (bf, _)), (c, (cf, _)) = next(iter(baseline.items())), next(iter(candidate.items()))
        raise InputError(cf, "scenario.name", f"another scenario: {c!r}, where the baseline {bf} is {b!r}")
    missing = [name for name in baseline if name not in candidate]
    if missing:
        raise InputError(args.candidate, "", f"no results of scenario {missing[0]!r}, which the baseline "
                                             f"{baseline[missing[0]][0]} has")
    worse, verdicts = False, []
    for name, (cf, c) in candidate.items():
        if name not in baseline:
            print(f"{name}: new (no baseline to compare with)")
            continue
        bf, b = baseline[name]
        gates = from_results(c, cf)
        compared = compare(gates, b, c)
        rows = [item.row() for item in compared]
        print(line(name, rows))
        for item in compared:
            print(f"  {item.word:5s}  {item.gate.name}: {item.described()}")
        for metric in dropped(from_results(b, bf), gates):
            print(f"  dropped  {metric}: gated in the baseline, not in the candidate (not compared)")
        worse |= any(item.worse for item in compared)
        verdicts.append((f"{name} against the baseline", rows))
    write_ci(args, verdicts, markdown)
    return EXIT_GATE_FAILED if worse else EXIT_OK
