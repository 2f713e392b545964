"""A plain-text progress line on stderr for long runs (no dependency, silent for short ones)."""
from __future__ import annotations

import sys
import time
from typing import TextIO

WIDTH = 30


class Progress:
    """Shown once a run has taken `delay` s; redrawn in place on a terminal, else a line every `interval` s."""

    def __init__(self, label: str, total: int | None, stream: TextIO = sys.stderr, delay: float = 1.0,
                 enabled: bool = True):
        self.label, self.total, self.stream, self.enabled = label, total, stream, enabled
        self.tty = stream.isatty()
        self.interval = 0.25 if self.tty else 5.0
        self.started = time.monotonic()
        self.next_draw = self.started + delay
        self.drawn = False

    def update(self, done: int) -> None:
        now = time.monotonic()
        if self.enabled and now >= self.next_draw:
            self.next_draw = now + self.interval
            self._draw(done, now - self.started)

    def _draw(self, done: int, elapsed: float) -> None:
        if self.total:
            fraction = min(done / self.total, 1.0)
            bar = "#" * int(WIDTH * fraction)
            eta = elapsed * (1.0 - fraction) / fraction if fraction > 0 else float("nan")
            text = (f"{self.label} [{bar:<{WIDTH}}] {fraction:4.0%} {done:,}/{self.total:,}, {elapsed:.0f} s, "
                    f"{eta:.0f} s left")
        else:
            text = f"{self.label} {done:,} messages, {elapsed:.0f} s"
        self.stream.write(("\r" + text) if self.tty else text + "\n")
        self.stream.flush()
        self.drawn = True

    def finish(self) -> None:
        if self.drawn and self.tty:
            self.stream.write("\n")
            self.stream.flush()
