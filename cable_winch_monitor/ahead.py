"""A second process that estimates replay's next window while this one publishes the current one.

A fused replay spends about a third of its time in the estimator (`recording_batch`) and
the rest in work that must run in log order: the alarms, the sensor gates, the output
records and the writing. The estimator of a window needs only the window's merged samples
and the sensors trusted when it starts, so a forked process estimates window k+1 while
this one publishes window k. What comes back are arrays (`BatchEstimate`, the clearances,
what each channel reads), not one object per sample: pickling those would cost as much as
the estimate; and each sample's records as the bytes the replay writes (`Published`): the
pose, /tf and tension, which its solution alone decides, and the collision alarm and the
scene, which the worker encodes with an alarm tracker and a scene throttle of its own and
the replay takes where it raises the same alarm there (else it encodes its own). What goes
there are arrays too: the samples' conditions packed (`PackedConditions`). A chunk's results
(2 MB for 909 samples) come back through a file (`SPOOL`), not the pool's pipe: a thread of
the replaying process reads that pipe, and it needs the interpreter lock for every 64 kB, so
the worker waited up to 40 ms to hand over a chunk before it could start the next.

Only a fork can start it (the process inherits the plant model as it is, effects from a
user's module included, without pickling it); where the platform has none, or the worker
process is lost, the window is estimated in the replaying process as before. The worker ignores Ctrl-C:
replay stops it when it stops.
"""
from __future__ import annotations

import multiprocessing
import os
import pickle
import shutil
import signal
import tempfile
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from contextlib import suppress
from dataclasses import replace
from typing import Mapping, NamedTuple, Sequence

import numpy as np

from .bagio.fields import Stamp
from .bagio.records import Record, alarm_record, scene_records, solution_records
from .bagio.scene import SceneBuilder, SceneThrottle
from .effects import PlantModel
from .effects.estimate import recording_batch
from .model.conditions import Conditions
from .model.estimation import BatchEstimate, Estimate
from .model.plant import Plant
from .monitor.alarm import Alarm, AlarmLevel, AlarmPolicy, AlarmTracker
from .monitor.clearance import Clearance, solution_clearances

SPOOL = "/dev/shm"  # where the worker's results are written, if the system has it (memory, not a disk)
_worker: "Publisher | None" = None  # the worker's state, made at the fork from the replay's


def _start(worker: "Publisher") -> None:
    global _worker
    _worker = worker
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


class PackedClearances(NamedTuple):
    """Samples' clearances as arrays, to send back: each posed sample's value, outline point and that
    point in `shaft`; the others' (a single-cable swing, none) as they are. Unpacked, the same values."""

    values: np.ndarray  # (N,)
    points: list[int]   # index in the plant's outline
    shaft: np.ndarray   # (N, 3)
    others: dict[int, Clearance | None]

    @classmethod
    def of(cls, plant: Plant, clearances: Sequence[Clearance | None], posed: Sequence[bool]) -> "PackedClearances":
        index = {point.name: k for k, point in enumerate(plant.outline)}
        rows = [(c.value, index[c.point_name], c.point_shaft) if ok else (np.nan, -1, np.full(3, np.nan))
                for c, ok in zip(clearances, posed)]
        values, points, shaft = zip(*rows) if rows else ((), (), ())
        return cls(np.array(values, dtype=float), list(points), np.array(shaft, dtype=float).reshape(-1, 3),
                   {i: c for i, (c, ok) in enumerate(zip(clearances, posed)) if not ok})

    def unpacked(self, plant: Plant) -> list[Clearance | None]:
        names, body = [point.name for point in plant.outline], plant.outline_array
        return [self.others[i] if k < 0 else Clearance(value, names[k], body[k], shaft)
                for i, (value, k, shaft) in enumerate(zip(self.values.tolist(), self.points, self.shaft))]


class Published(NamedTuple):
    """A sample's records as the worker encoded them: those its solution alone decides (pose, /tf,
    tension), and those the alarm decides (the collision alarm, the scene where one was due there):
    valid where the replay raises the same `alarm` (level, reason) at the sample."""

    solution: list[Record]
    alarm: tuple[AlarmLevel, str]
    alarm_record: Record
    scene: list[Record] | None  # None: no scene was due there

    @staticmethod
    def key(alarm: Alarm) -> tuple[AlarmLevel, str]:
        """What of an alarm its records depend on beyond the sample's solution and clearance."""
        return alarm.level, alarm.reason

    def encoded_for(self, alarm: Alarm) -> bool:
        """Whether the alarm and scene records were encoded for `alarm`."""
        return self.alarm == self.key(alarm)


class Ahead(NamedTuple):
    """What the worker sends back for a chunk: the estimator's arrays (without the plant: the caller has
    it), the clearances, what each channel reads at each state, and each sample's records."""

    batch: BatchEstimate
    clearances: PackedClearances
    predicted: dict[str, np.ndarray]
    published: list[Published]


