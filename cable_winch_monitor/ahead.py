"""Replay's second process: it estimates, judges and encodes the samples while the replay reads, merges and writes.

What happens to a complete sample after it is merged -- its estimate (the model's error
carried from window to window), its alarm and residuals, its records and scene -- is a
function of the merged samples in order (`SamplePublisher`), the same code the node runs
one sample at a time. Replay merges each window of messages (cheap, in log order) and
hands its complete samples to a forked process that publishes them, window after window,
while it reads and merges the next ones; it then writes the records the worker encoded, in
log order, with the sensor messages' residuals between them. What comes back is bytes and
small outcomes, not objects per sample, whose pickling would cost as much as the work.

A window's job and its results (about 1 kB a sample) go through files in the worker's spool
(forked.py: /dev/shm, or TMPDIR where that cannot be written), not a pipe, which would make
either process wait for the other to read. With each window comes the publisher's state
after it, so that where the worker is lost -- it died, failed on a window, or stopped
answering -- the replay publishes the rest itself from there. Only a fork can start it (the
process inherits the plant model as it is, a user's effects included); where there is none,
or no spool or process can be had, the replay publishes the samples itself.
"""
from __future__ import annotations

import functools
import math
import os
import pickle
from collections.abc import Sequence
from typing import Any, NamedTuple

from .bagio import records
from .bagio.fields import Stamp
from .bagio.records import Record
from .bagio.scene import SceneBuilder, SceneThrottle
from .forked import ForkedWorker, WorkerLost
from .model.conditions import Conditions
from .monitor.diagnostics import SampleView, sample_view
from .monitor.pipeline import CompleteSample, MonitorOutput, MonitorPipeline, Outcome


class Published(NamedTuple):
    """A complete sample as replay writes it: its records (outputs, and a scene where one is due), what its
    counts and the residuals of the sensor messages after it need, and at the first sample of each
    second of stamps what /diagnostics says of it."""

    records: list[Record]
    outcome: Outcome
    view: SampleView | None
    output: MonitorOutput | None = None  # the sample's outputs themselves, where published in this process


class SamplePublisher:
    """A window's merged samples estimated (or solved) together, judged one by one in order -- alarm,
    residuals, what the alarm is based on -- and encoded, by the pipeline's own code."""

    def __init__(self, pipeline: MonitorPipeline, scene_rate: float):
        self.pipeline = pipeline
        self.builder, self.throttle = SceneBuilder(pipeline.plant), SceneThrottle(scene_rate)
        self.second = -math.inf  # the second of stamps whose diagnostics view was sent

    def publish(self, samples: Sequence[CompleteSample], conditions: Sequence[Conditions],
                headers: Sequence[Stamp], batched: bool = True) -> list[Published]:
        """What replay writes for each sample (header stamps `headers`); solved together where `batched`."""
        pipeline = self.pipeline
        solved = pipeline.solve_samples(samples, conditions) if batched else [None] * len(samples)
        out = []
        for sample, at, header, ahead in zip(samples, conditions, headers, solved):
            output, outcome = pipeline.judge(sample, ahead, at)
            encoded = records.output_records(header, output)
            if self.throttle.due(output.stamp):
                encoded += records.scene_records(header, self.builder, output.solution, output.alarm)
            second = math.floor(output.stamp)
            view = None
            if second != self.second:
                self.second, view = second, sample_view(output, pipeline.fusing)
            out.append(Published(encoded, outcome, view, output))
        return out

    def state(self) -> bytes:
        """What the publisher has learnt so far (the estimator's, the alarm's, the scenes'), pickled."""
        pipeline = self.pipeline
        return pickle.dumps((pipeline.estimator, pipeline.alarms.level, pipeline.tracker, self.throttle.last,
                             self.second), protocol=pickle.HIGHEST_PROTOCOL)

    def restore(self, state: bytes) -> None:
        pipeline = self.pipeline
        estimator, level, tracker, scene, self.second = pickle.loads(state)
        if estimator is not None:
            estimator.attach(pipeline.model)
        pipeline.estimator, pipeline.alarms.level, pipeline.tracker, self.throttle.last = estimator, level, tracker, \
            scene


def _job(publisher: SamplePublisher, job: tuple[Any, ...]) -> tuple[list[Published], bytes]:
    """The worker's job: a window's Published (without the outputs themselves) and its publisher's state
    after them."""
    return [p._replace(output=None) for p in publisher.publish(*job)], publisher.state()


class AheadPublisher:
    """A worker process publishing windows in order for a replay's pipeline (forked before it merges); where
    it cannot be started, or is lost, the windows are published here."""

    def __init__(self, publisher: SamplePublisher):
        self.local = publisher
        try:
            self.worker: ForkedWorker | None = ForkedWorker(functools.partial(_job, publisher),
                                                            f"cable-winch-monitor-{os.getpid()}-")
        except OSError:
            self.worker = None  # no spool folder or no process to be had: published here
        self.pending: list[tuple[bool, tuple[Any, ...]]] = []  # (handed to the worker, job) in order
        self.state: bytes | None = None  # the worker's state after the last window taken from it
        self.lost = ""  # why the worker was given up, where it was

    @staticmethod
    def available() -> bool:
        return ForkedWorker.available()

    def submit(self, samples: list[CompleteSample], conditions: list[Conditions], headers: list[Stamp],
               batched: bool) -> None:
        """Start publishing a window's samples in the worker (in order after the windows before it)."""
        job = (samples, conditions, headers, batched)
        if self.worker is not None:
            try:
                self.worker.submit(job)
            except WorkerLost as lost:
                self._lost(str(lost))
        self.pending.append((self.worker is not None, job))

    def take(self) -> list[Published]:
        """The oldest submitted window's Published: the worker's, or published here from the worker's last
        state where it was lost, failed on the window, or stopped answering."""
        handed, job = self.pending.pop(0)
        if handed and self.worker is not None:
            try:
                result, self.state = self.worker.result()
                return result
            except WorkerLost as lost:
                self._lost(str(lost))
        if self.state is not None:
            self.local.restore(self.state)
            self.state = None
        return self.local.publish(*job)

    def _lost(self, why: str) -> None:
        """The worker is gone (or could not hand a window over): it is ended, the rest published here."""
        self.lost = why
        self.close()
        self.pending = [(False, job) for _, job in self.pending]

    def close(self) -> None:
        """End the worker, if there is one (killed where it still has work)."""
        if self.worker is not None:
            self.worker.close()
            self.worker = None
