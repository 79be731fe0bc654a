"""The verdict in the forms CI systems read: JUnit XML (one test case per gate, a failure element
for each failing gate) and a Markdown table for a job summary."""

from __future__ import annotations

import xml.etree.ElementTree as ET


def _value(g: dict) -> str:
    return "no value" if g["value"] is None else f"{g['value']:.3g}"


def _sign(g: dict) -> str:
    return "<=" if g["direction"] == "at_most" else ">="


def junit_xml(verdicts: list[tuple[str, list[dict]]]) -> str:
    """verdicts: (scenario name, gate rows) per scenario."""
    root = ET.Element("testsuites", name="harness", tests=str(sum(len(r) for _, r in verdicts)),
                      failures=str(sum(not g["passed"] for _, r in verdicts for g in r)))
    for name, rows in verdicts:
        suite = ET.SubElement(root, "testsuite", name=name, tests=str(len(rows)),
                              failures=str(sum(not g["passed"] for g in rows)), errors="0", skipped="0")
        for g in rows:
            case = ET.SubElement(suite, "testcase", classname=name, name=g["name"])
            ET.SubElement(case, "system-out").text = f"{g['metric']} = {_value(g)} (limit {_sign(g)} {g['limit']:.3g})"
            if not g["passed"]:
                why = f"{g['metric']} = {_value(g)}, limit {_sign(g)} {g['limit']:.3g}"
                failure = ET.SubElement(case, "failure", message=why + (f" ({g['reason']})" if g["reason"] else ""),
                                        type="GateFailed")
                failure.text = why
    ET.indent(root)
    return '<?xml version="1.0" encoding="utf-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def _cell(text: str) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


def markdown_summary(verdicts: list[tuple[str, list[dict]]]) -> str:
    out = []
    for name, rows in verdicts:
        ok = all(g["passed"] for g in rows)
        out.append(f"### {_cell(name)}: {'PASSED' if ok else 'FAILED'} ({sum(g['passed'] for g in rows)} of "
                   f"{len(rows)} gates)\n")
        out.append("| gate | metric | value | limit | result |\n|---|---|---:|---:|---|")
        for g in rows:
            out.append(f"| {_cell(g['name'])} | `{_cell(g['metric'])}` | {_value(g)} | {_sign(g)} {g['limit']:.3g} | "
                       f"{'pass' if g['passed'] else '**FAIL**'} |")
        out.append("")
    return "\n".join(out) + "\n"
