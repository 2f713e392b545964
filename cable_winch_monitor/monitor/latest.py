"""The live monitor under load: merge every winch message, solve only the newest complete sample.

Merging a message costs microseconds, solving a sample milliseconds. A node that solved
every sample in its callback fell seconds behind at 500 Hz while its DDS queue grew, and
dropped messages unseen. Here the callback only merges; a worker takes the newest
complete sample when it is free, and a complete sample replaced by a newer one before
the worker took it is counted as skipped. So the work waiting is never more than one
sample, and every complete sample is either solved or counted.
"""
from __future__ import annotations

import threading
from typing import Any, Hashable

from .pipeline import CompleteSample, MonitorOutput, MonitorPipeline
from .inputs import JointSample


class LatestSamplePipeline(MonitorPipeline):
    """MonitorPipeline for a callback thread (`offer`, `on_measurement`, `on_input`) and a worker (`take`, `solve`).

    `lock` guards every piece of state; hold it to read the counters from a third thread.
    """

    def __init__(self, *args: Any, **kwargs: Any):
        super().__init__(*args, background=True, **kwargs)  # the model error's updates beside the samples
        self.lock = threading.RLock()
        self._ready = threading.Condition(self.lock)
        self._pending: tuple[Hashable, CompleteSample] | None = None
        self.unseen = 0  # winch messages the transport dropped before they were offered (as far as known)
        self.complete = 0  # complete samples merged
        self.skipped = 0  # complete samples replaced by a newer one before a solve

    def offer(self, sample: JointSample, tag: Hashable = None) -> bool:
        """Merge a winch message; True if it made a complete sample (kept with `tag` for the worker)."""
        with self.lock:
            complete = self._merge(sample)
            if complete is None:
                return False
            self.complete += 1
            self.skipped += self._pending is not None
            self._pending = (tag, complete)
            self._ready.notify()
            return True

    def take(self, timeout: float) -> tuple[Hashable, CompleteSample] | None:
        """The newest complete sample and its tag, waiting up to `timeout` [s] for one (None: none came)."""
        with self.lock:
            if self._pending is None:
                self._ready.wait(timeout)
            pending, self._pending = self._pending, None
            return pending

    def solve(self, sample: CompleteSample) -> MonitorOutput:
        """Solve a sample from `take`: equilibrium, alarm and load-pin residuals."""
        with self.lock:
            return super().solve(sample)

    def counters(self) -> dict[str, int]:
        """The node's own counts, for /diagnostics."""
        return {"complete samples": self.complete, "skipped (a newer sample came first)": self.skipped,
                "winch messages": self.stats.winch, "winch messages lost before the node": self.unseen,
                "waiting": self.waiting}

    def restart(self) -> None:
        """Forget every stamp, keep the counts: the clock went back (a bag played again), so each reading kept,
        the estimator's windows and the model's error learnt since, the conditions' history, the last sample
        and the alarm's level are from a future that will not come. The pipeline starts again as it was made
        (its own constructor says how)."""
        with self.lock:
            counts = self.stats
            MonitorPipeline.__init__(self, self.plant, self.solver, self.staleness, self.merger.window,
                                     background=True)
            self.stats = counts
            self._pending = None

    @property
    def waiting(self) -> int:
        """Complete samples merged but neither solved nor skipped yet (0 or 1)."""
        return int(self._pending is not None)
