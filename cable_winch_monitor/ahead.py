"""Replay's second process: it estimates, judges and encodes the samples while the replay reads, merges and writes.

What happens to a complete sample after it is merged -- its estimate (the model's error
carried from window to window), its alarm and residuals, its records and scene -- is a
function of the merged samples in order (`SamplePublisher`), the same code the node runs
one sample at a time. Replay merges each window of messages (cheap, in log order) and
hands its complete samples to a forked process that publishes them, window after window,
while it reads and merges the next ones; it then writes the records the worker encoded, in
log order, with the sensor messages' residuals between them. What comes back is bytes and
small outcomes, not objects per sample, whose pickling would cost as much as the work.

A window's results (about 1 kB a sample) come back through a file in SPOOL (/dev/shm where
there is one), not the pool's pipe: a thread of the replaying process reads that pipe, and
it needs the interpreter lock for every 64 kB. With each window comes the publisher's state
after it, so that where the worker is lost, the replay publishes the rest itself from there.
Only a fork can start it (the process inherits the plant model as it is, a user's effects
included); where there is none, the replay publishes the samples itself.
"""
from __future__ import annotations

import math
import multiprocessing
import os
import pickle
import shutil
import signal
import tempfile
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from contextlib import suppress
from typing import Any, NamedTuple, Sequence

from .bagio import records
from .bagio.fields import Stamp
from .bagio.records import Record
from .bagio.scene import SceneBuilder, SceneThrottle
from .model.conditions import Conditions
from .monitor.diagnostics import SampleView, sample_view
from .monitor.pipeline import CompleteSample, MonitorOutput, MonitorPipeline, Outcome

SPOOL = "/dev/shm"  # where the worker's results are written, if the system has it (memory, not a disk)
_worker: "SamplePublisher | None" = None  # the worker's publisher, made at the fork from the replay's


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


def _start(worker: SamplePublisher) -> None:
    global _worker
    _worker = worker
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _job(spool: str, samples: list[CompleteSample], conditions: list[Conditions], headers: list[Stamp],
         batched: bool) -> str | None:
    """The worker's job: a window's Published and its state after them, pickled to a file in `spool` (its
    path; None where it could not be written: the replay then publishes from the last state it got)."""
    assert _worker is not None, "the worker was started without its publisher"
    published = [p._replace(output=None) for p in _worker.publish(samples, conditions, headers, batched)]
    try:
        with tempfile.NamedTemporaryFile(dir=spool, delete=False) as file:
            pickle.dump((published, _worker.state()), file, protocol=pickle.HIGHEST_PROTOCOL)
    except OSError:
        return None
    return file.name


class AheadPublisher:
    """One worker process publishing windows in order for a replay's pipeline (forked before it merges)."""

    def __init__(self, publisher: SamplePublisher):
        self.local = publisher
        self.spool = tempfile.mkdtemp(prefix="cable-winch-monitor-", dir=SPOOL if os.path.isdir(SPOOL) else None)
        self.pool: ProcessPoolExecutor | None = ProcessPoolExecutor(
            1, mp_context=multiprocessing.get_context("fork"), initializer=_start, initargs=(publisher,))
        self.pending: list[tuple[Future | None, tuple[Any, ...]]] = []
        self.state: bytes | None = None  # the worker's state after the last window taken from it

    @staticmethod
    def available() -> bool:
        return "fork" in multiprocessing.get_all_start_methods()

    def submit(self, samples: list[CompleteSample], conditions: list[Conditions], headers: list[Stamp],
               batched: bool) -> None:
        """Start publishing a window's samples in the worker (in order after the windows before it)."""
        job = (samples, conditions, headers, batched)
        future = None
        if self.pool is not None:
            try:
                future = self.pool.submit(_job, self.spool, *job)
            except BrokenProcessPool:
                self._lost()
        self.pending.append((future, job))

    def take(self) -> list[Published]:
        """The oldest submitted window's Published: the worker's, or published here from the worker's last
        state where it was lost or could not hand its results over."""
        future, job = self.pending.pop(0)
        result = None
        if future is not None and self.pool is not None:
            try:
                path = future.result()
            except Exception:  # noqa: BLE001 - lost, or failed in the worker: published here, where it fails as itself
                self._lost()
                path = None
            if path is not None:
                with open(path, "rb") as file:
                    result, self.state = pickle.load(file)
                os.unlink(path)
        if result is None:
            result = self._here(job)
        return result

    def _here(self, job: tuple[Any, ...]) -> list[Published]:
        """Publish a window in this process, from the worker's last state (its initial one where it sent
        none); the windows after it are published here too."""
        if self.pool is not None:
            self._lost()
        if self.state is not None:
            self.local.restore(self.state)
            self.state = None
        return self.local.publish(*job)

    def _lost(self) -> None:
        """The worker is gone (or could not hand over a window): publish the rest here."""
        if self.pool is not None:
            self.pool.shutdown(wait=False, cancel_futures=True)
            self.pool = None
        for k, (future, job) in enumerate(self.pending):
            self.pending[k] = (None, job)

    def close(self) -> None:
        if self.pool is not None:
            self.pool.shutdown(wait=True, cancel_futures=True)
            self.pool = None
        shutil.rmtree(self.spool, ignore_errors=True)

