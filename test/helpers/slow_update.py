"""A window update that keeps the update process busy (monitor.updates) and costs nothing where it is awaited."""
from __future__ import annotations

import os
import time
from typing import Any


class SlowInItsProcess:
    """Takes `seconds` in any process but the one that made it (the update process), answering where it ran."""

    def __init__(self, seconds: float):
        self.seconds, self.maker = seconds, os.getpid()

    def run(self, base: Any) -> str:
        if os.getpid() == self.maker:
            return "worked out where it was awaited"
        time.sleep(self.seconds)
        return "worked out in the update process"
