"""A bag's measurements as rows aligned with the model inputs at each measurement's own stamp.

Every measurement stamp is one row: a winch message (load-pin tensions) at its stamp
with the four lengths merged as the monitor merges them (carried to the stamp with the
payout speed), any other channel's message (inclinometer, depth gauge, a declared sensor)
at its stamp with the lengths, speeds and accelerations interpolated between the
neighbouring winch samples. Measurements stamped together (within TOGETHER: a laboratory
logger stamps its load cells and AHRS at once) are one row, estimated as one state. Each row
also carries its conditions (channels and effects
see the same ones live): speeds and accelerations differentiated over a centred window
(model.conditions), the direction of motion, and the extra inputs the plant's effects
declare, interpolated to the row's stamp. Rows are in time order, so solves can be
warm-started along the trajectory.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import cast

import numpy as np

from ..bagio.reader import BagError, BagReader
from ..channels import BUILTIN_CHANNELS, JOINT_STATE, TENSION_CHANNELS, Input
from ..effects import PlantModel
from ..messages import fields
from ..messages.topics import missing_input, require_inputs
from ..model.conditions import Conditions, derivatives, directions
from ..monitor.inputs import CableLengthMerger, CableReading

WINCH = "winches"  # the source of the winch rows (any joint-state topic)
MAX_GAP = 0.5  # [s] a sensor sample further than this from a winch sample has no lengths
TOGETHER = 1e-6  # [s] measurements whose stamps differ by less were taken together: one row


@dataclass
class Dataset:
    """Rows of measurements: time [s], source (index into `sources`: the winches, then each sensor
    topic), reported lengths (n, 4), payout speeds and accelerations (n, 4), measured channels
    (n, len(channels)) with NaN where a row does not measure a channel, and the extra inputs (n,)."""

    bag: str
    times: np.ndarray
    kinds: np.ndarray
    lengths: np.ndarray
    speeds: np.ndarray
    accelerations: np.ndarray
    measured: np.ndarray
    channels: tuple[str, ...] = BUILTIN_CHANNELS.names()
    sources: tuple[str, ...] = (WINCH,)
    inputs: dict[str, np.ndarray] = field(default_factory=dict)
    held: np.ndarray | None = None  # (n, 4) directions of motion found over the whole recording (subsets)

    def __len__(self) -> int:
        return len(self.times)

    @property
    def directions(self) -> np.ndarray:
        """Direction of motion of each winch at each row, held through stops (model.conditions): found over
        the whole recording, so that a subset's rows keep the direction their winch last moved in (a
        thinned subset may have no row of a short move)."""
        return self.held if self.held is not None else directions(self.speeds)

    def conditions(self) -> list[Conditions]:
        keys = list(self.inputs)
        values = np.column_stack([self.inputs[k] for k in keys]) if keys else np.zeros((len(self), 0))
        return [Conditions(t, s, a, d, dict(zip(keys, v.tolist())))
                for t, s, a, d, v in zip(self.times.tolist(), self.speeds, self.accelerations, self.directions, values)]

    def subset(self, rows: np.ndarray) -> Dataset:
        return Dataset(self.bag, self.times[rows], self.kinds[rows], self.lengths[rows], self.speeds[rows],
                       self.accelerations[rows], self.measured[rows], self.channels, self.sources,
                       {k: v[rows] for k, v in self.inputs.items()}, self.directions[rows])


def read_bag(bag: str | Path, model: PlantModel | None = None, optional: tuple[Input, ...] = ()) -> Dataset:
    """Every usable measurement of a bag as a Dataset: the channels of the plant `model` (without one, the
    built-in ones) and the extra inputs its effects read (BagError if it is not a bag, or lacks an input's
    topic), and the `optional` inputs it has (candidate effects of diagnose)."""
    known, inputs = (BUILTIN_CHANNELS, ()) if model is None else (model.channels, model.inputs)
    require_inputs(bag, inputs)
    required = {spec.key for spec in inputs}
    inputs = tuple(inputs) + tuple(optional)
    names = known.names()
    column = {name: k for k, name in enumerate(names)}
    tension_columns = [column[name] for name in TENSION_CHANNELS]
    topics = {**fields.input_topics(model), **{spec.topic: spec.msgtype for spec in optional}}
    sensor_topics = [t for t, kind in known.topic_types().items() if kind != JOINT_STATE]
    merger = CableLengthMerger(staleness=MAX_GAP)
    joints: list[tuple[float, np.ndarray, np.ndarray, np.ndarray]] = []
    others: list[tuple[float, int, np.ndarray]] = []
    series: dict[str, list[tuple[float, float]]] = {spec.key: [] for spec in inputs}
    by_topic = {spec.topic: [s for s in inputs if s.topic == spec.topic] for spec in inputs}
    for item in BagReader(bag, topics):
        msg = item.message
        stamp = fields.message_seconds(msg, item.log_time)
        for spec in by_topic.get(item.topic, ()):
            series[spec.key].append((stamp, spec.read(msg)))
        if item.msgtype == JOINT_STATE:
            merged = merger.add(fields.joint_sample(msg, item.topic))
            lengths, _ = merger.complete(stamp)
            if merged.rejected or lengths is None:
                continue
            tensions = merger.measured_tensions()
            row = np.full(len(names), np.nan)
            row[[tension_columns[i] for i in merged.accepted]] = tensions[merged.accepted]
            readings = cast(list[CableReading], merger.readings)  # every cable read: the lengths are complete
            joints.append((stamp, lengths, np.array([r.velocity for r in readings]), row))
        elif item.topic in sensor_topics:
            row = np.full(len(names), np.nan)
            for channel in known.on_topic(item.topic):
                assert channel.read is not None  # `on_topic` gives the channels with a reader
                row[column[channel.name]] = channel.read(msg)
            if np.isfinite(row).any():
                others.append((stamp, 1 + sensor_topics.index(item.topic), row))
    data = _dataset(str(bag), joints, others, names, (WINCH, *sensor_topics))
    for spec in inputs:
        points = np.array([p for p in series[spec.key] if np.isfinite(p[1])]).reshape(-1, 2)
        if not len(points) and spec.key not in required:
            continue
        if not len(points):
            raise missing_input(bag, spec)
        points = points[np.argsort(points[:, 0], kind="stable")]
        data.inputs[spec.key] = np.interp(data.times, points[:, 0], points[:, 1])
    return data


def require_measurements(data: Dataset) -> None:
    """Refuse (BagError) a bag that holds no measurement the model could be compared with."""
    if not len(data) or not np.isfinite(data.measured).any():
        raise BagError(f"{data.bag}: no measurements to compare the model with (load pins, inclinometer or "
                       "depth gauge readings with the four cable lengths): nothing to compare")


def _together(joints: list, others: list) -> list:
    """Sensor rows stamped together with a winch row merged into it, and with each other into one row
    (the first topic's); the rows left, in time order. Where two messages measure the same channel at
    one stamp, the first read is kept."""
    others = sorted(others, key=lambda o: o[0])
    merged: list = []
    for stamp, kind, row in others:
        if merged and stamp - merged[-1][0] <= TOGETHER:
            merged[-1] = (merged[-1][0], merged[-1][1], np.where(np.isnan(merged[-1][2]), row, merged[-1][2]))
        else:
            merged.append((stamp, kind, row))
    if not joints or not merged:
        return merged
    times = np.array([j[0] for j in joints])
    left = []
    for stamp, kind, row in merged:
        k = int(np.clip(np.searchsorted(times, stamp), 0, len(times) - 1))
        k = min((k, max(k - 1, 0)), key=lambda i: abs(times[i] - stamp))
        if abs(times[k] - stamp) <= TOGETHER:
            joints[k][3][:] = np.where(np.isnan(joints[k][3]), row, joints[k][3])
        else:
            left.append((stamp, kind, row))
    return left


def _dataset(bag: str, joints: list, others: list, names: tuple[str, ...], sources: tuple[str, ...]) -> Dataset:
    joints.sort(key=lambda j: j[0])
    others = _together(joints, others)
    times = np.array([j[0] for j in joints])
    lengths = np.array([j[1] for j in joints]).reshape(-1, 4)
    speeds, accelerations = derivatives(times, lengths, np.array([j[2] for j in joints]).reshape(-1, 4))
    rows_t, rows_kind, rows_l, rows_v, rows_a = [times], [np.zeros(len(times), int)], [lengths], [speeds], \
        [accelerations]
    rows_m = [np.array([j[3] for j in joints]).reshape(-1, len(names))]
    if others and len(times):
        t = np.array([o[0] for o in others])
        nearest = np.abs(times[np.clip(np.searchsorted(times, t), 0, len(times) - 1)] - t)
        before = np.abs(times[np.clip(np.searchsorted(times, t) - 1, 0, len(times) - 1)] - t)
        keep = (np.minimum(nearest, before) <= MAX_GAP) & (t >= times[0]) & (t <= times[-1])
        t = t[keep]
        kept = [o for o, k in zip(others, keep) if k]

        def interpolated(values: np.ndarray) -> np.ndarray:
            return np.column_stack([np.interp(t, times, values[:, i]) for i in range(4)]).reshape(-1, 4)

        rows_t.append(t)
        rows_kind.append(np.array([o[1] for o in kept], int))
        rows_l.append(interpolated(lengths))
        rows_v.append(interpolated(speeds))
        rows_a.append(interpolated(accelerations))
        rows_m.append(np.array([o[2] for o in kept]).reshape(-1, len(names)))
    all_t = np.concatenate(rows_t)
    order = np.argsort(all_t, kind="stable")
    return Dataset(bag, all_t[order], np.concatenate(rows_kind)[order], np.concatenate(rows_l)[order],
                   np.concatenate(rows_v)[order], np.concatenate(rows_a)[order], np.concatenate(rows_m)[order],
                   names, sources)
