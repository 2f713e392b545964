"""Merging the winches' joint states by cable name, with every rejected value accounted for."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple, Sequence

import numpy as np

from ..model.plant import CABLE_NAMES

CABLE_INDEX = {name: i for i, name in enumerate(CABLE_NAMES)}
NAN = float("nan")


class JointSample(NamedTuple):
    """One sensor_msgs/JointState, as plain values (stamp in seconds)."""

    stamp: float
    names: Sequence[str]
    positions: Sequence[float]
    velocities: Sequence[float] = ()
    efforts: Sequence[float] = ()
    topic: str = "/winch/joint_states"


class CableReading(NamedTuple):
    length: float
    stamp: float
    velocity: float = NAN
    tension: float = NAN


@dataclass
class MergeResult:
    """What one message did: the cables it updated, or why it was refused; names it ignored."""

    accepted: list[int] = field(default_factory=list)
    rejected: str = ""
    ignored: list[str] = field(default_factory=list)


class CableLengthMerger:
    """Latest length of each cable from whichever topic reported it.

    A message is refused whole, with a reason, when its names repeat, its arrays do not
    match its names, a length is not a finite positive number, or a stamp is not newer
    than that cable's last reading: a bad sample is skipped, not patched. Names that are
    not cables (other joints of a winch) are ignored and counted.
    """

    def __init__(self, staleness: float):
        self.staleness = staleness
        self.readings: list[CableReading | None] = [None] * 4

    def _check(self, sample: JointSample) -> tuple[dict[int, int], list[str], str]:
        """Cable -> index in the message, ignored names, and the reason to refuse ('' if none)."""
        names = list(sample.names)
        if len(sample.positions) != len(names):
            return {}, [], f"malformed message: {len(sample.positions)} positions for {len(names)} names"
        if len(set(names)) != len(names):
            repeated = sorted({n for n in names if names.count(n) > 1})
            return {}, [], f"duplicate cable names: {', '.join(repeated)} in one message"
        if not math.isfinite(sample.stamp):
            return {}, [], f"bad stamp: {sample.stamp}"
        cables = {CABLE_INDEX[n]: k for k, n in enumerate(names) if n in CABLE_INDEX}
        ignored = [n for n in names if n not in CABLE_INDEX]
        for cable, k in cables.items():
            length = float(sample.positions[k])
            if not math.isfinite(length) or length <= 0.0:
                return {}, ignored, f"bad length: {CABLE_NAMES[cable]} = {length}"
            previous = self.readings[cable]
            if previous is not None and sample.stamp <= previous.stamp:
                return {}, ignored, (f"stamp not increasing: {CABLE_NAMES[cable]} at {sample.stamp:.6f} s "
                                     f"after {previous.stamp:.6f} s")
        if not cables:
            return {}, ignored, "no cable in message: " + ", ".join(repr(n) for n in names)
        return cables, ignored, ""

    def add(self, sample: JointSample) -> MergeResult:
        cables, ignored, reason = self._check(sample)
        if reason:
            return MergeResult(rejected=reason, ignored=ignored)
        n = len(sample.names)
        positions = _floats(sample.positions)
        velocities = _floats(sample.velocities) if len(sample.velocities) == n else None
        efforts = _floats(sample.efforts) if len(sample.efforts) == n else None
        for cable, k in cables.items():
            self.readings[cable] = CableReading(positions[k], sample.stamp, NAN if velocities is None else velocities[k],
                                                NAN if efforts is None else efforts[k])
        return MergeResult(accepted=sorted(cables), ignored=ignored)

    def complete(self, stamp: float) -> tuple[np.ndarray | None, str]:
        """The four lengths at `stamp` if all are known and none is older than the staleness limit.

        Winches that report separately are not sampled at the same instant: 0.1 s apart at
        0.5 m/s payout is a 5 cm synchronisation error that is not there. Each reading is
        carried forward to `stamp` with its reported payout speed, where it has one.
        """
        if None in self.readings:
            return None, "waiting for " + ", ".join(CABLE_NAMES[i] for i, r in enumerate(self.readings) if r is None)
        if any(stamp - r.stamp > self.staleness for r in self.readings):
            return None, "stale: " + ", ".join(f"{CABLE_NAMES[i]} ({stamp - r.stamp:.3f} s old)"
                                               for i, r in enumerate(self.readings) if stamp - r.stamp > self.staleness)
        return np.array([r.length + (r.velocity * (stamp - r.stamp) if math.isfinite(r.velocity) else 0.0)
                         for r in self.readings]), ""

    def measured_tensions(self) -> np.ndarray:
        """Load-pin tensions of the latest readings [N] (NaN where not measured)."""
        return np.array([NAN if r is None else r.tension for r in self.readings])


def _floats(values: Sequence[float]) -> list[float]:
    """A message array (list, array.array or numpy array) as Python floats."""
    return values.tolist() if hasattr(values, "tolist") else [float(v) for v in values]


class InputSeries:
    """Recent values of one extra input (a shaft temperature): the value at a stamp is interpolated
    between the readings around it, or the nearest reading where the stamp lies outside them (live,
    the latest one). Readings older than HISTORY seconds before the newest are dropped."""

    HISTORY = 600.0  # [s]

    def __init__(self) -> None:
        self.stamps: list[float] = []
        self.values: list[float] = []

    def add(self, stamp: float, value: float) -> None:
        if self.stamps and stamp <= self.stamps[-1]:
            if stamp < self.stamps[-1]:  # out of order: insert, keeping the series sorted
                k = int(np.searchsorted(self.stamps, stamp))
                self.stamps.insert(k, stamp)
                self.values.insert(k, value)
            return
        self.stamps.append(stamp)
        self.values.append(value)
        if self.stamps[0] < stamp - self.HISTORY and len(self.stamps) > 2:
            cut = int(np.searchsorted(self.stamps, stamp - self.HISTORY)) - 1
            del self.stamps[:cut], self.values[:cut]

    def value_at(self, stamp: float) -> float:
        """The value at `stamp` (NaN while there is no reading)."""
        if not self.stamps:
            return NAN
        return float(np.interp(stamp, self.stamps, self.values))
