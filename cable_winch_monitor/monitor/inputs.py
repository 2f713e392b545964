"""Merging the winches' joint states by cable name, with every rejected value accounted for."""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any, NamedTuple, cast

import numpy as np

from ..model.plantfile.plant import CABLE_NAMES

CABLE_INDEX = {name: i for i, name in enumerate(CABLE_NAMES)}
NAN = float("nan")
UNIT_QUATERNION_TOLERANCE = 0.01


class JointSample(NamedTuple):
    """One sensor_msgs/JointState, as plain values (stamp in seconds)."""

    stamp: float
    names: Sequence[str]
    positions: Sequence[float]
    velocities: Sequence[float] = ()
    efforts: Sequence[float] = ()
    topic: str = "/winch/joint_states"
    received: float = NAN  # when it arrived [s]: node clock live, log time in replay (NaN: not known)


class CableReading(NamedTuple):
    length: float
    stamp: float
    velocity: float = NAN
    tension: float = NAN
    received: float = NAN


@dataclass(frozen=True)
class StampWindow:
    """How far a winch stamp may lie from the clock and from the other winches [s].

    `ahead` and `behind` bound the stamp against the time the message arrived (the node
    clock live, the log time in replay); `skew` bounds it against the newest reading of
    the other winches that are still reporting. A stamp outside is refused before it can
    become the reading later stamps are compared with, so a far-future stamp costs one
    message, not the cable. Without an arrival time (offline use) only the order of the
    stamps is checked: nothing else tells a pause from a bad stamp. `offset` is how far the
    arrival clock runs ahead of the stamps' clock throughout (a recording whose recorder and
    winches kept different clocks: messages.clock); arrivals are judged less it.
    """

    ahead: float = 2.0
    behind: float = 10.0
    skew: float = 2.0
    offset: float = 0.0

    def __post_init__(self) -> None:
        for name in ("ahead", "behind", "skew"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"stamp window '{name}' must be a positive number of seconds, got {value}")
        if not math.isfinite(self.offset):
            raise ValueError(f"stamp window offset must be a number of seconds, got {self.offset}")

    def holds(self, lag: float) -> bool:
        """A stamp `lag` seconds before its arrival (less the offset) lies within the window."""
        return -self.ahead <= lag - self.offset <= self.behind


@dataclass(frozen=True)
class InputLimits:
    """Largest plausible payout [m] and payout speed [m/s] of a winch."""

    max_length: float = math.inf
    max_speed: float = math.inf


@dataclass
class MergeResult:
    """What one message did: the cables it updated, or why it was refused; names it ignored."""

    accepted: list[int] = field(default_factory=list)
    rejected: str = ""
    ignored: list[str] = field(default_factory=list)


