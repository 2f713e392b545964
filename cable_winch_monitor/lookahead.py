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

Step 1 of a window runs before step 3 of the window before it (step 3 reads nothing step 1
writes), so that with `second_process` the next windows' estimates are computed in a
second process (ahead.py) while this one takes the current window in order (MERGED_AHEAD
windows ahead: the second process has the time to estimate its first); they are used
where the gates have not changed in between, the same estimates as here, with the records
encoded there (`run_published`).

Each message comes out with its result: the solved sample (MonitorOutput), residuals,
None, or the exception the pipeline raised on it (counted like the node's callback errors).
"""
from __future__ import annotations

from collections import deque
from concurrent.futures import Future
from contextlib import contextmanager
from typing import Any, Iterable, Iterator, NamedTuple, Union

import numpy as np

from .ahead import AheadEstimator, Published
from .bagio import fields
from .effects.estimate import estimate_recording, forward_estimate
from .model.conditions import Conditions
from .model.estimation import Estimate
from . import channels
from .model.plant import Plant
from .model.result import Solution
from .bagio.scene import REPLAY_RATE
from .monitor.clearance import Clearance, solution_clearances
from .monitor.inputs import StampWindow
from .monitor.pipeline import CompleteSample, MonitorOutput, MonitorPipeline, Solved
from .monitor.residuals import Residuals
from .monitor.sensors import DEFAULT_HOLD

WINDOW = 2000  # messages read ahead
CHUNKS = (16, 1024)  # fewest and most samples solved together under one set of trusted sensors
MERGED_AHEAD = 3  # windows merged ahead of the one taken in order, with a second process

Result = Union[MonitorOutput, Residuals, None, Exception]


class Merged(NamedTuple):
    """A complete sample with its conditions and its winch message's header stamp."""

    sample: CompleteSample
    conditions: Conditions
    header: fields.Stamp


class FusedJob(NamedTuple):
    """The samples of a chunk that have trusted sensors (their indices in it), and the estimator's input."""

    fused: list[int]
    lengths: np.ndarray
    measured: dict[str, np.ndarray]
    conditions: list[Conditions]
    stamps: list[fields.Stamp]
    times: list[float]


class Speculated(NamedTuple):
    """A chunk's estimates started in the second process before the window's turn, under the sensors
    trusted then (`refused` left out): used only if the chunk and the gates are the same at its turn."""

    stop: int
    refused: tuple[str, ...]
    job: FusedJob
    future: Future


class Prepared(NamedTuple):
    """A window after step 1: its messages, what merging made of each, its samples, its speculated chunks."""

    window: list[Any]
    merged: list["Merged | dict[str, float] | Exception | None"]
    samples: list[Merged]
    speculated: dict[int, Speculated]


class Presolved:
    """Step 2 for a window's samples, a chunk at a time: each chunk is solved together under the
    sensors trusted when it starts. Where a gate opens or closes, the rest of the chunk is solved
    again from that sample on under the new trusted set, in a chunk of CHUNKS[0] samples, each
    following chunk twice as long up to CHUNKS[1] (a gate that flaps costs a few small chunks, a
    steady one runs in long chunks, neither a per-sample solve). A chunk speculated in the second
    process (by its start) is taken from there if the gates have not changed since."""

    def __init__(self, pipeline: "LookaheadPipeline", speculated: dict[int, Speculated]):
        self.pipeline = pipeline
        self.speculated = speculated
        self.start = self.stop = 0
        self.size = CHUNKS[1]
        self.solved: list[Solved | None] = []
        self.published: list[Published | None] = []
        self.refused: tuple[str, ...] | None = None

    def at(self, index: int, samples: list[Merged]) -> tuple[Solved | None, Published | None]:
        """The presolved equilibrium, clearance, estimate and predictions of sample `index` of the window,
        and its records where the second process encoded them."""
        refused = self.pipeline.gates.refused
        changed = index < self.stop and refused != self.refused and self.solved[index - self.start] is not None \
            and self.solved[index - self.start].estimate is not None
        if index >= self.stop or changed:
            self.size = CHUNKS[0] if changed else min(2 * self.size, CHUNKS[1])
            self.start, self.stop = index, min(index + self.size, len(samples))
            ahead = self.speculated.pop(self.start, None)
            taken = ahead is not None and ahead.stop == self.stop and ahead.refused == refused
            if ahead is not None and not taken:
                self.pipeline.ahead.discard(ahead.future)
            self.solved, self.published = self.pipeline._presolve(samples[self.start:self.stop],
                                                                  ahead if taken else None)
            self.refused = refused
        return self.solved[index - self.start], self.published[index - self.start]

    def discard_rest(self) -> None:
        """Drop the speculated chunks the window did not take (where a gate changed, its chunks start
        elsewhere)."""
        for ahead in self.speculated.values():
            self.pipeline.ahead.discard(ahead.future)
        self.speculated.clear()


class LookaheadPipeline(MonitorPipeline):
    """The monitor pipeline fed a stream of bag messages (with .msgtype, .topic, .message), a window at a time."""

    def __init__(self, plant: Plant, solver: str = "energy", staleness: float = 0.5, batched: bool = True,
                 window: int = WINDOW, stamp_window: StampWindow | None = None, gate_hold: float = DEFAULT_HOLD,
                 second_process: bool = False, scene_rate: float = REPLAY_RATE):
        super().__init__(plant, solver, staleness, stamp_window, gate_hold)
        self.window = window
        self.batched = batched and (self.fusing or self.model.batchable)  # else solved in step 3, as the node does
        self.input_specs = {spec.topic: spec for spec in self.model.inputs}
        self.second_process = second_process and self.batched and self.fusing and not self.model.refining \
            and AheadEstimator.available()
        self.ahead: AheadEstimator | None = None
        self.scene_rate = scene_rate

    def run(self, items: Iterable[Any]) -> Iterator[tuple[Any, Result]]:
        """Every item in order, with what the pipeline made of it."""
        for item, result, _ in self.run_published(items):
            yield item, result

    def run_published(self, items: Iterable[Any]) -> Iterator[tuple[Any, Result, Published | None]]:
        """`run`, each solved sample with its records where the second process encoded them (None: not
        encoded; scenes there at `scene_rate`). Each window is merged (step 1) before the one before it
        is taken in order (step 3); with `second_process`, MERGED_AHEAD windows are, so that the
        second process has estimated a window by its turn (its first one included)."""
        with self._second_process():
            depth = MERGED_AHEAD if self.ahead is not None else 1
            prepared: deque[Prepared] = deque()
            window: list[Any] = []
            for item in items:
                window.append(item)
                if len(window) == self.window:
                    prepared.append(self._prepare(window))
                    window = []
                    if len(prepared) > depth:
                        yield from self._run_window(prepared.popleft())
            prepared.append(self._prepare(window))
            while prepared:
                yield from self._run_window(prepared.popleft())

    @contextmanager
    def _second_process(self) -> Iterator[None]:
        self.ahead = AheadEstimator(self.model, self.plant, self.scene_rate) if self.second_process else None
        try:
            yield
        finally:
            if self.ahead is not None:
                self.ahead.close()
                self.ahead = None

    def _prepare(self, window: list[Any]) -> Prepared:
        """Step 1 for a window, and its chunks' estimates started in the second process."""
        for item in window:
            spec = self.input_specs.get(item.topic)
            if spec is not None:
                self.on_input(spec, fields.message_seconds(item.message, item.log_time), item.message)
        merged = [self._merge_item(item) for item in window]
        samples = [outcome for outcome in merged if isinstance(outcome, Merged)]
        speculated = {}
        if self.ahead is not None:
            for start in range(0, len(samples), CHUNKS[1]):
                stop = min(start + CHUNKS[1], len(samples))
                job = self._fused_job(samples[start:stop])
                future = self.ahead.submit(*job[1:]) if job.fused else None
                if future is not None:
                    speculated[start] = Speculated(stop, self.gates.refused, job, future)
        return Prepared(window, merged, samples, speculated)

    def _run_window(self, prepared: Prepared) -> Iterator[tuple[Any, Result, Published | None]]:
        window, merged, samples, speculated = prepared
        ahead = Presolved(self, speculated)
        index = 0
        for item, outcome in zip(window, merged):
            solved = published = None
            if isinstance(outcome, Merged):
                solved, published = ahead.at(index, samples)
                index += 1
            try:
                result = self._result(item, outcome, solved)
            except Exception as error:  # noqa: BLE001 - reported with the message, the replay goes on
                result = error
            yield item, result, published
        ahead.discard_rest()

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
        return None if sample is None else Merged(sample, self.conditions(sample), fields.stamp_of(item.message))

    def _presolve(self, samples: list[Merged], speculated: Speculated | None = None) \
            -> tuple[list[Solved | None], list[Published | None]]:
        """Equilibrium, clearance and estimate of each sample, solved together (None each where not batched),
        and the records the second process encoded. Where the plant fuses: the estimates from the sensors
        trusted now (from the second process where `speculated` there under the same gates); a sample
        with none is solved from its lengths alone (batched), as the node solves it."""
        published: list[Published | None] = [None] * len(samples)
        if not self.batched or not samples:
            return [None] * len(samples), published
        lengths = np.array([s.sample.lengths for s in samples])
        conditions = [s.conditions for s in samples]
        if not self.fusing:
            solutions = self.model.solve_batch(lengths, conditions, self._warm_start())
            return self._solved(solutions, [None] * len(samples), conditions), published
        job = self._fused_job(samples) if speculated is None else speculated.job
        out: list[Solved | None] = [None] * len(samples)
        if job.fused:
            ahead = None if speculated is None or self.ahead is None else self.ahead.estimates(speculated.future)
            if ahead is None:
                estimates = estimate_recording(self.model, *job[1:4])
                solved = self._solved([e.solution for e in estimates], estimates, job.conditions)
            else:
                solved = self._solved([e.solution for e in ahead.estimates], ahead.estimates, job.conditions,
                                      ahead.clearances, ahead.predicted)
                for i, encoded in zip(job.fused, ahead.published):
                    published[i] = encoded
            for i, row in zip(job.fused, solved):
                out[i] = row
        fused = set(job.fused)
        alone = [i for i in range(len(samples)) if i not in fused]
        if alone:
            solutions = self.model.solve_batch(lengths[alone], [conditions[i] for i in alone], self._warm_start())
            estimates = [forward_estimate(solution, lengths[i]) for i, solution in zip(alone, solutions)]
            for i, row in zip(alone, self._solved(solutions, estimates, [conditions[i] for i in alone])):
                out[i] = row
        return out, published

    def _solved(self, solutions: list[Solution], estimates: list[Estimate | None], conditions: list[Conditions],
                clearances: list[Clearance | None] | None = None,
                predicted: dict[str, np.ndarray] | None = None) -> list[Solved]:
        """Each solution with its clearance, estimate and what every channel reads there (None where not
        solved): clearances and predictions computed together here, unless given (the second process's)."""
        if clearances is None:
            clearances = solution_clearances(self.model.physical, solutions)
        if predicted is None:
            predicted = self.model.predict_solutions(solutions, conditions)
        names = list(predicted)
        rows = zip(*(values.tolist() for values in predicted.values()))
        return [Solved(solution, clearance, estimate, dict(zip(names, row)) if solution.ok else None)
                for solution, clearance, estimate, row in zip(solutions, clearances, estimates, rows)]

    def _fused_job(self, samples: list[Merged]) -> FusedJob:
        """The samples with sensors trusted now, and what the estimator needs of them."""
        trusted = [self.gates.trusted(s.sample.sensors) for s in samples]
        fused = [i for i, row in enumerate(trusted) if row]
        names = sorted({name for i in fused for name in trusted[i]})
        return FusedJob(fused, np.array([samples[i].sample.lengths for i in fused]).reshape(-1, 4),
                        {name: np.array([trusted[i].get(name, np.nan) for i in fused]) for name in names},
                        [samples[i].conditions for i in fused], [samples[i].header for i in fused],
                        [samples[i].sample.stamp for i in fused])

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
