"""A plain-text progress line on stderr for long runs (no dependency, silent for short ones).

The time left is estimated from the rate since the first update, not since the start:
a run's start-up (opening a bag, compiling decoders, a first cold solve) would otherwise
be charged to every item -- one item done after a second of start-up made 8,000 items look
like 8,000 s. Before MIN_SHARE of the work is done, or MIN_RATE_TIME has passed since the
first update, no estimate is shown.
"""
from __future__ import annotations

import sys
import time
from collections.abc import Callable
from typing import TextIO

WIDTH = 30
MIN_SHARE = 0.02        # share of the work done before the time left is estimated ...
MIN_RATE_TIME = 0.1     # [s] ... and time measured since the first update


class Progress:
    """Shown once a run has taken `delay` s; redrawn in place on a terminal, else a line every `interval` s.
    `only_tty`: draw nothing unless the stream is a terminal."""

    def __init__(self, label: str, total: int | float | None, stream: TextIO = sys.stderr, delay: float = 1.0,
                 enabled: bool = True, only_tty: bool = False, clock: Callable[[], float] = time.monotonic):
        self.label, self.total, self.stream, self.clock = label, total, stream, clock
        self.tty = stream.isatty()
        self.enabled = enabled and (self.tty or not only_tty)
        self.interval = 0.25 if self.tty else 5.0
        self.started = clock()
        self.next_draw = self.started + delay
        self.drawn = False
        self.first: tuple[float, float] | None = None  # (time, done) at the first update
        self.note = ""
        self.done: int | float = 0  # the last count given

    def update(self, done: int | float, note: str = "") -> None:
        now = self.clock()
        if self.first is None:
            self.first = (now, done)
        self.note = note or self.note
        self.done = done
        if self.enabled and now >= self.next_draw:
            self.next_draw = now + self.interval
            self._draw(done, now)

    def left(self, done: int | float, now: float) -> float | None:
        """Seconds left at the rate since the first update (None: too early to tell)."""
        if not self.total or self.first is None:
            return None
        since, done_then = now - self.first[0], done - self.first[1]
        if done / self.total < MIN_SHARE or since < MIN_RATE_TIME or done_then <= 0:
            return None
        return max(self.total - done, 0.0) * since / done_then

    def _draw(self, done: int | float, now: float) -> None:
        elapsed = now - self.started
        note = f" {self.note}" if self.note else ""
        if self.total:
            fraction = min(done / self.total, 1.0)
            bar = "#" * int(WIDTH * fraction)
            left = self.left(done, now)
            eta = "estimating" if left is None else f"{left:.0f} s left"
            text = (f"{self.label} [{bar:<{WIDTH}}] {fraction:4.0%} {done:,}/{self.total:,}, {elapsed:.0f} s, "
                    f"{eta}{note}")
        else:
            text = f"{self.label} {done:,} messages, {elapsed:.0f} s{note}"
        self.stream.write(("\r" + text + "\x1b[K") if self.tty else text + "\n")
        self.stream.flush()
        self.drawn = True

    def finish(self) -> None:
        if self.drawn and self.tty:
            self.stream.write("\n")
            self.stream.flush()
