"""What the monitor fuses with each sample's lengths: the latest readings of every channel, and which
sensors it still trusts.

A sensor is a load pin (one channel) or a topic's instrument (the inclinometer's roll and
pitch, the position gauge's x, y and depth, a user's declared channel). A reading is
fused with the samples stamped within the staleness limit of it; the depth gauge's is
first carried to the sample's stamp by the payout since it was taken (the platform hangs
on vertical ropes: its depth follows the mean payout), as a stale depth reading of a
moving platform would otherwise be centimetres off. A sensor whose reading
disagrees with the estimate beyond its Mahalanobis gate for `hold` seconds is left out
(`model.gate.HeldGate`), and taken back once it has agreed as long: while left out, it is
judged by what taking it in would cost the estimate (`gate_taken_in`), not by its reading
against a prediction from the others as if that prediction were exact.
"""
from __future__ import annotations

import math
from functools import lru_cache
from typing import Mapping

from .. import channels
from ..model.estimation import Estimate
from ..model.gate import DEFAULT_PROBABILITY, GateResult, HeldGate, chi_square_threshold

CARRIED = {"depth": -1.0}  # channel: its change per metre of mean payout (the shaft's z axis points up)
DEFAULT_HOLD = 1.0  # [s] a sensor fails (or passes) its gate this long before it is left out (taken back)
TRIALS_PER_HOLD = 4  # a left-out sensor is tried this often per hold time (one sensor at a time)


_SENSORS: dict[str, str] = {}  # declared channel -> its sensor (a declared channel keeps its topics)


def sensor_of(channel: str) -> str:
    """The sensor a channel belongs to: a load pin is its own, any other channel its topic's instrument."""
    sensor = _SENSORS.get(channel)
    if sensor is not None:
        return sensor
    if channel in channels.TENSION_CHANNELS:
        sensor = channel
    else:
        try:
            sensor = channels.get(channel).topics[0]
        except KeyError:  # not declared (yet): its own sensor, not remembered
            return channel
    _SENSORS[channel] = sensor
    return sensor


def sensors_used(estimate: Estimate) -> list[str]:
    """The sensors whose channels an estimate used, in the channels' declared order."""
    return list(_sensors_used(estimate.used, channels.names()))


@lru_cache(maxsize=256)  # every fused sample asks; a recording uses a few sets of channels
def _sensors_used(used_names: tuple[str, ...], declared: tuple[str, ...]) -> tuple[str, ...]:
    used = set(used_names)
    ordered = [name for name in declared if name in used] + sorted(used - set(declared))
    return tuple(dict.fromkeys(sensor_of(name) for name in ordered))


class LatestReadings:
    """The latest finite reading of each channel read off a sensor topic, with its stamp and the mean
    payout [m] then."""

    def __init__(self, staleness: float):
        self.staleness = staleness
        self.values: dict[str, tuple[float, float, float]] = {}

    def add(self, stamp: float, values: Mapping[str, float], payout: float) -> None:
        for name, value in values.items():
            if math.isfinite(value) and math.isfinite(stamp):
                self.values[name] = (stamp, value, payout)

    def at(self, stamp: float, payout: float) -> dict[str, float]:
        """The readings stamped within the staleness limit of `stamp`, carried to the mean payout then."""
        out = {}
        for name, (taken, value, then) in self.values.items():
            if abs(stamp - taken) <= self.staleness:
                carry = CARRIED.get(name, 0.0) * (payout - then) if carry_known(payout, then) else 0.0
                out[name] = value + carry
        return out


def carry_known(payout: float, then: float) -> bool:
    return math.isfinite(payout) and math.isfinite(then)


class SensorGates:
    """One held Mahalanobis gate per sensor: which sensors are trusted, and which are left out now."""

    def __init__(self, hold: float = DEFAULT_HOLD, probability: float = DEFAULT_PROBABILITY):
        if not (math.isfinite(hold) and hold >= 0.0):
            raise ValueError(f"gate hold time must be a finite number of seconds >= 0, got {hold!r}")
        self.hold, self.probability = hold, probability
        self.gates: dict[str, HeldGate] = {}
        self.last_chi_square: dict[str, float] = {}
        self._refused: tuple[str, ...] = ()  # kept as the gates change: every sample asks
        self._slot: int | None = None  # the last trial's TRIALS_PER_HOLD-th of a hold time
        self._turn = 0  # trials so far: the left-out sensors take turns

    def trusted(self, measured: Mapping[str, float]) -> dict[str, float]:
        """The measured channels of the sensors not left out."""
        if not self._refused:
            return dict(measured)
        return {name: value for name, value in measured.items() if sensor_of(name) not in self._refused}

    @property
    def refused(self) -> tuple[str, ...]:
        """The sensors left out now."""
        return self._refused

    def update(self, stamp: float, normalised: Mapping[str, float],
               taken_in: Mapping[str, GateResult] | None = None) -> None:
        """Each sensor's verdict at `stamp`: a sensor the estimate used by its channels' (measured -
        predicted) / sigma, one left out by its gate from `taken_in` (`gate_taken_in`)."""
        grouped: dict[str, list[float]] = {}
        for name, value in normalised.items():
            if math.isfinite(value):
                sensor = sensor_of(name)
                if sensor in grouped:
                    grouped[sensor].append(value)
                else:
                    grouped[sensor] = [value]
        verdicts: dict[str, tuple[float, bool]] = {}
        for sensor, values in grouped.items():  # normalised residuals: d^2 is their sum of squares
            chi_square = values[0] * values[0] if len(values) == 1 else math.fsum(v * v for v in values)
            verdicts[sensor] = chi_square, chi_square <= chi_square_threshold(len(values), self.probability)
        for sensor, gate in (taken_in or {}).items():
            verdicts[sensor] = gate.chi_square, gate.passed
        changed = False
        for sensor, (chi_square, passed) in verdicts.items():
            self.last_chi_square[sensor] = chi_square
            gate = self.gates.get(sensor)
            if gate is None:
                gate = self.gates[sensor] = HeldGate(self.hold)
            trusted = gate.trusted
            changed |= gate.update(stamp, passed) != trusted
        if changed:
            self._refused = tuple(sorted(s for s, gate in self.gates.items() if not gate.trusted))

    def trial(self, stamp: float, measured: Mapping[str, float]) -> tuple[str, dict[str, float]] | None:
        """The left-out sensor to try taking back in at `stamp`, with its readings (None: none now). A trial
        estimates the sample again, so the sensors take turns, TRIALS_PER_HOLD times per hold time:
        a sensor of k left out is tried every k / TRIALS_PER_HOLD hold times."""
        if not self._refused:
            return None
        left_out: dict[str, dict[str, float]] = {}
        for name, value in measured.items():
            sensor = sensor_of(name)
            if sensor in self._refused:
                left_out.setdefault(sensor, {})[name] = value
        slot = math.floor(stamp * TRIALS_PER_HOLD / self.hold) if self.hold > 0.0 else None
        if not left_out or (slot is not None and slot == self._slot):
            return None
        self._slot, self._turn = slot, self._turn + 1
        sensor = sorted(left_out)[self._turn % len(left_out)]
        return sensor, left_out[sensor]
