"""The live scheduler: a callback thread merges every winch message, a worker solves the waiting samples together.

Merging a message costs microseconds, solving a sample milliseconds. A node that solved
every sample in its callback fell seconds behind at 500 Hz while its DDS queue grew, and
dropped messages unseen. Here the callback only merges; a worker takes every complete
sample waiting when it is free and estimates them together, in order (the estimator's
batch is the replay's: the same states as one at a time, for a fraction of the cost), so
a stall of the machine costs no sample and leaves the node's state the replay's. Only a
sample more than `backlog` seconds (of stamps) older than the newest is dropped unsolved,
and counted as skipped: the work waiting never outgrows the backlog, and the outputs are
never more than that behind the winches. What a sample waited before its solve and what it took from
its merge to its outputs are kept for the last TIMED samples and reported in /diagnostics: the share of
the latency that is queueing, the share that is solving.

DDS delivers each topic in order, but not the topics in the order they were sent: under load a
winch message can overtake an inclinometer reading stamped before it. A complete sample with a
reading due at it is held until the reading comes, `wait` seconds at most (monitor.waiting), so that
the node fuses what a replay fuses, and its state stays the replay's.

It holds a monitor (`monitor`) and decides when its stages run; what they do is the
monitor's.
"""
from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable, Hashable
from typing import Any

import numpy as np

from ..model.plantfile.plant import Plant
from ..monitor.inputs import JointSample, StampWindow
from ..monitor.judged import MonitorOutput
from ..monitor.pipeline import CompleteSample, MonitorPipeline
from ..monitor.residuals import Residuals
from ..monitor.sensors import READING_LAG
from ..monitor.updates import UpdateProcess
from ..monitor.waiting import READING_WAIT, ReadingWait

BACKLOG = 0.3  # [s] of sample stamps the worker may be behind the newest sample before the oldest are skipped
TIMED = 500  # the latest samples whose queueing and processing time /diagnostics reports
QUEUED, PROCESSED = "queued before the solve", "merged to outputs"  # their names there
UPDATES_LOST = "update processes lost (their updates worked out in the node)"


