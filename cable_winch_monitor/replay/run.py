"""`replay`: a recorded bag through the monitor, every output into a new bag beside the inputs.

The monitor's code and the field mapping are the live node's own (MonitorPipeline,
messages.fields); messages are fed in the bag's log order (windows.py merges and
solves a window ahead, then takes them one at a time), so a replay gives what the node
gave. No ROS runtime is needed. Memory stays at about one chunk of
the input whatever the length of the bag. Outputs carry their input's header stamp, and
that stamp is their log time; inputs keep their own log time and bytes. The head-sheave
frames (/tf_static) and deck outlines are written once, at the first message; the 3-D scene at most
`scene_rate` times per second of recording.
"""
from __future__ import annotations

import gc
import time
from collections import Counter
from collections.abc import Iterator
from contextlib import closing, contextmanager
from dataclasses import dataclass, field
from pathlib import Path

from ..bagio.reader import BagReader, ReadReport
from ..bagio.writer import new_bag
from ..effects import PlantModel
from ..messages import fields, records
from ..messages.clock import clock_offset
from ..messages.scene import REPLAY_RATE
from ..messages.topics import require_inputs
from ..model.plantfile.plant import CABLE_NAMES, Plant, load_plant
from ..model.statics.result import SolveStatus
from ..monitor.alarm import AlarmLevel
from ..monitor.inputs import StampWindow
from ..monitor.pipeline import MonitorStats
from ..monitor.sensors import READING_LAG
from ..progress import Progress
from ..stopping import Stopped, stop_signals
from .stages import Encoded, Measured
from .windows import Failed, WindowScheduler

INVALID = "invalid input"  # the tension state of a sample whose input could not be used


@dataclass(frozen=True)
class TopicCount:
    """One input topic: read = used + rejected + skipped."""

    topic: str
    msgtype: str
    read: int
    used: int
    rejected: int
    skipped: int

    @property
    def balanced(self) -> bool:
        return self.read == self.used + self.rejected + self.skipped


@dataclass
class ReplaySummary:
    bag: Path
    out: Path
    report: ReadReport
    stats: MonitorStats
    written: Counter[str] = field(default_factory=Counter)
    errors: Counter[str] = field(default_factory=Counter)  # the monitor's exceptions (as the node's callback errors)
    wall: float = 0.0
    stopped: str = ""  # the signal that stopped it (SIGINT: Ctrl-C): the output bag holds what was replayed until then
    unsolved: dict[str, str] = field(default_factory=dict)  # tension state without a pose -> why, its first sample

    @property
    def samples(self) -> int:
        return sum(self.stats.states.values())

    @property
    def complete(self) -> bool:
        return self.report.complete and not self.stopped

    @property
    def refused(self) -> str:
        """Where every sample was invalid input (the job could not be done), why, in one line; else ''."""
        invalid = self.stats.states[INVALID]
        if not invalid or invalid < self.samples:
            return ""
        why = " ".join(self.unsolved.get(INVALID, INVALID).split())
        return f"no sample of {self.bag} could be solved: all {invalid} are {why}"

    def topics(self) -> list[TopicCount]:
        rejected: Counter[str] = Counter()
        for key, count in self.stats.rejected.items():
            rejected[key.split(": ", 1)[0]] += count
        skipped: Counter[str] = Counter()
        for (topic, _), count in self.report.skipped.items():
            skipped[topic] += count
        return [TopicCount(topic, self.report.types.get(topic, ""), self.report.read[topic], self.stats.used[topic],
                           rejected[topic], skipped[topic]) for topic in sorted(self.report.read)]

    def format(self) -> str:
        report, stats = self.report, self.stats
        lines = [f"replayed {self.bag} ({len(report.files)} file(s)) -> {self.out}"]
        lines += [f"  note: {note}" for note in report.notes]
        rows = self.topics()
        width = [max([len(name), *(len(getattr(r, name)) + 2 for r in rows)]) for name in ("topic", "msgtype")]
        lines.append(f"{'topic':<{width[0]}}{'type':<{width[1]}}{'read':>8}{'used':>8}{'rejected':>10}{'skipped':>9}")
        for row in rows:
            lines.append(f"{row.topic:<{width[0]}}{row.msgtype:<{width[1]}}{row.read:>8}{row.used:>8}{row.rejected:>10}"
                         f"{row.skipped:>9}" + ("" if row.balanced else "   <- not all accounted for"))
        lines += [f"  rejected {reason}: {n}" for reason, n in sorted(stats.rejected.items())]
        lines += [f"  skipped {topic}: {reason}: {n}" for (topic, reason), n in sorted(report.skipped.items())]
        lines += [f"  ignored joint name '{name}': {n}" for name, n in sorted(stats.ignored_names.items())]
        lines += [f"  error {what}: {n}" for what, n in sorted(self.errors.items())]
        lines.append(f"samples: {self.samples} (solved {stats.solved}, solver failures {stats.failures})")
        lines += [f"  sensor left out: {sensor} on {count} samples ({first:.1f}-{last:.1f} s): {why}"
                  for sensor, (count, first, last, why) in sorted(stats.faults.items())]
        lines.append("tension states: " + (", ".join(f"{s} {n}" for s, n in stats.states.most_common()) or "none"))
        lines += [f"  {why} (first of {stats.states[state]} samples)" for state, why in self.unsolved.items()
                  if why != state]
        lines.append("alarm levels: " + ", ".join(f"{level.name} {stats.levels[level.name]}" for level in AlarmLevel))
        lines += [f"  based on: {basis}: {n}" for basis, n in stats.bases.most_common()]
        if stats.last_error is not None:
            lengths, pins = stats.last_error
            lines.append("model error at the last sample (model minus reported length; load pin minus model): "
                         + ", ".join(f"{name} {length:+.3f} m, {pin:+.0f} N"
                                     for name, length, pin in zip(CABLE_NAMES, lengths, pins)))
        lines.append(f"written: {sum(self.written.values())} messages to {self.out} ("
                     + ", ".join(f"{t} {n}" for t, n in sorted(self.written.items())) + ")")
        rate = self.samples / self.wall if self.wall > 0 else float("nan")
        lines.append(f"wall time {self.wall:.2f} s, {rate:.0f} samples/s")
        if not report.complete:
            lines.append("PARTIAL REPLAY: parts of the bag could not be read and were skipped:")
            lines += [f"  {damage}" for damage in report.damage]
        if self.stopped:
            lines.append(f"INTERRUPTED by {self.stopped}: replay stopped after {sum(report.read.values())} messages; "
                         f"{self.out} holds what was replayed until then")
        return "\n".join(lines)