class Estimated(NamedTuple):
    """A chunk's estimates from the worker, with their clearances, predictions and records."""

    estimates: list[Estimate]
    clearances: list[Clearance | None]
    predicted: dict[str, np.ndarray]
    published: list[Published]


class Publisher:
    """The worker: estimates a chunk, and encodes its samples' records with an alarm tracker and a scene
    throttle of its own, which follow the samples it sees in order as the replay's follow them all."""

    def __init__(self, model: PlantModel, plant: Plant, scene_rate: float):
        self.model = model
        self.alarms = AlarmTracker(AlarmPolicy.from_plant(plant))
        self.builder, self.throttle = SceneBuilder(plant), SceneThrottle(scene_rate)

    def chunk(self, reported: np.ndarray, measured: Mapping[str, np.ndarray], packed: PackedConditions,
              stamps: Sequence[Stamp], times: Sequence[float]) -> Ahead:
        conditions = packed.unpacked()
        batch = recording_batch(self.model, reported, measured, conditions)
        estimates = batch.estimates()
        solutions = [e.solution for e in estimates]
        clearances = solution_clearances(self.model.physical, solutions)
        published = []
        for stamp, time, estimate, clearance in zip(stamps, times, estimates, clearances):
            alarm = self.alarms.update(estimate.solution, clearance)
            scene = scene_records(stamp, self.builder, estimate.solution, alarm) if self.throttle.due(time) else None
            published.append(Published(solution_records(stamp, estimate.solution, estimate), Published.key(alarm),
                                       alarm_record(stamp, alarm), scene))
        return Ahead(replace(batch, plant=None),
                     PackedClearances.of(self.model.physical, clearances, [s.ok for s in solutions]),
                     self.model.predict_solutions(solutions, conditions), published)


def _chunk(spool: str, *job: object) -> str | None:
    """The worker's job: a chunk's `Ahead`, pickled to a file in `spool` (its path; None where it could
    not be written: the replay then estimates the chunk itself)."""
    assert _worker is not None, "the worker was started without its state"
    ahead = _worker.chunk(*job)
    try:
        with tempfile.NamedTemporaryFile(dir=spool, delete=False) as file:
            pickle.dump(ahead, file, protocol=pickle.HIGHEST_PROTOCOL)
    except OSError:
        return None
    return file.name


def _remove_results(future: Future) -> None:
    """Remove the file a finished chunk's results were written to (none if it failed or was cancelled;
    gone already if the spool was removed)."""
    if not future.cancelled() and future.exception() is None and future.result() is not None:
        with suppress(OSError):
            os.unlink(future.result())


class AheadEstimator:
    """One worker process estimating windows for `model` (it must fuse, and not refine its geometry)."""

    def __init__(self, model: PlantModel, plant: Plant, scene_rate: float):
        self.model = model
        self.spool = tempfile.mkdtemp(prefix="cable-winch-monitor-", dir=SPOOL if os.path.isdir(SPOOL) else None)
        self.pool: ProcessPoolExecutor | None = ProcessPoolExecutor(
            1, mp_context=multiprocessing.get_context("fork"), initializer=_start,
            initargs=(Publisher(model, plant, scene_rate),))

    @staticmethod
    def available() -> bool:
        return "fork" in multiprocessing.get_all_start_methods()

    def submit(self, reported: np.ndarray, measured: Mapping[str, np.ndarray], conditions: Sequence[Conditions],
               stamps: Sequence[Stamp], times: Sequence[float]) -> Future | None:
        """Start estimating these samples (their winch messages' header `stamps`, in seconds `times`) in
        the worker; None where it is gone."""
        if self.pool is None:
            return None
        try:
            return self.pool.submit(_chunk, self.spool, reported, measured, PackedConditions.of(conditions),
                                    list(stamps), list(times))
        except BrokenProcessPool:
            self.pool = None
            return None

    def estimates(self, future: Future) -> Estimated | None:
        """What `future` was started for; None where the worker was lost or could not write its results (the
        caller estimates them itself). The estimator's own errors are raised as they would be in the caller's
        process."""
        try:
            path = future.result()
        except BrokenProcessPool:
            self.pool = None
            return None
        if path is None:
            return None
        with open(path, "rb") as file:
            batch, clearances, predicted, published = pickle.load(file)
        os.unlink(path)
        batch.plant = self.model.physical
        return Estimated(batch.estimates(), clearances.unpacked(self.model.physical), predicted, published)

    @staticmethod
    def discard(future: Future) -> None:
        """Drop what `future` was started for (the gates changed before its turn): its results' file is
        removed as soon as it is written, not left in the spool until the replay ends."""
        future.add_done_callback(_remove_results)

    def close(self) -> None:
        if self.pool is not None:
            self.pool.shutdown(wait=True, cancel_futures=True)
            self.pool = None
        shutil.rmtree(self.spool, ignore_errors=True)
