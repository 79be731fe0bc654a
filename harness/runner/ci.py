"""The verdict in the forms CI systems read: JUnit XML (one test case per gate, a failure element
for each failing gate) and a Markdown table for a job summary. A run that ends in bad input or an
internal error has no verdict: both files then hold one test case with an error carrying the
one-line message, so that a CI's test tab is never empty when something went wrong."""

from __future__ import annotations

import xml.etree.ElementTree as ET

from harness.runner.gates import summary_line


def _value(g: dict) -> str:
    return "no value" if g["value"] is None else f"{g['value']:.3g}"


def _sign(g: dict) -> str:
    return "<=" if g["direction"] == "at_most" else ">="


def junit_xml(verdicts: list[tuple[str, list[dict]]]) -> str:
    """verdicts: (scenario name, gate rows) per scenario."""
    root = ET.Element("testsuites", name="harness", tests=str(sum(len(r) for _, r in verdicts)), errors="0",
                      failures=str(sum(not g["passed"] for _, r in verdicts for g in r)))
    for name, rows in verdicts:
        suite = ET.SubElement(root, "testsuite", name=name, tests=str(len(rows)),
                              failures=str(sum(not g["passed"] for g in rows)), errors="0",
                              skipped=str(sum(bool(g.get("skipped")) for g in rows)))
        for g in rows:
            case = ET.SubElement(suite, "testcase", classname=name, name=g["name"])
            ET.SubElement(case, "system-out").text = f"{g['metric']} = {_value(g)} (limit {_sign(g)} {g['limit']:.3g})"
            if g.get("skipped"):
                ET.SubElement(case, "skipped", message=g["reason"])
            elif not g["passed"]:
                why = gate_line(g)
                failure = ET.SubElement(case, "failure", message=why, type="GateFailed")
                failure.text = why
    return _xml(root)


def result_word(g: dict, fail: str = "FAIL") -> str:
    """A gate's outcome in one word: pass, skip (what it judges did not run) or FAIL."""
    return "skip" if g.get("skipped") else "pass" if g["passed"] else fail


def _xml(root: ET.Element) -> str:
    ET.indent(root)
    return '<?xml version="1.0" encoding="utf-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def gate_line(g: dict) -> str:
    """One gate as a line: `metric = value <= limit`, then why it has no value or where its worst
    case lies (the joint and time, or the parameter), when the result says so."""
    sign = _sign(g) if g["passed"] or g["value"] is None else (">" if g["direction"] == "at_most" else "<")
    line = g["metric"] if g.get("skipped") else f"{g['metric']} = {_value(g)} {sign} {g['limit']:.3g}"
    if g["name"] != g["metric"]:
        line = f"{g['name']}: {line}"
    notes = [n for n in (g.get("reason"), g.get("where") and f"worst: {g['where']}") if n]
    return line + (f" ({'; '.join(notes)})" if notes else "")


def error_xml(name: str, kind: str, message: str) -> str:
    """No verdict: one test case `name` with an <error> (kind: "bad input" or "internal error")."""
    root = ET.Element("testsuites", name="harness", tests="1", failures="0", errors="1")
    suite = ET.SubElement(root, "testsuite", name=name, tests="1", failures="0", errors="1", skipped="0")
    case = ET.SubElement(suite, "testcase", classname=name, name=f"{name}: {kind}")
    error = ET.SubElement(case, "error", message=message, type=kind.title().replace(" ", ""))
    error.text = message
    return _xml(root)


def error_summary(name: str, kind: str, message: str) -> str:
    return f"### {cell(name)}: ERROR ({kind})\n\n{cell(message)}\n"


def cell(text: str) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


def markdown_summary(verdicts: list[tuple[str, list[dict]]]) -> str:
    out = []
    for name, rows in verdicts:
        out.append(f"### {cell(summary_line(name, rows))}\n")
        out.append("| gate | metric | value | limit | result | worst case |\n|---|---|---:|---:|---|---|")
        for g in rows:
            out.append(f"| {cell(g['name'])} | `{cell(g['metric'])}` | {_value(g)} | {_sign(g)} {g['limit']:.3g} | "
                       f"{result_word(g, '**FAIL**')} | {cell(g.get('where') or g.get('reason') or '')} |")
        out.append("")
    return "\n".join(out) + "\n"
