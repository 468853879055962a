"""What a long command is doing now, on stderr: a live line on a terminal, plain lines in a log.

Progress goes to stderr so that what a command prints on stdout (its tables, its
results) is the same from one run to the next whatever the timing, and a pipe or
file of results is not interleaved with it.

- On a terminal: one transient line (spinner, the current step, elapsed time) that
  disappears when the command ends.
- Otherwise (a log file, CI, a pipe): plain lines ``phid [  12.3 s] step``, one when the
  step changes (at most one a second) and a reminder every ``HEARTBEAT_S`` while a step
  lasts, so a log shows the command is alive and where it spends its time.

Nothing is printed for a command that ends within ``QUIET_S``: a quick command, and
above all a refused one, keeps its output to its results or its one-line error.
"""

from __future__ import annotations

import sys
import threading
import time
from collections.abc import Callable
from types import TracebackType
from typing import Any, TextIO

QUIET_S = 2.0  # no progress at all for a command that ends sooner
MIN_GAP_S = 1.0  # plain lines: at most one a second
HEARTBEAT_S = 30.0  # plain lines: the step again while it lasts longer than this
POLL_S = 0.2


LIVE_FRAME = 13  # the spinner, the elapsed time (0:00:00) and the spaces between the three columns


class ProgressLine:
    """Context manager; ``update(step)`` says what the command is doing now."""

    def __init__(
        self,
        first: str = "",
        *,
        stream: TextIO | None = None,
        quiet_s: float | None = None,
        source: Callable[[], str | None] | None = None,
    ) -> None:
        """``source``: asked every poll what the command is doing now (a step another thread
        works through, which no ``update`` call reports); its answer, when not None, is the step."""
        self.stream = stream if stream is not None else sys.stderr
        self.source = source
        self.quiet_s = QUIET_S if quiet_s is None else quiet_s
        self.live = bool(getattr(self.stream, "isatty", lambda: False)())
        self._step = first
        self._printed: str | None = None
        self._last_line = -float("inf")
        self._t0 = time.monotonic()
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._rich: Any = None  # a rich Progress while live
        self._task = None

    def __enter__(self) -> ProgressLine:
        self._t0 = time.monotonic()
        if self.live:
            self._start_live()
            if self.source is not None:
                self._thread = threading.Thread(target=self._plain_loop, name="phid-progress", daemon=True)
                self._thread.start()
        else:
            self._maybe_print()  # without a quiet time the first step shows at once, not at the first poll
            self._thread = threading.Thread(target=self._plain_loop, name="phid-progress", daemon=True)
            self._thread.start()
        return self

    def update(self, step: str) -> None:
        with self._lock:
            self._step = step
        if self._rich is not None and self._task is not None:
            self._rich.update(self._task, description=self._fitted(step))
        elif self._thread is not None and self._rich is None:
            # a step is shown when it begins, not at the next poll: a step shorter than a poll
            # would otherwise be missing from the log, depending on the machine's speed
            self._maybe_print()

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
        if self._rich is not None:
            self._rich.stop()

    def print_above(self, console: Any, *objects: Any, **kwargs: Any) -> None:
        """``console.print(*objects, **kwargs)`` while the live line runs: on a terminal (stdout and
        the live line on one screen) it is printed above the line, which is drawn again below it;
        printed past the live display, a tracking row was lost from the screen altogether. Where
        stdout is not a terminal (a pipe, a file), ``console`` prints as it would."""
        if self._rich is not None and sys.__stdout__ is not None and sys.__stdout__.isatty():
            self._rich.console.print(*objects, **kwargs)
        else:
            console.print(*objects, **kwargs)

    # -- plain lines -------------------------------------------------------------------------
    def _plain_loop(self) -> None:
        while not self._stop.wait(POLL_S):
            if self.source is not None and (step := self.source()) is not None and step != self._step:
                self.update(step)
            elif self._rich is None:
                self._maybe_print()

    def _maybe_print(self) -> None:
        # the lock covers the decision and the write: the poll thread and update() both print
        with self._lock:
            now = time.monotonic()
            elapsed = now - self._t0
            step = self._step
            if not step or elapsed < self.quiet_s:
                return
            changed = step != self._printed and now - self._last_line >= MIN_GAP_S
            if changed or now - self._last_line >= HEARTBEAT_S:
                still = "" if changed else " (still)"
                self.stream.write(f"phid [{elapsed:6.1f} s] {step}{still}\n")
                self.stream.flush()
                self._printed, self._last_line = step, now

    # -- a live line on a terminal -----------------------------------------------------------
    def _start_live(self) -> None:
        from rich.console import Console
        from rich.progress import Progress, SpinnerColumn, TextColumn, TimeElapsedColumn

        console = Console(file=self.stream, markup=False)  # the step names the user's files
        self._rich = Progress(
            SpinnerColumn(),
            TextColumn("{task.description}", markup=False),
            TimeElapsedColumn(),
            console=console,
            transient=True,
        )
        self._rich.start()
        self._task = self._rich.add_task(self._fitted(self._step), total=None)

    def _fitted(self, step: str) -> str:
        """The step cut to what the line leaves beside the spinner and the elapsed time: rich crops a
        row that is too long from its right, so at 80 columns a long step hid the elapsed time (and
        the spinner) and the line read as hung."""
        room = self._rich.console.width - LIVE_FRAME
        return step if len(step) <= room else step[: max(1, room - 1)] + "…"
