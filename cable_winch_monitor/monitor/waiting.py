"""Complete samples held until the sensor readings due at them are in, so that what a sample fuses depends
on the readings' stamps, not on the order the topics came in.

A reading is due at a sample when the sensor's next reading, one period after its latest, is stamped at
or before the sample (`LatestReadings.due`). DDS delivers each topic in order but not the topics in the
order they were sent, and a recorder logs a reading whenever it came: either way a winch message can
come before a reading stamped before it. The node and replay both hold such a sample, and the samples
after it, until the reading comes or `wait` seconds (of its clock: the node's, a replay's log time) have
passed since the sample came; then it takes what is in.
"""
from __future__ import annotations

from collections import deque
from collections.abc import Hashable
from typing import Generic, TypeVar

from .pipeline import CompleteSample, MonitorPipeline

Key = TypeVar("Key", bound=Hashable)

READING_WAIT = 0.05  # [s] a complete sample is held at most this long for a sensor reading due at its stamp


class ReadingWait(Generic[Key]):
    """Complete samples from `MonitorPipeline.merge_winch`, each with a key, given back in order with their
    readings (`MonitorPipeline.read_sensors`) once none is due at them, or their wait is over."""

    def __init__(self, monitor: MonitorPipeline, wait: float = READING_WAIT):
        self.monitor, self.wait = monitor, wait
        self._held: deque[tuple[Key, CompleteSample, float]] = deque()  # key, sample, when it came
        self.held = 0  # samples that had to wait (for a reading due at them, or at a sample before them)
        self.unheld = 0  # of those, released when the wait ran out before the reading came

    def add(self, key: Key, sample: CompleteSample, now: float) -> list[tuple[Key, CompleteSample]]:
        """A complete sample that came at `now`; the samples released by it (itself, unless it waits)."""
        self._held.append((key, sample, now))
        released = self.release(now)
        self.held += bool(self._held)
        return released

    def release(self, now: float, everything: bool = False) -> list[tuple[Key, CompleteSample]]:
        """The samples held that may go at `now` (`everything`: all of them), oldest first, with their readings:
        up to the first whose reading is still due within its wait."""
        out = []
        while self._held:
            key, sample, since = self._held[0]
            if not everything and self.monitor.waits_for_readings(sample.stamp):
                if now - since < self.wait:
                    break
                self.unheld += 1
            self._held.popleft()
            out.append((key, self.monitor.read_sensors(sample)))
        return out

    def deadline(self) -> float | None:
        """When the oldest sample's wait runs out (None: none is held)."""
        return self._held[0][2] + self.wait if self._held else None

    def clear(self) -> int:
        """Forget the samples held; how many there were."""
        count = len(self._held)
        self._held.clear()
        return count

    def __len__(self) -> int:
        return len(self._held)
