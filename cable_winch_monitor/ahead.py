"""A second process that estimates replay's next window while this one publishes the current one.

A fused replay spends about a third of its time in the estimator (`recording_batch`) and
the rest in work that must run in log order: the alarms, the sensor gates, the output
records and the writing. The estimator of a window needs only the window's merged samples
and the sensors trusted when it starts, so a forked process estimates window k+1 while
this one publishes window k. What comes back are the estimator's arrays (`BatchEstimate`),
not one object per sample: pickling those would cost as much as the estimate; and each
sample's pose, /tf and tension records (`records.solution_records`), which its solution
alone decides, as the bytes the replay writes. What goes there are arrays too: the samples'
conditions packed (`PackedConditions`).

Only a fork can start it (the process inherits the plant model as it is, effects from a
user's module included, without pickling it); where the platform has none, or the worker
process is lost, the window is estimated in the replaying process as before. The worker ignores Ctrl-C:
replay stops it when it stops.
"""
from __future__ import annotations

import multiprocessing
import signal
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import replace
from typing import Mapping, NamedTuple, Sequence

import numpy as np

from .bagio.fields import Stamp
from .bagio.records import Record, solution_records
from .effects import PlantModel
from .effects.estimate import recording_batch
from .model.conditions import Conditions
from .model.estimation import BatchEstimate, Estimate

_model: PlantModel | None = None  # the worker's copy of the plant model, inherited at the fork


def _start(model: PlantModel) -> None:
    global _model
    _model = model
    signal.signal(signal.SIGINT, signal.SIG_IGN)


class PackedConditions(NamedTuple):
    """Samples' conditions as arrays, to send to the worker: pickling a `Conditions` costs more than
    estimating its sample (its three small arrays). Unpacked, the same values (inputs as they were:
    a NaN input stays in, where `StackedConditions` leaves it out)."""

    time: np.ndarray          # (N,)
    speeds: np.ndarray        # (N, 4)
    accelerations: np.ndarray  # (N, 4)
    direction: np.ndarray     # (N, 4)
    inputs: list[Mapping[str, float]]

    @classmethod
    def of(cls, conditions: Sequence[Conditions]) -> "PackedConditions":
        return cls(np.array([c.time for c in conditions], dtype=float),
                   *(np.array([getattr(c, name) for c in conditions], dtype=float).reshape(-1, 4)
                     for name in ("speeds", "accelerations", "direction")),
                   [c.inputs for c in conditions])

    def unpacked(self) -> list[Conditions]:
        return [Conditions(*row) for row in zip(self.time.tolist(), self.speeds, self.accelerations, self.direction,
                                                self.inputs)]


class Ahead(NamedTuple):
    """What the worker sends back for a chunk: the estimator's arrays (without the plant: the caller has
    it), and each sample's `records.solution_records` at its header stamp."""

    batch: BatchEstimate
    published: list[list[Record]]


def _estimate(reported: np.ndarray, measured: Mapping[str, np.ndarray], conditions: PackedConditions,
              stamps: Sequence[Stamp]) -> Ahead:
    assert _model is not None, "the worker was started without a model"
    batch = recording_batch(_model, reported, measured, conditions.unpacked())
    published = [solution_records(stamp, estimate.solution, estimate)
                 for stamp, estimate in zip(stamps, batch.estimates())]
    return Ahead(replace(batch, plant=None), published)


class AheadEstimator:
    """One worker process estimating windows for `model` (it must fuse, and not refine its geometry)."""

    def __init__(self, model: PlantModel):
        self.model = model
        self.pool: ProcessPoolExecutor | None = ProcessPoolExecutor(
            1, mp_context=multiprocessing.get_context("fork"), initializer=_start, initargs=(model,))

    @staticmethod
    def available() -> bool:
        return "fork" in multiprocessing.get_all_start_methods()

    def submit(self, reported: np.ndarray, measured: Mapping[str, np.ndarray], conditions: Sequence[Conditions],
               stamps: Sequence[Stamp]) -> Future | None:
        """Start estimating these samples (their winch messages' header `stamps`) in the worker; None where
        it is gone."""
        if self.pool is None:
            return None
        try:
            return self.pool.submit(_estimate, reported, measured, PackedConditions.of(conditions), list(stamps))
        except BrokenProcessPool:
            self.pool = None
            return None

    def estimates(self, future: Future) -> tuple[list[Estimate], list[list[Record]]] | None:
        """The estimates `future` was started for, and their samples' solution records; None where the
        worker was lost (the caller estimates them itself). The estimator's own errors are raised as they
        would be in the caller's process."""
        try:
            batch, published = future.result()
        except BrokenProcessPool:
            self.pool = None
            return None
        batch.plant = self.model.physical
        return batch.estimates(), published

    def close(self) -> None:
        if self.pool is not None:
            self.pool.shutdown(wait=True, cancel_futures=True)
            self.pool = None