def _records(result: Encoded | Measured | None) -> list[records.Record]:
    """What the node publishes for one input message, from what became of it."""
    return [] if result is None else result.records


@contextmanager
def _fewer_collections(threshold: int = 100_000) -> Iterator[None]:
    """Let the cyclic garbage collector run every `threshold` allocations instead of every 700.

    A replay allocates a few dozen short-lived objects per message, freed by reference
    counting; at Python's default threshold the collector scanned the young objects (and
    every 10th time the older ones) so often that it took a quarter of the replay. The
    windows read ahead keep tens of thousands of objects alive, which every collection
    scans until they are promoted: at 20,000 the collections still took 80 ms of (a)'s
    replay in one process (as a fleet's replays run), at 100,000 16 ms. Memory stays
    bounded: the collector still runs, only less often. Start-up objects are frozen out
    of the scans.
    """
    before = gc.get_threshold()
    gc.freeze()
    gc.set_threshold(threshold, *before[1:])
    try:
        yield
    finally:
        gc.set_threshold(*before)
        gc.unfreeze()


def replay(bag: str | Path, out: str | Path, plant: Plant | None = None, solver: str = "energy",
           staleness: float = 0.5, progress: bool = True, batched: bool = True,
           scene_rate: float = REPLAY_RATE, stamp_window: StampWindow | None = None,
           second_process: bool = True, lag: float = READING_LAG) -> ReplaySummary:
    """Replay `bag` (rosbag2 directory or .mcap file) into the new bag `out`.

    With the energy solver and `batched`, the samples of each window of messages are
    solved at once (windows.py); the outputs are the per-sample monitor's. `second_process`
    runs the windows' stages in a second process (second_process.py) meanwhile: the same outputs, on
    two cores (a fleet of bags keeps each replay to one).

    Raises BagError (nothing written) when `bag` holds no bag, lacks a topic the plant's effects read, or
    `out` exists; damage met while reading is in the summary (`complete` False), never raised. An error
    during the replay leaves no output bag. SIGINT, SIGTERM or SIGHUP stop it (stopping.py): the output
    bag is closed with what was replayed until then, which the summary counts (`stopped`).
    """
    started = time.perf_counter()
    plant = plant or load_plant()
    require_inputs(bag, PlantModel.from_plant(plant, solver).inputs)  # a topic the effects read: before any work
    stamp_window, clock_note = clock_offset(bag, stamp_window or StampWindow())
    scheduler = WindowScheduler(plant, solver, staleness, batched, stamp_window=stamp_window,
                                second_process=second_process, scene_rate=scene_rate, lag=lag)
    inputs = fields.input_topics(scheduler.monitor.model)
    reader = BagReader(bag, inputs)
    reader.report.notes += [clock_note] if clock_note else []
    summary = ReplaySummary(Path(bag), Path(out), reader.report, scheduler.monitor.stats)
    bar = Progress("replay", reader.report.expected, enabled=progress)
    with stop_signals(), new_bag(out) as writer, _fewer_collections(), \
            closing(scheduler.run_diagnosed(reader, reader.report.expected or 0)) as taken:
        try:
            for count, (item, result, diagnostics) in enumerate(taken, 1):
                if count == 1:
                    first = divmod(item.log_time, 1_000_000_000)
                    for topic, msgtype, data in records.static_records(first, scheduler.stages.builder):
                        writer.write_raw(topic, msgtype, item.log_time, data, latched=True)
                writer.write_raw(item.topic, item.msgtype, item.log_time, item.data)
                outputs: list[records.Record] = []  # the message's outputs, stamped `log_time`
                log_time = item.log_time
                if isinstance(result, Failed):
                    summary.errors[f"{item.topic}: {result.why}"] += 1
                else:
                    try:  # a message whose stamp cannot be read, or whose outputs cannot be encoded
                        stamp = fields.message_stamp(item.message, item.log_time)
                        outputs, log_time = _records(result), fields.stamp_ns(stamp)
                    except Exception as error:
                        summary.errors[f"{item.topic}: {Failed.of(error).why}"] += 1
                    else:
                        if isinstance(result, Encoded) and result.outcome.status is not SolveStatus.SOLVED:
                            summary.unsolved.setdefault(result.outcome.tension_state, result.outcome.failure)
                writer.write_records(log_time, outputs)
                writer.write_records(item.log_time, diagnostics)
                bar.update(count)
        except KeyboardInterrupt as stop:
            summary.stopped = stop.signal if isinstance(stop, Stopped) else "SIGINT"
            reader.report.read -= scheduler.not_taken
        finally:
            bar.finish()
            if scheduler.worker_lost:
                reader.report.notes.append(f"second process given up ({scheduler.worker_lost}): the rest was "
                                           "replayed in this process")
            summary.written = Counter({t: n for t, n in writer.counts.items() if t not in inputs})
    summary.wall = time.perf_counter() - started
    return summary
