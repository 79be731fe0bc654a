"""Progress on stderr for long commands."""

from __future__ import annotations

import sys
import time


class Bar:
    """A progress bar on stderr, redrawn in place on a terminal, every 10 % otherwise."""

    def __init__(self, label: str):
        self.label, self.start, self.last = label, time.monotonic(), -1
        self.tty = sys.stderr.isatty()

    def __call__(self, done: int, total: int) -> None:
        tenth = 10 * done // total
        if not self.tty and tenth == self.last and done < total:
            return
        self.last = tenth
        width = 30
        filled = width * done // total
        line = (f"{self.label} [{'#' * filled}{'.' * (width - filled)}] {done}/{total} "
                f"{time.monotonic() - self.start:5.1f} s")
        print(("\r" if self.tty else "") + line, end="" if self.tty and done < total else "\n",
              file=sys.stderr, flush=True)
