"""Replay's solve path: the complete samples of a window of messages solved at once.

The live node must solve each sample as it arrives; a replay can read ahead. Before a
window of messages is fed to the pipeline, a copy of its input merger runs over the
window's joint states to find the complete samples the pipeline will meet, and
`solve_batch` solves them together, warm-started from the last solved sample. The
pipeline then takes these solutions in turn (each checked against its sample's
lengths; a sample not foreseen is solved per sample), so merging, alarms, residuals and
outputs are the per-sample pipeline's own.
"""
from __future__ import annotations

import copy
from collections import deque
from typing import Any, Iterable, Iterator, TypeVar

import numpy as np

from ..model.batched import solve_batch
from ..model.plant import Plant
from ..model.result import Solution
from . import fields
from .clearance import Clearance, solution_clearances
from .pipeline import MonitorPipeline

JOINT_STATE = "sensor_msgs/msg/JointState"
WINDOW = 2000  # messages read ahead

Item = TypeVar("Item")


class LookaheadPipeline(MonitorPipeline):
    """The energy-solver pipeline, fed by `feed`, solving each window's samples in one batch."""

    def __init__(self, plant: Plant, staleness: float = 0.5, window: int = WINDOW):
        super().__init__(plant, "energy", staleness)
        self.window = window
        self._presolved: deque[tuple[np.ndarray, Solution, Clearance | None]] = deque()

    def _solution(self, lengths: np.ndarray) -> tuple[Solution, Clearance | None]:
        if self._presolved and np.array_equal(self._presolved[0][0], lengths):
            return self._presolved.popleft()[1:]
        self._presolved.clear()  # not foreseen: the rest of the window would be out of step
        return super()._solution(lengths)

    def feed(self, items: Iterable[Item]) -> Iterator[Item]:
        """The items (with .msgtype, .topic, .message) unchanged, a window at a time, each window presolved."""
        window: list[Item] = []
        for item in items:
            window.append(item)
            if len(window) == self.window:
                self._presolve(window)
                yield from window
                window = []
        self._presolve(window)
        yield from window

    def _presolve(self, window: list[Any]) -> None:
        merger = copy.deepcopy(self.merger)
        lengths = []
        for item in window:
            if item.msgtype != JOINT_STATE:
                continue
            try:
                sample = fields.joint_sample(item.message, item.topic)
                if merger.add(sample).rejected:
                    continue
                complete, _ = merger.complete(sample.stamp)
            except Exception:  # noqa: BLE001 - the pipeline meets the same error and counts it
                continue
            if complete is not None:
                lengths.append(complete)
        if lengths and self.model is None:  # the batch solver is the rigid model: not with physical effects
            solutions = solve_batch(self.plant, np.array(lengths), warm_start=self._warm_start()).solutions()
            self._presolved = deque(zip(lengths, solutions, solution_clearances(self.plant, solutions)))
