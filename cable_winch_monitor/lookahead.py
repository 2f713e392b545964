"""Replay's feed: bag messages through the pipeline a window at a time, each window's samples solved at once.

The live node must merge and solve each winch message as it arrives; a replay can read
ahead. For each window of messages:

1. every winch message is merged, in log order, by the pipeline's own merger (as the
   node would merge it); each complete sample keeps what the merger knew at its message;
2. the window's complete samples are solved together (`solve_batch`, warm-started from
   the last solved sample), with their wall clearances; with another solver or with the
   plant's physical effects each is solved in step 3 instead, as the node solves it;
3. the messages are taken in log order again: a complete sample gets its alarm and
   load-pin residuals, an inclinometer or depth reading its residuals against the latest
   solved pose -- the per-sample pipeline's own code, so the outputs are the node's.

Extra inputs the plant's effects read (a shaft temperature) are taken in first, so that
a sample's value is interpolated between the readings around its stamp.

Each message comes out with its result: the solved sample (MonitorOutput), residuals,
None, or the exception the pipeline raised on it (counted like the node's callback errors).
"""
from __future__ import annotations

from typing import Any, Iterable, Iterator, Union

import numpy as np

from .bagio import fields
from .model.batched import solve_batch
from .model.plant import Plant
from .model.result import Solution
from .monitor.clearance import Clearance, solution_clearances
from .monitor.pipeline import CompleteSample, MonitorOutput, MonitorPipeline
from .monitor.residuals import Residuals

WINDOW = 2000  # messages read ahead

Result = Union[MonitorOutput, Residuals, None, Exception]


class LookaheadPipeline(MonitorPipeline):
    """The monitor pipeline fed a stream of bag messages (with .msgtype, .topic, .message), a window at a time."""

    def __init__(self, plant: Plant, solver: str = "energy", staleness: float = 0.5, batched: bool = True,
                 window: int = WINDOW):
        super().__init__(plant, solver, staleness)
        self.window = window
        # The batch solver is the rigid energy model: not for another solver, nor with physical effects.
        self.batched = batched and solver == "energy" and self.model.plain
        self.input_specs = {spec.topic: spec for spec in self.model.inputs}

    def run(self, items: Iterable[Any]) -> Iterator[tuple[Any, Result]]:
        """Every item in order, with what the pipeline made of it."""
        window: list[Any] = []
        for item in items:
            window.append(item)
            if len(window) == self.window:
                yield from self._run_window(window)
                window = []
        yield from self._run_window(window)

    def _run_window(self, window: list[Any]) -> Iterator[tuple[Any, Result]]:
        for item in window:
            spec = self.input_specs.get(item.topic)
            if spec is not None:
                self.on_input(spec, fields.message_seconds(item.message, item.log_time), item.message)
        merged = [self._merge_item(item) if item.msgtype == fields.JOINT_STATE else None for item in window]
        samples = [outcome for outcome in merged if isinstance(outcome, CompleteSample)]
        presolved = iter(self._presolve(samples))
        for item, outcome in zip(window, merged):
            solved = next(presolved) if isinstance(outcome, CompleteSample) else None
            try:
                result = self._result(item, outcome, solved)
            except Exception as error:  # noqa: BLE001 - reported with the message, the replay goes on
                result = error
            yield item, result

    def _merge_item(self, item: Any) -> CompleteSample | Exception | None:
        try:
            return self._merge(fields.joint_sample(item.message, item.topic))
        except Exception as error:  # noqa: BLE001 - returned with its message in step 3
            return error

    def _presolve(self, samples: list[CompleteSample]) -> list[tuple[Solution, Clearance | None] | None]:
        """Equilibrium and clearance of each sample, solved together (None each where not batched)."""
        if not self.batched or not samples:
            return [None] * len(samples)
        batch = solve_batch(self.plant, np.array([s.lengths for s in samples]), warm_start=self._warm_start())
        solutions = batch.solutions()
        return list(zip(solutions, solution_clearances(self.model.physical, solutions)))

    def _result(self, item: Any, outcome: CompleteSample | Exception | None,
                solved: tuple[Solution, Clearance | None] | None) -> Result:
        msg = item.message
        if item.msgtype == fields.JOINT_STATE:
            if isinstance(outcome, Exception):
                raise outcome
            return None if outcome is None else self._solve(outcome, solved)
        if item.topic in self.input_specs:
            return None  # taken in ahead of the window's samples
        return self.on_measurement(item.topic, fields.message_seconds(msg, item.log_time), msg)
