"""When the `harness` command started: its package's import, the first thing the command does (the
interpreter's own start-up before it is not the harness's). `harness.cli` imports this module first."""

import time

STARTED = time.perf_counter()