class CableLengthMerger:
    """Latest length of each cable from whichever topic reported it.

    A message is refused whole, with a reason, when its names repeat, its arrays do not
    match its names, a length or speed is not finite or beyond the plant's limits, its
    stamp lies outside the plausible window (`StampWindow`), or a stamp is not newer than
    that cable's last reading: a bad sample is skipped, not patched. Names that are not
    cables (other joints of a winch) are ignored and counted.
    """

    def __init__(self, staleness: float, window: StampWindow | None = None, limits: InputLimits | None = None):
        self.staleness = staleness
        self.window = window or StampWindow()
        self.limits = limits or InputLimits()
        self.readings: list[CableReading | None] = [None] * 4

    def _stamp_reason(self, cable: int, stamp: float, received: float, others: list[float]) -> str:
        """Why `stamp` is implausible for `cable` ('' if it is not); `others` are the stamps of the other
        winches still reporting (`_reporting_others`)."""
        name, window = CABLE_NAMES[cable], self.window
        if math.isfinite(received):
            received -= window.offset
            if stamp - received > window.ahead:
                return (f"stamp ahead of the clock: {name} at {stamp:.6f} s is {stamp - received:.6g} s after its "
                        f"arrival (window {window.ahead:g} s)")
            if received - stamp > window.behind:
                return (f"stamp behind the clock: {name} at {stamp:.6f} s is {received - stamp:.6g} s before its "
                        f"arrival (window {window.behind:g} s)")
        if others and stamp - max(others) > window.skew:
            return (f"stamp ahead of the other winches: {name} at {stamp:.6f} s is {stamp - max(others):.6g} s "
                    f"after their newest reading (window {window.skew:g} s)")
        previous = self.readings[cable]
        if previous is not None and stamp <= previous.stamp and not self._implausible(cable, previous):
            return f"stamp not increasing: {name} at {stamp:.6f} s after {previous.stamp:.6f} s"
        return ""

    def _reporting_others(self, in_message: dict[int, int], received: float) -> list[float]:
        """Stamps of the readings of cables not in this message that arrived within the staleness limit."""
        if not math.isfinite(received):
            return []
        return [r.stamp for i, r in enumerate(self.readings) if i not in in_message and r is not None
                and math.isfinite(r.received) and received - r.received <= self.staleness]

    def _implausible(self, cable: int, reading: CableReading) -> bool:
        """A kept reading the other winches now show to be ahead of time: it must not block its cable."""
        others = [r.stamp for i, r in enumerate(self.readings) if i != cable and r is not None]
        return bool(others) and reading.stamp - max(others) > self.window.skew

    def _value_reason(self, cable: int, length: float, velocity: float) -> str:
        """Why a length or payout speed is not plausible ('' if both are)."""
        name, limits = CABLE_NAMES[cable], self.limits
        if not math.isfinite(length) or length <= 0.0:
            return f"bad length: {name} = {length}"
        if length > limits.max_length:
            return f"bad length: {name} = {length:.6g} m beyond the maximum payout {limits.max_length:g} m"
        if math.isnan(velocity):
            return ""  # not reported
        if not math.isfinite(velocity) or abs(velocity) > limits.max_speed:
            return f"bad payout speed: {name} = {velocity:.6g} m/s (at most {limits.max_speed:g} m/s)"
        return ""

    def _check(self, sample: JointSample) -> tuple[dict[int, int], list[str], str]:
        """Cable -> index in the message, ignored names, and the reason to refuse ('' if none)."""
        names = tuple(sample.names)
        if len(sample.positions) != len(names):
            return {}, [], f"malformed message: {len(sample.positions)} positions for {len(names)} names"
        where, not_cables, repeated = _layout(names)
        if repeated:
            return {}, [], f"duplicate cable names: {', '.join(repeated)} in one message"
        if not math.isfinite(sample.stamp):
            return {}, [], f"bad stamp: {sample.stamp}"
        cables, ignored = dict(where), list(not_cables)
        velocities = sample.velocities if len(sample.velocities) == len(names) else None
        others = self._reporting_others(cables, sample.received)
        for cable, k in cables.items():
            velocity = NAN if velocities is None else float(velocities[k])
            reason = (self._value_reason(cable, float(sample.positions[k]), velocity)
                      or self._stamp_reason(cable, sample.stamp, sample.received, others))
            if reason:
                return {}, ignored, reason
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
                                                NAN if efforts is None else efforts[k], sample.received)
        return MergeResult(accepted=sorted(cables), ignored=ignored)

    def complete(self, stamp: float) -> tuple[np.ndarray | None, str]:
        """The four lengths at `stamp` if all are known and none is older than the staleness limit.

        Winches that report separately are not sampled at the same instant: 0.1 s apart at
        0.5 m/s payout is a 5 cm synchronisation error that is not there. Each reading is
        carried forward to `stamp` with its reported payout speed, where it has one.
        """
        if None in self.readings:
            return None, "waiting for " + ", ".join(CABLE_NAMES[i] for i, r in enumerate(self.readings) if r is None)
        readings = cast(list[CableReading], self.readings)  # none is None (above)
        if any(abs(stamp - r.stamp) > self.staleness for r in readings):
            return None, "stale: " + ", ".join(f"{CABLE_NAMES[i]} ({stamp - r.stamp:.3f} s old)"
                                               for i, r in enumerate(readings)
                                               if abs(stamp - r.stamp) > self.staleness)
        return np.array([r.length + (r.velocity * (stamp - r.stamp) if math.isfinite(r.velocity) else 0.0)
                         for r in readings]), ""

    def measured_tensions(self) -> np.ndarray:
        """Load-pin tensions of the latest readings [N] (NaN where not measured)."""
        return np.array([NAN if r is None else r.tension for r in self.readings])


def measurement_reason(message: Any, limits: InputLimits) -> str:
    """Why a sensor message holds an absurd orientation or position ('' if it does not, or has neither)."""
    orientation, point = getattr(message, "orientation", None), getattr(message, "point", None)
    if orientation is not None:
        return orientation_reason([_number(orientation, axis) for axis in "xyzw"])
    if point is not None:
        return position_reason([_number(point, axis) for axis in "xyz"], limits)
    return ""


def _number(value: Any, name: str) -> float:
    try:
        return float(getattr(value, name))
    except (AttributeError, TypeError, ValueError):
        return NAN


def orientation_reason(quaternion_xyzw: Sequence[float]) -> str:
    """Why a measured orientation is not a unit quaternion ('' if it is one, to within 1 %)."""
    norm = math.sqrt(math.fsum(v * v for v in quaternion_xyzw)) if all(map(math.isfinite, quaternion_xyzw)) else NAN
    if not abs(norm - 1.0) <= UNIT_QUATERNION_TOLERANCE:
        return f"bad measurement: orientation is not a unit quaternion (norm {norm:.6g})"
    return ""


def position_reason(xyz: Sequence[float], limits: InputLimits) -> str:
    """Why a measured position is absurd ('' if it is not): z must be finite (x, y may be NaN: a depth
    gauge measures z only) and no coordinate farther than twice the maximum payout from the shaft origin."""
    reach = 2.0 * limits.max_length
    if not math.isfinite(xyz[2]) or any(math.isinf(v) or abs(v) > reach for v in xyz):
        return f"bad measurement: position {tuple(xyz)} not finite or beyond {reach:g} m"
    return ""


@lru_cache(maxsize=64)  # a winch names its joints alike in every message
def _layout(names: tuple[str, ...]) -> tuple[tuple[tuple[int, int], ...], tuple[str, ...], tuple[str, ...]]:
    """Where a message's cables are ((cable, index in the message), ...), the names that are not cables,
    and the names given more than once."""
    repeated = tuple(sorted({n for n in names if names.count(n) > 1}))
    return (tuple((CABLE_INDEX[n], k) for k, n in enumerate(names) if n in CABLE_INDEX),
            tuple(n for n in names if n not in CABLE_INDEX), repeated)


def small_mean(values: Sequence[float]) -> float:
    """The mean of fewer than eight floats, bit for bit as numpy.mean gives it (numpy adds so few in
    order, from 0.0), without numpy's cost per call, which is most of it for four values."""
    if not 0 < len(values) < 8:
        raise ValueError(f"small_mean takes 1 to 7 values, got {len(values)}")
    total = 0.0
    for value in values:
        total += value
    return total / len(values)


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
