"""What the `harness` commands share: the exit statuses, the workers --jobs and --dask ask for, a
scenario named by path or name, atomic writes (nothing half-written on a failure), the CI files,
results.json read back, the gates printed."""

from __future__ import annotations

import argparse
import json
import os
import tempfile
from collections.abc import Callable
from pathlib import Path

from harness.base.tomlio import InputError
from harness.runner.ci import gate_line, result_word

EXIT_OK, EXIT_GATE_FAILED, EXIT_BAD_INPUT, EXIT_INTERNAL = 0, 1, 2, 3
DEFAULT_SCENARIO = "kr500_rail"
REPORT_FILE = "report.html"


def max_jobs() -> int:
    return 4 * (os.cpu_count() or 1)


def workers(args: argparse.Namespace, source):
    """The workers --jobs and --dask ask for (harness/base/workers.py); bad values name `source`."""
    from harness.base.workers import Workers

    if not 1 <= args.jobs <= max_jobs():
        raise InputError(source, "--jobs", f"needs 1 to {max_jobs()} processes (4 per core), got {args.jobs}")
    if args.dask is not None and args.jobs != 1:
        raise InputError(source, "--dask", f"the trials run either on Dask or on --jobs {args.jobs} processes, "
                                           "not both")
    if args.dask is not None and not args.dask.strip():
        raise InputError(source, "--dask", "needs a scheduler address (or none, for a local cluster)")
    return Workers(args.jobs, args.dask)


def resolve_scenario(arg: str) -> Path:
    """A path to a scenario file, or a bare name: ./scenarios/NAME.toml, ./NAME.toml, then the
    built-in scenario of that name (harness/base/builtin.py)."""
    from harness.base.builtin import resolve

    return resolve(arg, "scenarios")


def write_ci(args: argparse.Namespace, verdicts: list[tuple[str, list[dict]]], markdown=None) -> None:
    """--junit-xml and --summary of the verdicts (gate rows per scenario); `markdown` the summary's own
    form where it is not a gate table (a comparison's)."""
    from harness.runner.ci import junit_xml, markdown_summary

    for path, text in ((args.junit_xml, junit_xml), (args.summary, markdown or markdown_summary)):
        if path is not None:
            try:
                write_file_atomically(path, text(verdicts))
            except OSError as exc:
                raise InputError(path, "", f"cannot write ({exc.strerror or exc})") from None


def write_file_atomically(path: Path, text: str) -> None:
    path = path.resolve()
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(fd, "w") as f:
            f.write(text)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def write_atomically(out: Path, files: dict[str, Callable[[Path], object]]) -> None:
    """Write every file into a staging folder beside `out`, then move them into the (new or empty) folder
    `out`: a failure leaves nothing half-written in it. A run's folder is written by
    harness/runner/folder.py's `place`, which also says whose run it holds."""
    from harness.runner.folder import staged

    out = out.resolve()
    with staged(out, files) as staging:
        out.mkdir(exist_ok=True)
        for entry in staging.iterdir():
            entry.replace(out / entry.name)


def print_gates(rows: list[dict]) -> None:
    for g in rows:
        print(f"  {result_word(g)}  {gate_line(g)}")


def read_results(path: Path) -> dict:
    from harness.base.tomlio import MAX_DATA_BYTES, read_bounded

    try:
        results = json.loads(read_bounded(path, MAX_DATA_BYTES).decode("utf-8"))
    except UnicodeDecodeError as exc:
        raise InputError(path, "", f"cannot read file ({exc})") from None
    except json.JSONDecodeError as exc:
        raise InputError(path, "", f"invalid JSON: {exc}") from None
    except RecursionError:
        raise InputError(path, "", "invalid JSON: nested too deeply") from None
    schema = results.get("schema") if isinstance(results, dict) else None
    if not isinstance(schema, dict) or schema.get("name") != "harness-results":
        raise InputError(path, "schema", "not a results.json written by harness")
    for key in ("scenario", "data" if "data" in results else "recording", "run"):
        if not isinstance(results.get(key), dict):
            raise InputError(path, key, "missing or not an object: not a complete results.json")
    return results


