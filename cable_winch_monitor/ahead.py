"""A second process that estimates replay's next window while this one publishes the current one.

A fused replay spends about a third of its time in the estimator (`recording_batch`) and
the rest in work that must run in log order: the alarms, the sensor gates, the output
records and the writing. The estimator of a window needs only the window's merged samples
and the sensors trusted when it starts, so a forked process estimates window k+1 while
this one publishes window k. What comes back are the estimator's arrays (`BatchEstimate`),
not one object per sample: pickling those would cost as much as the estimate.

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
from typing import Mapping, Sequence

import numpy as np

from .effects import PlantModel
from .effects.estimate import recording_batch
from .model.conditions import Conditions
from .model.estimation import BatchEstimate, Estimate

_model: PlantModel | None = None  # the worker's copy of the plant model, inherited at the fork


def _start(model: PlantModel) -> None:
    global _model
    _model = model
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _estimate(reported: np.ndarray, measured: Mapping[str, np.ndarray],
              conditions: Sequence[Conditions]) -> BatchEstimate:
    assert _model is not None, "the worker was started without a model"
    return replace(recording_batch(_model, reported, measured, conditions), plant=None)  # the caller has it


class AheadEstimator:
    """One worker process estimating windows for `model` (it must fuse, and not refine its geometry)."""

    def __init__(self, model: PlantModel):
        self.model = model
        self.pool: ProcessPoolExecutor | None = ProcessPoolExecutor(
            1, mp_context=multiprocessing.get_context("fork"), initializer=_start, initargs=(model,))

    @staticmethod
    def available() -> bool:
        return "fork" in multiprocessing.get_all_start_methods()

    def submit(self, reported: np.ndarray, measured: Mapping[str, np.ndarray],
               conditions: Sequence[Conditions]) -> Future | None:
        """Start estimating these samples in the worker; None where it is gone."""
        if self.pool is None:
            return None
        try:
            return self.pool.submit(_estimate, reported, measured, list(conditions))
        except BrokenProcessPool:
            self.pool = None
            return None

    def estimates(self, future: Future) -> list[Estimate] | None:
        """The estimates `future` was started for; None where the worker was lost (the caller estimates
        them itself). The estimator's own errors are raised as they would be in the caller's process."""
        try:
            batch = future.result()
        except BrokenProcessPool:
            self.pool = None
            return None
        batch.plant = self.model.physical
        return batch.estimates()

    def close(self) -> None:
        if self.pool is not None:
            self.pool.shutdown(wait=True, cancel_futures=True)
            self.pool = None