class LiveScheduler:
    """A monitor fed by a callback thread (`offer`, `on_measurement`, and the monitor's `on_input` under
    `lock`) and solved by a worker (`take`, `solve_all`).

    `lock` guards every piece of state, the monitor's included; hold it to read the counters from a third
    thread. `monitor` is replaced when the scheduler restarts: read it under the lock each time.
    """

    def __init__(self, plant: Plant, solver: str = "energy", staleness: float = 0.5,
                 stamp_window: StampWindow | None = None, backlog: float = BACKLOG, wait: float = READING_WAIT,
                 clock: Callable[[], float] = time.monotonic, lag: float = READING_LAG):
        # the window updates (the model's error, the tracked parameters) are worked out beside the samples, in a
        # process of their own (started at the first)
        self.updates = UpdateProcess(plant, solver)
        self.monitor = MonitorPipeline(plant, solver, staleness, stamp_window, background=self.updates, lag=lag)
        self.backlog, self.clock = backlog, clock
        self.lock = threading.RLock()
        self._ready = threading.Condition(self.lock)
        # complete samples keyed by their tag and the clock at their merge: held while a reading due at them has
        # not come, then pending with their readings for the worker
        self._held: ReadingWait[tuple[Hashable, float]] = ReadingWait(self.monitor, wait)
        self._pending: deque[tuple[tuple[Hashable, float], CompleteSample]] = deque()
        self._taken: list[float] = []  # the clock at the merge of each sample of the latest `take`
        self._solving = 0  # samples taken by the worker and not yet noted: still waiting for their outputs
        self.unseen = 0  # winch messages the transport dropped before they were offered (as far as known)
        self.complete = 0  # complete samples merged
        self.skipped = 0  # complete samples dropped unsolved: more than the backlog behind the newest
        self.generation = 0  # restarts so far
        self.queued: deque[float] = deque(maxlen=TIMED)  # [s] from merge to the start of its solve, latest samples
        self.processed: deque[float] = deque(maxlen=TIMED)  # [s] from merge to its outputs

    def offer(self, sample: JointSample, tag: Hashable = None) -> bool:
        """Merge a winch message; True if it made a complete sample (kept with `tag` for the worker, held
        while a sensor reading due at it has not come)."""
        with self.lock:
            complete = self.monitor.merge_winch(sample)
            if complete is None:
                return False
            self.complete += 1
            now = self.clock()
            self._hand_over(self._held.add((tag, now), complete, now))
            while self._pending and self._pending[0][1].stamp < complete.stamp - self.backlog:
                self._pending.popleft()
                self.skipped += 1
            return True

    def on_measurement(self, topic: str, stamp: float, message: Any) -> Residuals | None:
        """A sensor message, kept by the monitor (its residuals, as `MonitorPipeline.on_measurement`); the
        samples held for it go on."""
        with self.lock:
            residuals = self.monitor.on_measurement(topic, stamp, message)
            self._hand_over(self._held.release(self.clock()))
            return residuals

    def _hand_over(self, released: list[tuple[tuple[Hashable, float], CompleteSample]]) -> None:
        """Samples released with their readings, for the worker."""
        if released:
            self._pending.extend(released)
            self._ready.notify()

    def take(self, timeout: float) -> list[tuple[Hashable, CompleteSample]]:
        """Every complete sample waiting, oldest first, with its tag; waits up to `timeout` [s] for one
        (empty: none came)."""
        with self.lock:
            self._hand_over(self._held.release(self.clock()))
            if not self._pending:
                deadline = self._held.deadline()  # the oldest waits for a reading: until it comes, or its wait is over
                self._ready.wait(timeout if deadline is None else min(timeout, max(deadline - self.clock(), 0.0)))
                self._hand_over(self._held.release(self.clock()))
            taken = list(self._pending)
            self._pending.clear()
            self._solving = len(taken)
            self._taken = [merged for (_, merged), _ in taken]
            return [(tag, sample) for (tag, _), sample in taken]

    def solve_all(self, samples: list[CompleteSample]) -> list[MonitorOutput]:
        """Solve samples from `take` together, in order: equilibrium, alarm and load-pin residuals of each
        (none where the scheduler restarted meanwhile: the samples are from a future that will not come).
        The estimate, the long part, runs without the lock (its state is the worker's alone), so that the
        callbacks merge the messages as they come meanwhile."""
        try:
            with self.lock:
                started = self.clock()
                monitor, generation = self.monitor, self.generation
                conditions = monitor.conditions(samples)
                estimator = monitor.estimator
            solved = monitor.solve_samples(samples, conditions, estimator)
            with self.lock:
                if generation != self.generation:
                    return []
                judged = monitor.judge_samples(samples, solved)
                for outcome in judged.outcomes():
                    monitor.note(outcome)
                outputs = judged.outputs()
                self._time(started, self.clock())
                return outputs
        finally:
            with self.lock:
                self._solving = 0

    def _time(self, started: float, done: float) -> None:
        """Keep how long each sample of the latest `take` queued and took from its merge to its outputs
        (`started`, `done`: the clock when their solve began and ended)."""
        for merged in self._taken:
            self.queued.append(started - merged)
            self.processed.append(done - merged)
        self._taken = []

    def counters(self) -> dict[str, object]:
        """The node's own counts, the update process's losses, and its latest samples' times, for /diagnostics."""
        lost: dict[str, object] = {UPDATES_LOST: self.updates.losses}
        if self.updates.losses:
            lost[f"{UPDATES_LOST}, the last"] = self.updates.last_loss
        return {**self._counts(), **lost, **{f"{name} [ms], latest {len(times)} samples": _percentiles(times)
                                             for name, times in ((QUEUED, self.queued), (PROCESSED, self.processed))
                                             if times}}

    def _counts(self) -> dict[str, int]:
        return {"complete samples": self.complete, "skipped (behind by more than the backlog)": self.skipped,
                "winch messages": self.monitor.stats.winch, "winch messages lost before the node": self.unseen,
                "waiting": self.waiting + self._solving,  # neither solved nor skipped yet: queued or being solved
                "held for a sensor reading": self._held.held, "of those, released without it": self._held.unheld}

    def restart(self) -> None:
        """Forget every stamp, keep the counts: the clock went back (a bag played again), so each reading kept,
        the estimator's windows and the model's error learnt since, the conditions' history, the last sample
        and the alarm's level are from a future that will not come. A new monitor, made as the first was,
        carries the counts on."""
        with self.lock:
            old = self.monitor
            self.monitor = MonitorPipeline(old.plant, old.solver, old.staleness, old.merger.window,
                                           background=self.updates, lag=old.readings.lag)
            self.monitor.stats = old.stats
            self.skipped += self._held.clear() + len(self._pending) + self._solving  # dropped unsolved: from the future that went
            self._pending.clear()
            self._held.monitor = self.monitor
            self.generation += 1

    def close(self) -> None:
        """Stop the window updates' process."""
        self.updates.close()

    @property
    def waiting(self) -> int:
        """Complete samples merged and not yet taken by the worker."""
        return len(self._held) + len(self._pending)


def _percentiles(seconds: deque[float]) -> str:
    p50, p99, most = 1e3 * np.percentile(seconds, [50.0, 99.0, 100.0])
    return f"p50 {p50:.1f}, p99 {p99:.1f}, max {most:.1f}"
