"""A bag's measurements as rows aligned with the model inputs at each measurement's own stamp.

Every measurement message is one row: a winch message (load-pin tensions) at its stamp
with the four lengths merged as the monitor merges them (carried to the stamp with the
payout speed), an inclinometer (roll, pitch) or depth-gauge message at its stamp with
the lengths and speeds interpolated between the neighbouring winch samples. Rows are in
time order, so solves can be warm-started along the trajectory.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..bagio.reader import BagReader
from ..effects import Conditions
from ..effects.sheave import motion_directions
from ..monitor import fields
from ..monitor.fields import IMU, INPUT_TOPICS, JOINT_STATE
from ..monitor.inputs import CableLengthMerger
from ..monitor.residuals import TENSION_CHANNELS, imu_channels

CHANNELS = TENSION_CHANNELS + ("roll", "pitch", "depth")
NOISE_KEYS = {channel: ("tension" if channel.startswith("tension_") else channel) for channel in CHANNELS}
KINDS = ("joint", "imu", "position")
MAX_GAP = 0.5  # [s] an inclinometer or depth sample further than this from a winch sample has no lengths


@dataclass
class Dataset:
    """Rows of measurements: time [s], kind (index into KINDS), reported lengths (n, 4), payout speeds
    (n, 4), measured channels (n, len(CHANNELS)), NaN where a row does not measure a channel."""

    bag: str
    times: np.ndarray
    kinds: np.ndarray
    lengths: np.ndarray
    speeds: np.ndarray
    measured: np.ndarray

    def __len__(self) -> int:
        return len(self.times)

    @property
    def directions(self) -> np.ndarray:
        """Direction of motion of each winch at each row, held through stops (see effects.sheave)."""
        return motion_directions(self.speeds)

    def conditions(self) -> list[Conditions]:
        return [Conditions(s, d) for s, d in zip(self.speeds, self.directions)]

    def subset(self, rows: np.ndarray) -> "Dataset":
        return Dataset(self.bag, self.times[rows], self.kinds[rows], self.lengths[rows], self.speeds[rows],
                       self.measured[rows])


def read_bag(bag: str | Path) -> Dataset:
    """Every usable measurement of a bag as a Dataset (BagError if it is not a bag)."""
    merger = CableLengthMerger(staleness=MAX_GAP)
    joints: list[tuple[float, np.ndarray, np.ndarray, np.ndarray]] = []
    others: list[tuple[float, int, np.ndarray]] = []
    for item in BagReader(bag, INPUT_TOPICS):
        msg = item.message
        stamp = fields.seconds(msg.header.stamp)
        if item.msgtype == JOINT_STATE:
            merged = merger.add(fields.joint_sample(msg, item.topic))
            lengths, _ = merger.complete(stamp)
            if merged.rejected or lengths is None:
                continue
            tensions = merger.measured_tensions()
            row = np.full(len(CHANNELS), np.nan)
            row[merged.accepted] = tensions[merged.accepted]
            speeds = np.array([r.velocity for r in merger.readings])
            joints.append((stamp, lengths, speeds, row))
        elif item.msgtype == IMU:
            values = imu_channels(fields.imu_quaternion(msg))
            others.append((stamp, 1, np.array([np.nan] * 4 + [values["roll"], values["pitch"], np.nan])))
        else:
            others.append((stamp, 2, np.array([np.nan] * 6 + [fields.point_xyz(msg)[2]])))
    return _dataset(str(bag), joints, others)


def _dataset(bag: str, joints: list, others: list) -> Dataset:
    joints.sort(key=lambda j: j[0])
    times = np.array([j[0] for j in joints])
    lengths = np.array([j[1] for j in joints]).reshape(-1, 4)
    speeds = np.array([j[2] for j in joints]).reshape(-1, 4)
    rows_t, rows_kind, rows_l, rows_v, rows_m = [times], [np.zeros(len(times), int)], [lengths], [speeds], \
        [np.array([j[3] for j in joints]).reshape(-1, len(CHANNELS))]
    if others and len(times):
        t = np.array([o[0] for o in others])
        nearest = np.abs(times[np.clip(np.searchsorted(times, t), 0, len(times) - 1)] - t)
        before = np.abs(times[np.clip(np.searchsorted(times, t) - 1, 0, len(times) - 1)] - t)
        keep = (np.minimum(nearest, before) <= MAX_GAP) & (t >= times[0]) & (t <= times[-1])
        keep &= np.array([np.isfinite(o[2]).any() for o in others])
        t = t[keep]
        kept = [o for o, k in zip(others, keep) if k]
        rows_t.append(t)
        rows_kind.append(np.array([o[1] for o in kept], int))
        rows_l.append(np.column_stack([np.interp(t, times, lengths[:, i]) for i in range(4)]).reshape(-1, 4))
        rows_v.append(np.column_stack([np.interp(t, times, np.nan_to_num(speeds[:, i])) for i in range(4)])
                      .reshape(-1, 4))
        rows_m.append(np.array([o[2] for o in kept]).reshape(-1, len(CHANNELS)))
    all_t = np.concatenate(rows_t)
    order = np.argsort(all_t, kind="stable")
    return Dataset(bag, all_t[order], np.concatenate(rows_kind)[order], np.concatenate(rows_l)[order],
                   np.concatenate(rows_v)[order], np.concatenate(rows_m)[order])
