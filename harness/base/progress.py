"""Progress of a long command on stderr, one mechanism for all of them: whatever works reports
`progress(stage, fraction)`, `fraction` None when a stage starts and 0..1 while one that counts
trials or steps goes on (a pool's `done, total` passes through `Progress.counting`). Here it is
shown: a line per stage once the command has taken more than a moment, and for a stage that
reports fractions a bar (tqdm) on a terminal, a line every tenth in a log file."""

from __future__ import annotations

import shutil
import sys
import time
from collections.abc import Callable
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from tqdm import tqdm

STEPS = 1000  # a bar's resolution


class Progress:
    def __init__(self, name: str, quiet: bool = False, after: float = 1.0):
        """`name` heads every line; nothing is shown with `quiet`, nor before `after` seconds."""
        self.name, self.quiet, self.after, self.start = name, quiet, after, time.monotonic()
        self.bar: tqdm | None = None
        self.stage: str | None = None
        self.tenth = -1  # the last tenth written as a line, where stderr is not a terminal
        self.terminal = sys.stderr.isatty()

    def __call__(self, stage: str, fraction: float | None) -> None:
        elapsed = time.monotonic() - self.start
        if self.quiet:
            return
        if fraction is None or stage != self.stage:
            self.close()
        if fraction is None:
            if elapsed >= self.after:
                print(f"  [{self.name} {elapsed:5.1f} s] {stage}", file=sys.stderr, flush=True)
            return
        if not self.terminal:
            tenth = int(10 * fraction)
            if stage != self.stage or tenth > self.tenth:
                self.stage, self.tenth = stage, tenth
                print(f"  [{self.name} {elapsed:5.1f} s] {stage} {100 * fraction:3.0f}%", file=sys.stderr, flush=True)
            return
        if self.bar is None:
            from tqdm import tqdm  # only where a bar is drawn: a run in a log or --quiet has no use for it

            self.stage = stage
            size = shutil.get_terminal_size()  # 80 x 24 where the terminal reports none (tqdm would show nothing)
            self.bar = tqdm(total=STEPS, desc=f"  [{self.name} {elapsed:5.1f} s] {stage}", file=sys.stderr,
                            leave=True, mininterval=0.5,
                            ncols=size.columns, nrows=size.lines,
                            bar_format="{desc} {percentage:3.0f}% |{bar:20}| {elapsed}")
        self.bar.update(max(0, round(STEPS * fraction) - self.bar.n))
        if fraction >= 1.0:
            self.close()

    def counting(self, stage: str) -> Callable[[int, int], None]:
        """A `progress(done, total)` callback (a pool of trials) reporting as `stage`."""
        return lambda done, total: self(stage, done / total)

    def close(self) -> None:
        """End the bar in progress, if any, with its line (before an error or another stage)."""
        if self.bar is not None:
            self.bar.close()
        self.bar, self.stage, self.tenth = None, None, -1
