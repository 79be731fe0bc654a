"""The `harness` command, by command: run (harness/cli/run.py), report and gate (results.py), sweep
and excite (sweep.py), audit, list and init (project.py); the command line (parser.py), what they share
(common.py), and the door that runs one and chooses the exit status (main.py). It only wires the data
flow: scenario -> recording -> results -> report."""

from harness.cli.started import STARTED  # first: the harness's own start (its imports are part of the start-up)

# isort: split
from harness.cli.main import entry, main

__all__ = ["STARTED", "entry", "main"]
