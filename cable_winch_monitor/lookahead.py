"""Replay's feed: bag messages through the pipeline a window at a time, each window's samples solved at once.

The live node must merge and solve each winch message as it arrives; a replay can read
ahead. For each window of messages:

1. every winch message is merged, in log order, by the pipeline's own merger (as the
   node would merge it, its log time standing for the node clock in the stamp window), and
   every sensor reading kept as the node keeps it; each complete sample keeps what the
   merger knew at its message, what the sensors read then, and its conditions;
2. the window's complete samples are solved together, with their wall clearances: where
   the plant fuses its sensors (`noise.length`), estimated together from the sensors
   trusted at the window's start (`estimate_recording`); else solved by
   `PlantModel.solve_batch`, warm-started from the last solved sample. Where the effects
   make the geometry depend on the pose, or with another solver, each sample is solved in
   step 3 instead, as the node solves it;
3. the messages are taken in log order again: a complete sample gets its alarm and
   load-pin residuals, an inclinometer or depth reading its residuals against the latest
   solved pose -- the per-sample pipeline's own code, so the outputs are the node's. A sample
   whose trusted sensors changed within the window (a gate closed or opened) is estimated
   again there, warm-started, as the node estimates it.

Extra inputs the plant's effects read (a shaft temperature) are taken in first, so that
a sample's value is interpolated between the readings around its stamp.

Each message comes out with its result: the solved sample (MonitorOutput), residuals,
None, or the exception the pipeline raised on it (counted like the node's callback errors).
"""
from __future__ import annotations

from typing import Any, Iterable, Iterator, NamedTuple, Union

import numpy as np

from .bagio import fields
from .effects.estimate import estimate_recording
from .model.conditions import Conditions
from .model.estimation import Estimate
from . import channels
from .model.plant import Plant
from .model.result import Solution
from .monitor.clearance import Clearance, solution_clearances
from .monitor.inputs import StampWindow
from .monitor.pipeline import CompleteSample, MonitorOutput, MonitorPipeline
from .monitor.residuals import Residuals
from .monitor.sensors import DEFAULT_HOLD

WINDOW = 2000  # messages read ahead

Result = Union[MonitorOutput, Residuals, None, Exception]
Solved = tuple[Solution, Clearance | None, Estimate | None]


class Merged(NamedTuple):
    """A complete sample with its conditions."""

    sample: CompleteSample
    conditions: Conditions


class LookaheadPipeline(MonitorPipeline):
    """The monitor pipeline fed a stream of bag messages (with .msgtype, .topic, .message), a window at a time."""

    def __init__(self, plant: Plant, solver: str = "energy", staleness: float = 0.5, batched: bool = True,
                 window: int = WINDOW, stamp_window: StampWindow | None = None, gate_hold: float = DEFAULT_HOLD):
        super().__init__(plant, solver, staleness, stamp_window, gate_hold)
        self.window = window
        self.batched = batched and (self.fusing or self.model.batchable)  # else solved in step 3, as the node does
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
        merged = [self._merge_item(item) for item in window]
        samples = [outcome for outcome in merged if isinstance(outcome, Merged)]
        refused = self.gates.refused  # the sensors left out when the window was estimated
        presolved = iter(self._presolve(samples))
        for item, outcome in zip(window, merged):
            solved = next(presolved) if isinstance(outcome, Merged) else None
            if solved is not None and solved[2] is not None and self.gates.refused != refused:
                solved = None  # a gate changed within the window: estimated as the node does
            try:
                result = self._result(item, outcome, solved)
            except Exception as error:  # noqa: BLE001 - reported with the message, the replay goes on
                result = error
            yield item, result

    def _merge_item(self, item: Any) -> Merged | Exception | None:
        """Step 1 for one message: a winch message merged (its complete sample, if it makes one), a
        sensor reading kept for the samples to come."""
        if item.msgtype != fields.JOINT_STATE:
            readers = channels.on_topic(item.topic)
            if readers and item.topic not in self.input_specs:
                try:
                    stamp = fields.message_seconds(item.message, item.log_time)
                except Exception:  # noqa: BLE001 - step 3 reports it with its message
                    return None
                self.keep_reading(stamp, {c.name: c.read(item.message) for c in readers})
            return None
        try:
            sample = self._merge(fields.joint_sample(item.message, item.topic)
                                 ._replace(received=item.log_time * 1e-9))  # arrival: the log time
        except Exception as error:  # noqa: BLE001 - returned with its message in step 3
            return error
        return None if sample is None else Merged(sample, self.conditions(sample))

    def _presolve(self, samples: list[Merged]) -> list[Solved | None]:
        """Equilibrium, clearance and estimate of each sample, solved together (None each where not batched)."""
        if not self.batched or not samples:
            return [None] * len(samples)
        lengths = np.array([s.sample.lengths for s in samples])
        if self.fusing:
            trusted = [self.gates.trusted(s.sample.sensors) for s in samples]
            names = sorted({name for row in trusted for name in row})
            measured = {name: np.array([row.get(name, np.nan) for row in trusted]) for name in names}
            estimates = estimate_recording(self.model, lengths, measured, [s.conditions for s in samples])
            solutions = [e.solution for e in estimates]
        else:
            solutions = self.model.solve_batch(lengths, [s.conditions for s in samples], self._warm_start())
            estimates = [None] * len(samples)
        return list(zip(solutions, solution_clearances(self.model.physical, solutions), estimates))

    def _result(self, item: Any, outcome: Merged | Exception | None, solved: Solved | None) -> Result:
        msg = item.message
        if item.msgtype == fields.JOINT_STATE:
            if isinstance(outcome, Exception):
                raise outcome
            if outcome is None:
                return None
            return self._solve(outcome.sample, solved, outcome.conditions)
        if item.topic in self.input_specs:
            return None  # taken in ahead of the window's samples
        return self.on_measurement(item.topic, fields.message_seconds(msg, item.log_time), msg, keep=False)
