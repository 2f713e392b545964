"""The replay scheduler: bag messages through the monitor a window at a time, each window's samples solved at once.

The live node must merge and solve each winch message as it arrives; a replay can read
ahead. For each window of messages:

1. every winch message is merged, in log order, by the monitor's own merger (as the
   node would merge it, its log time standing for the node clock in the stamp window), and
   every sensor reading kept as the node keeps it; each complete sample keeps what the
   merger knew at its message, what the sensors read then (the latest readings stamped at or
   before it: one logged after it is waited for, as the node waits, monitor.waiting), and the
   extra inputs' values at its stamp;
2. the window's complete samples get their conditions (speeds, accelerations, directions) and
   are estimated (or solved) together by the monitor's own `conditions` and `solve_samples`,
   with their wall clearances: both are functions of the samples in order, so a window at once
   gives what the node gives one sample at a time;
3. the messages are taken in log order again: a complete sample gets its alarm and
   load-pin residuals, an inclinometer or depth reading its residuals against the latest
   solved pose -- the per-sample monitor's own code, so the outputs are the node's; once the
   window's messages are taken, its samples' residuals are encoded together and the 3-D
   scenes, where one is due, drawn.

Extra inputs the plant's effects read (a shaft temperature) are taken in first, so that
a sample's value is interpolated between the readings around its stamp. Where the effects
make the geometry depend on the pose, or with another solver, each sample is solved in
step 3 instead, as the node solves it.

With a second process, the windows grow from FIRST_WINDOW messages to the full size and shrink
again towards the bag's end (`window_sizes`): the second process, which takes longer over a
window than this one, starts on a small window instead of waiting for a full one to be merged,
and this one waits less for the last window's results before it can write them.

Each message comes out with its result: the encoded sample (`Encoded`), residuals, None,
or why the monitor could not take it (`Failed`: what it raised, counted like the node's
callback errors). The scheduler holds the monitor and decides when and where its stages
run (steps 2 and 3 in a second process where there is one: second_process.py); what they
do is the monitor's.
"""
from __future__ import annotations

import itertools
import math
from collections import Counter, deque
from collections.abc import Generator, Iterable, Iterator
from typing import Any, NamedTuple

from ..messages import fields, stacked
from ..messages.records import Record, diagnostics_record
from ..messages.scene import REPLAY_RATE
from ..model.plantfile.plant import CABLE_NAMES, Plant
from ..monitor.diagnostics import DiagnosticsReporter, SampleView, WinchView, sample_view, winch_view
from ..monitor.inputs import StampWindow
from ..monitor.pipeline import CompleteSample, MonitorPipeline, MonitorStats
from ..monitor.residuals import Residuals
from ..monitor.sensors import READING_LAG
from ..monitor.waiting import ReadingWait
from ..stopping import interruptible
from .second_process import SecondProcess
from .stages import Encoded, Measured, WindowStages, finished

WINDOW = 2000  # messages read ahead
FIRST_WINDOW = 250  # messages in the first and last windows read ahead, with a second process
EXTENDED = 1000  # messages a window goes on by at most while a sample waits for a reading due at it
MERGED_AHEAD = 3  # windows merged ahead of the one taken in order, with a second process
DIAGNOSTICS_PERIOD = 1.0  # [s] of log time between /diagnostics, as the node's default
COUNTED = ("messages", "used", "rejected", "ignored_names")  # the stats merging counts, ahead of the messages taken


class Failed(NamedTuple):
    """A message the monitor could not take: what it raised, as "Type: message"."""

    why: str

    @classmethod
    def of(cls, error: Exception) -> Failed:
        return cls(f"{type(error).__name__}: {error}")


Result = Encoded | Measured | Failed | None


class Merged(NamedTuple):
    """A complete sample with the extra inputs' values at its stamp and its winch message's header stamp."""

    sample: CompleteSample
    inputs: dict[str, float]
    header: fields.Stamp


class Prepared(NamedTuple):
    """A window merged and handed to the stages (step 1): its messages, what merging made of each, the
    diagnostics due at each, and what merging it added to the stats (COUNTED)."""

    window: list[Any]
    merged: list[Any]
    inputs: list[Any]
    counted: list[Counter[str]]


def _counters(stats: MonitorStats) -> list[Counter[str]]:
    """A copy of the stats merging counts (COUNTED), to tell later what a window added."""
    return [getattr(stats, name).copy() for name in COUNTED]


