"""The first sample of each second of stamps: where what changes slowly is published (the tracked plant
parameters) or looked at (the latest sample's view that replay's /diagnostics gives)."""
from __future__ import annotations

import math


class FirstOfEachSecond:
    """Called with each sample's stamp in order: whether it is the first of its second of stamps."""

    def __init__(self) -> None:
        self.second = -math.inf  # the second of the last sample that was the first of its own

    def __call__(self, stamp: float) -> bool:
        """The first of a later second than the last one's, or of one more than a second earlier (the stamps went
        back: a simulation restarted). A sample made at another winch's message, stamped a little before the
        one before it and so across the start of a second, is not."""
        second = math.floor(stamp)
        if second > self.second or second < self.second - 1:
            self.second = second
            return True
        return False
