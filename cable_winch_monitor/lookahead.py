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
   solved pose -- the per-sample pipeline's own code, so the outputs are the node's. Step 2
   runs a chunk of samples ahead of step 3 (`Presolved`): where a gate closes or opens, the
   chunk is estimated again from that sample on under the sensors trusted then.

Extra inputs the plant's effects read (a shaft temperature) are taken in first, so that
a sample's value is interpolated between the readings around its stamp.

Each message comes out with its result: the solved sample (MonitorOutput), residuals,
None, or the exception the pipeline raised on it (counted like the node's callback errors).
"""
from __future__ import annotations

from typing import Any, Iterable, Iterator, NamedTuple, Union

import numpy as np

from .bagio import fields
from .effects.estimate import estimate_recording, forward_estimate
from .model.conditions import Conditions
from .model.estimation import Estimate
from . import channels
from .model.plant import Plant
from .model.result import Solution
from .monitor.clearance import solution_clearances
from .monitor.inputs import StampWindow
from .monitor.pipeline import CompleteSample, MonitorOutput, MonitorPipeline, Solved
from .monitor.residuals import Residuals
from .monitor.sensors import DEFAULT_HOLD

WINDOW = 2000  # messages read ahead
CHUNKS = (16, 1024)  # fewest and most samples solved together under one set of trusted sensors

Result = Union[MonitorOutput, Residuals, None, Exception]


class Merged(NamedTuple):
    """A complete sample with its conditions."""

    sample: CompleteSample
    conditions: Conditions


class Presolved:
    """Step 2 for a window's samples, a chunk at a time: each chunk is solved together under the
    sensors trusted when it starts. Where a gate opens or closes, the rest of the chunk is solved
    again from that sample on under the new trusted set, in a chunk of CHUNKS[0] samples, each
    following chunk twice as long up to CHUNKS[1] (a gate that flaps costs a few small chunks, a
    steady one runs in long chunks, neither a per-sample solve)."""

    def __init__(self, pipeline: "LookaheadPipeline"):
        self.pipeline = pipeline
        self.start = self.stop = 0
        self.size = CHUNKS[1]
        self.solved: list[Solved | None] = []
        self.refused: tuple[str, ...] | None = None

    def at(self, index: int, samples: list[Merged]) -> Solved | None:
        """The presolved equilibrium, clearance, estimate and predictions of sample `index` of the window."""
        refused = self.pipeline.gates.refused
        changed = index < self.stop and refused != self.refused and self.solved[index - self.start] is not None \
            and self.solved[index - self.start].estimate is not None
        if index >= self.stop or changed:
            self.size = CHUNKS[0] if changed else min(2 * self.size, CHUNKS[1])
            self.start, self.stop = index, min(index + self.size, len(samples))
            self.solved = self.pipeline._presolve(samples[self.start:self.stop])
            self.refused = refused
        return self.solved[index - self.start]


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
        ahead = Presolved(self)
        index = 0
        for item, outcome in zip(window, merged):
            solved = None
            if isinstance(outcome, Merged):
                solved = ahead.at(index, samples)
                index += 1
            try:
                result = self._result(item, outcome, solved)
            except Exception as error:  # noqa: BLE001 - reported with the message, the replay goes on
                result = error
            yield item, result

    def _merge_item(self, item: Any) -> Merged | dict[str, float] | Exception | None:
        """Step 1 for one message: a winch message merged (its complete sample, if it makes one), a
        sensor's readings kept for the samples to come (and returned, for step 3)."""
        if item.msgtype != fields.JOINT_STATE:
            if channels.on_topic(item.topic) and item.topic not in self.input_specs:
                try:
                    stamp = fields.message_seconds(item.message, item.log_time)
                except Exception:  # noqa: BLE001 - step 3 reports it with its message
                    return None
                values = self.read_channels(item.topic, item.message)
                self.keep_reading(stamp, values)
                return values
            return None
        try:
            sample = self._merge(fields.joint_sample(item.message, item.topic, item.log_time * 1e-9))  # arrival: log time
        except Exception as error:  # noqa: BLE001 - returned with its message in step 3
            return error
        return None if sample is None else Merged(sample, self.conditions(sample))

    def _presolve(self, samples: list[Merged]) -> list[Solved | None]:
        """Equilibrium, clearance and estimate of each sample, solved together (None each where not batched)."""
        if not self.batched or not samples:
            return [None] * len(samples)
        lengths = np.array([s.sample.lengths for s in samples])
        if self.fusing:
            estimates = self._estimates(samples, lengths)
            solutions = [e.solution for e in estimates]
        else:
            solutions = self.model.solve_batch(lengths, [s.conditions for s in samples], self._warm_start())
            estimates = [None] * len(samples)
        return [Solved(*row) for row in zip(solutions, solution_clearances(self.model.physical, solutions), estimates,
                                            self._predictions(solutions, [s.conditions for s in samples]))]

    def _predictions(self, solutions: list[Solution], conditions: list[Conditions]) -> list[dict[str, float] | None]:
        """What every channel reads at each solved state (None where not solved), all at once."""
        predicted = self.model.predict_solutions(solutions, conditions)
        names = list(predicted)
        rows = zip(*(values.tolist() for values in predicted.values()))
        return [dict(zip(names, row)) if solution.ok else None for row, solution in zip(rows, solutions)]

    def _estimates(self, samples: list[Merged], lengths: np.ndarray) -> list[Estimate]:
        """The window's estimates from the sensors trusted now; a sample with none is solved from its
        lengths alone (batched), as the node solves it."""
        trusted = [self.gates.trusted(s.sample.sensors) for s in samples]
        conditions = [s.conditions for s in samples]
        fused = [i for i, row in enumerate(trusted) if row]
        alone = [i for i, row in enumerate(trusted) if not row]
        out: list[Estimate | None] = [None] * len(samples)
        if fused:
            names = sorted({name for i in fused for name in trusted[i]})
            measured = {name: np.array([trusted[i].get(name, np.nan) for i in fused]) for name in names}
            for i, estimate in zip(fused, estimate_recording(self.model, lengths[fused], measured,
                                                             [conditions[i] for i in fused])):
                out[i] = estimate
        if alone:
            solutions = self.model.solve_batch(lengths[alone], [conditions[i] for i in alone], self._warm_start())
            for i, solution in zip(alone, solutions):
                out[i] = forward_estimate(solution, lengths[i])
        return out

    def _result(self, item: Any, outcome: Merged | dict[str, float] | Exception | None,
                solved: Solved | None) -> Result:
        msg = item.message
        if item.msgtype == fields.JOINT_STATE:
            if isinstance(outcome, Exception):
                raise outcome
            if outcome is None:
                return None
            return self._solve(outcome.sample, solved, outcome.conditions)
        if item.topic in self.input_specs:
            return None  # taken in ahead of the window's samples
        values = outcome if isinstance(outcome, dict) else None
        return self.on_measurement(item.topic, fields.message_seconds(msg, item.log_time), msg, keep=False,
                                   values=values)
