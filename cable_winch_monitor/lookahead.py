"""Replay's feed: bag messages through the pipeline a window at a time, each window's samples solved at once.

The live node must merge and solve each winch message as it arrives; a replay can read
ahead. For each window of messages:

1. every winch message is merged, in log order, by the pipeline's own merger (as the
   node would merge it, its log time standing for the node clock in the stamp window);
   each complete sample keeps what the merger knew at its message;
2. the window's complete samples get their conditions and are solved together
   (`PlantModel.solve_batch`, warm-started from the last solved sample), with their wall
   clearances; the plant's effects act as in the node's solve. Where they make the
   geometry depend on the pose, or with another solver, each sample is solved in step 3
   instead, as the node solves it;
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
from .model.conditions import Conditions
from .model.plant import Plant
from .model.result import Solution
from .monitor.clearance import Clearance, solution_clearances
from .monitor.inputs import StampWindow
from .monitor.pipeline import CompleteSample, MonitorOutput, MonitorPipeline
from .monitor.residuals import Residuals

WINDOW = 2000  # messages read ahead

Result = Union[MonitorOutput, Residuals, None, Exception]
Presolved = tuple[Solution, Union[Clearance, None], Conditions]


class LookaheadPipeline(MonitorPipeline):
    """The monitor pipeline fed a stream of bag messages (with .msgtype, .topic, .message), a window at a time."""

    def __init__(self, plant: Plant, solver: str = "energy", staleness: float = 0.5, batched: bool = True,
                 window: int = WINDOW, stamp_window: StampWindow | None = None):
        super().__init__(plant, solver, staleness, stamp_window)
        self.window = window
        self.batched = batched and self.model.batchable  # else each sample is solved in step 3, as the node does
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
            sample = fields.joint_sample(item.message, item.topic)
            return self._merge(sample._replace(received=item.log_time * 1e-9))  # arrival: the log time
        except Exception as error:  # noqa: BLE001 - returned with its message in step 3
            return error

    def _presolve(self, samples: list[CompleteSample]) -> list[Presolved | None]:
        """Equilibrium, clearance and conditions of each sample, solved together (None each where not batched)."""
        if not self.batched or not samples:
            return [None] * len(samples)
        conditions = [self.conditions(sample) for sample in samples]
        solutions = self.model.solve_batch(np.array([s.lengths for s in samples]), conditions, self._warm_start())
        return list(zip(solutions, solution_clearances(self.model.physical, solutions), conditions))

    def _result(self, item: Any, outcome: CompleteSample | Exception | None, solved: Presolved | None) -> Result:
        msg = item.message
        if item.msgtype == fields.JOINT_STATE:
            if isinstance(outcome, Exception):
                raise outcome
            if outcome is None:
                return None
            return self._solve(outcome) if solved is None else self._solve(outcome, solved[:2], solved[2])
        if item.topic in self.input_specs:
            return None  # taken in ahead of the window's samples
        return self.on_measurement(item.topic, fields.message_seconds(msg, item.log_time), msg)