def _read(merged: list[Any], released: list[tuple[int, CompleteSample]]) -> None:
    """The samples released by the wait for their readings, with them, in their places in a window's `merged`."""
    for index, sample in released:
        merged[index] = merged[index]._replace(sample=sample)


def window_sizes(full: int, expected: int) -> Iterator[int]:
    """How many messages each window takes, with a second process, of a bag of `expected` messages (0: not
    known): doubling from FIRST_WINDOW up to `full`, and halving again over the last ones, but not below
    FIRST_WINDOW. (The messages a window goes on by while a sample waits, EXTENDED, are not counted: the
    last windows are then a little larger.)"""
    size = least = min(FIRST_WINDOW, full)
    taken = 0
    while True:
        left = expected - taken
        this = max(min(size, left // 2), least) if 0 < left < 2 * full else size
        yield this
        taken += this
        size = min(2 * size, full)


def _since(before: list[Counter[str]], stats: MonitorStats) -> list[Counter[str]]:
    """What merging has counted since `before` (a `_counters` copy)."""
    return [getattr(stats, name) - counter for name, counter in zip(COUNTED, before)]


class WindowScheduler:
    """A monitor fed a stream of bag messages (with .msgtype, .topic, .message), a window at a time.

    Each window is merged here (step 1) and its complete samples run through the `WindowStages` (steps 2
    and 3 of a sample: estimated, judged, encoded): in a second process where `second_process`
    (MERGED_AHEAD windows ahead of the one taken in order), else here. The messages then come out in
    log order with what became of them."""

    def __init__(self, plant: Plant, solver: str = "energy", staleness: float = 0.5, batched: bool = True,
                 window: int = WINDOW, stamp_window: StampWindow | None = None, second_process: bool = False,
                 scene_rate: float = REPLAY_RATE, lag: float = READING_LAG):
        self.monitor = monitor = MonitorPipeline(plant, solver, staleness, stamp_window, lag=lag)
        self.window = window
        self.batched = batched and (monitor.fusing or monitor.model.batchable)  # else one by one, as the node does
        self.input_specs = {spec.topic: spec for spec in monitor.model.inputs}
        self.stages = WindowStages(monitor, scene_rate)
        self.waiting: ReadingWait[int] = ReadingWait(monitor)  # a window's samples (by place) waiting for a reading due at them
        self.second_process = second_process and SecondProcess.available()
        self.last_view: SampleView | None = None  # what /diagnostics says of the latest sample taken
        self.reporter = DiagnosticsReporter(plant.name)
        self.diagnostics_due = -math.inf  # [s] of log time: the next /diagnostics
        self._merging: list[Counter[str]] | None = None  # the stats COUNTED before the window being merged
        self._encoded: list[Encoded] = []  # the window's samples, where the stages run in this process
        self.not_taken: Counter[str] = Counter()  # after a stop: messages read but not taken, by topic
        self.worker_lost = ""  # why the second process was given up (the rest published here), where it was

    def run(self, items: Iterable[Any], expected: int = 0) -> Iterator[tuple[Any, Result]]:
        """Every item in order, with what became of it: a winch message that made a complete sample with its
        `Encoded`, a sensor message with its residuals (or None), a message the monitor could not
        take with why (`Failed`: counted as the node counts its callback errors). `expected`: how many
        items there are (0: not known), to size the windows by."""
        for item, result, _ in self.run_diagnosed(items, expected):
            yield item, result

    def run_diagnosed(self, items: Iterable[Any], expected: int = 0
                      ) -> Generator[tuple[Any, Result, list[Record]], None, None]:
        """`run`, with /diagnostics after the messages where DIAGNOSTICS_PERIOD of log time has passed, as
        the node publishes them at its clock (log time stands for it).

        A stop signal (stopping.py) breaks it off only while a window is merged or its samples are awaited,
        never between the messages of a window taken; the counts of the messages read or merged but not
        taken are then taken back (`not_taken`: the reader's)."""
        second = SecondProcess(self.stages) if self.second_process else None
        depth = MERGED_AHEAD if second is not None else 0
        sizes = window_sizes(self.window, expected) if second is not None else itertools.repeat(self.window)
        size = next(sizes)
        prepared: deque[Prepared] = deque()
        window: list[Any] = []
        try:
            stream = iter(items)
            for item in stream:
                window.append(item)
                if len(window) == size:
                    size = next(sizes)
                    prepared.append(self._prepare(window, second, stream))
                    window = []
                    if len(prepared) > depth:
                        yield from self._take(prepared[0], second)
                        prepared.popleft()
            prepared.append(self._prepare(window, second))
            window = []
            while prepared:
                yield from self._take(prepared[0], second)
                prepared.popleft()
        except KeyboardInterrupt:
            self._take_back(prepared, window)
            raise
        finally:
            if second is not None:
                second.close()
                self.worker_lost = second.lost

    def _take_back(self, prepared: Iterable[Prepared], unmerged: list[Any]) -> None:
        """After a stop: what merging counted of the messages not taken (never written) taken back from the
        stats, and those messages counted by topic in `not_taken`."""
        counted = [p.counted for p in prepared]
        if self._merging is not None:  # stopped while merging
            counted.append(_since(self._merging, self.monitor.stats))
        for counters in counted:
            for name, counter in zip(COUNTED, counters):
                total = getattr(self.monitor.stats, name)
                total -= counter
        self.not_taken = Counter(item.topic for p in prepared for item in p.window)
        self.not_taken.update(item.topic for item in unmerged)

    def _prepare(self, window: list[Any], second: SecondProcess | None, more: Iterator[Any] | None = None) -> Prepared:
        """Step 1 for a window: extra inputs taken in first (a sample's is interpolated between the readings
        around it), every message merged; while a sample waits for a reading due at it, the window goes on
        with the messages after it (`more`, up to EXTENDED more), so that no window's end cuts a wait short;
        its complete samples handed to the stages."""
        with interruptible():
            self._merging = _counters(self.monitor.stats)
            for item in window:
                self._take_input(item)
            merged: list[Merged | dict[str, float] | Failed | None] = []
            inputs: list[Any] = []
            for item in window:
                self._merge_one(item, merged, inputs)
            if more is not None:
                self._extend(window, more, merged, inputs)
            # none waits any more, or the stream ended, or the window went on EXTENDED messages: what is in, they take
            _read(merged, self.waiting.release(math.inf, everything=True))
            samples = [outcome for outcome in merged if isinstance(outcome, Merged)]
            values = [s.inputs for s in samples] if self.monitor.inputs else None
            job = ([s.sample for s in samples], values, [s.header for s in samples], self.batched)
            if second is not None:
                second.submit(*job)
            else:
                self._encoded = self.stages.run(*job).encoded()
            counted, self._merging = _since(self._merging, self.monitor.stats), None
            return Prepared(window, merged, inputs, counted)

    def _extend(self, window: list[Any], more: Iterator[Any], merged: list[Any], inputs: list[Any]) -> None:
        """The window gone on with the messages after it while a sample waits for a reading (EXTENDED at most)."""
        for _ in range(EXTENDED):
            item = next(more, None) if len(self.waiting) else None
            if item is None:
                return
            window.append(item)
            self._take_input(item)
            self._merge_one(item, merged, inputs)

    def _take_input(self, item: Any) -> None:
        """An extra input's message (a shaft temperature), taken in ahead of the samples' merging."""
        spec = self.input_specs.get(item.topic)
        if spec is not None:
            self.monitor.on_input(spec, fields.message_seconds(item.message, item.log_time), item.message)

    def _merge_one(self, item: Any, merged: list[Any], inputs: list[Any]) -> None:
        """A message merged (appended to the window's `merged`, with the diagnostics due at it to `inputs`); the
        samples the wait for their readings releases then put in their places, with their readings."""
        outcome = self._merge_item(item)
        merged.append(outcome)
        now = item.log_time * 1e-9
        key = len(merged) - 1
        _read(merged, self.waiting.add(key, outcome.sample, now) if isinstance(outcome, Merged) else
              self.waiting.release(now))
        inputs.append(self._inputs_due(item))

    def _inputs_due(self, item: Any) -> tuple[float, Any] | None:
        """The arrival of a winch message's cables, and where /diagnostics are due at this message, the
        inputs' status as merging has left them (it runs windows second of the rest)."""
        now = item.log_time * 1e-9
        if item.msgtype == fields.JOINT_STATE:
            names = list(getattr(item.message, "name", []))
            self.reporter.note_readings([CABLE_NAMES.index(n) for n in names if n in CABLE_NAMES], now)
        if now < self.diagnostics_due:
            return None
        self.diagnostics_due = now + DIAGNOSTICS_PERIOD
        return now, winch_view(self.monitor, self.reporter.rates(now))

    def _take(self, prepared: Prepared, second: SecondProcess | None) -> Iterator[tuple[Any, Result, list[Record]]]:
        """The window's messages in log order with what became of them, and the diagnostics due there; the
        samples' residuals encoded together, and their scenes drawn, once every message is taken, and the
        sensor messages' residuals encoded together."""
        with interruptible():
            encoded = iter(second.take() if second is not None else self._encoded)
        results: list[Result | Residuals] = []  # a sensor message's residuals: encoded below
        diagnostics: list[list[Record]] = []
        for item, outcome, due in zip(prepared.window, prepared.merged, prepared.inputs):
            try:
                result = self._result(item, outcome, encoded)
            except Exception as error:
                result = Failed.of(error)
            residuals = result.outcome.residuals if isinstance(result, Encoded) else result
            if isinstance(residuals, Residuals):
                self.reporter.note_residuals(residuals)
            results.append(result)
            diagnostics.append([] if due is None else [self._diagnostics(item, *due)])
        # the residuals of the window's samples and sensor messages, each with its header stamp (a sensor message
        # whose stamp cannot be read: failed), encoded together
        measured: list[tuple[int, Residuals, fields.Stamp]] = []
        for k, result in enumerate(results):
            if isinstance(result, Encoded) and result.outcome.residuals is not None:
                measured.append((k, result.outcome.residuals, prepared.merged[k].header))
            elif isinstance(result, Residuals):
                item = prepared.window[k]
                try:
                    measured.append((k, result, fields.message_stamp(item.message, item.log_time)))
                except Exception as error:
                    results[k] = Failed.of(error)
        written = dict(zip((k for k, _, _ in measured),
                           stacked.residual_records([header for _, _, header in measured], [r for _, r, _ in measured])))
        for k, result in enumerate(results):
            if isinstance(result, Encoded):
                try:
                    results[k] = finished(result, prepared.merged[k].header, self.stages.builder,
                                          [written[k]] if k in written else [])
                except Exception as error:
                    results[k] = Failed.of(error)
            elif isinstance(result, Residuals):
                results[k] = Measured(result, [written[k]])
        yield from zip(prepared.window, results, diagnostics)

    def _diagnostics(self, item: Any, now: float, winch: WinchView) -> Record:
        last = self.last_view or sample_view(None, self.monitor.fusing, self.monitor.model.channels)
        values = self.reporter.build(self.monitor, now, divmod(item.log_time, 1_000_000_000), last=last, winch=winch)
        return diagnostics_record(values)

    def _merge_item(self, item: Any) -> Merged | dict[str, float] | Failed | None:
        """Step 1 for one message: a winch message merged (its complete sample, if it makes one), a
        sensor's readings kept for the samples to come (and returned, for its residuals)."""
        if item.msgtype != fields.JOINT_STATE:
            if self.monitor.model.channels.on_topic(item.topic) and item.topic not in self.input_specs:
                try:
                    stamp = fields.message_seconds(item.message, item.log_time)
                except Exception:
                    return None
                values = self.monitor.read_channels(item.topic, item.message)
                self.monitor.keep_reading(stamp, values)
                return values
            return None
        try:
            sample = self.monitor.merge_winch(fields.joint_sample(item.message, item.topic, item.log_time * 1e-9))  # arrival
        except Exception as error:
            return Failed.of(error)
        return None if sample is None else Merged(sample, self.monitor.inputs_at(sample.stamp), fields.stamp_of(item.message))

    def _result(self, item: Any, outcome: Merged | dict[str, float] | Failed | None,
                encoded: Iterator[Encoded]) -> Result | Residuals:
        msg = item.message
        if item.msgtype == fields.JOINT_STATE:
            if isinstance(outcome, Failed):
                return outcome
            if outcome is None:
                return None
            assert isinstance(outcome, Merged)  # a winch message merges into a sample, or fails, or waits
            done = next(encoded)
            self.monitor.note(done.outcome)
            self.last_view = done.view or self.last_view
            return done  # finished (its residuals and scene) once the window is taken
        if item.topic in self.input_specs:
            return None  # taken in ahead of the window's samples
        values = outcome if isinstance(outcome, dict) else None
        return self.monitor.on_measurement(item.topic, fields.message_seconds(msg, item.log_time), msg, keep=False,
                                   values=values)
