"""The wall time a diagnosis may take: deadlines for its parts, and what it could not finish."""
from __future__ import annotations

import time

import numpy as np

RESERVE = 0.1  # share of the budget kept for scoring the last fits on the held-out rows and the report


class Budget:
    """Wall time in seconds (None: unbounded); `unfinished` lists what the time did not allow, in words."""

    def __init__(self, seconds: float | None):
        self.seconds = seconds
        self.deadline = None if seconds is None else time.monotonic() + seconds
        self.unfinished: list[str] = []

    def left(self) -> float:
        return np.inf if self.deadline is None else self.deadline - time.monotonic()

    def spent(self) -> bool:
        """Nothing new starts now: what is left is the reserve for the held-out scores and the report."""
        return self.left() <= RESERVE * (self.seconds or 0.0)

    def part(self, share: float) -> float | None:
        """A deadline for a part that may take `share` of the time left before the reserve."""
        if self.deadline is None or self.seconds is None:  # both or neither
            return None
        return time.monotonic() + share * max(self.left() - RESERVE * self.seconds, 0.0)
