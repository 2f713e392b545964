"""What the monitor fuses with each sample's lengths: the latest readings of every channel, and which
sensor each belongs to.

A sensor is a load pin (one channel) or a topic's instrument (the inclinometer's roll and
pitch, the position gauge's x, y and depth, a user's declared channel). A reading is
fused with the samples stamped within the staleness limit of it; the depth gauge's is
first carried to the sample's stamp by the payout since it was taken (the platform hangs
on vertical ropes: its depth follows the mean payout), as a stale depth reading of a
moving platform would otherwise be centimetres off. A channel whose readings repeat to
the bit is stuck and not fused (`StuckReadings`); which sensors contradict the others is
the estimator's to say (monitor.estimator).
"""
from __future__ import annotations

import math
from functools import lru_cache
from typing import Mapping

from .. import channels
from ..model.estimation import Estimate

CARRIED = {"depth": -1.0}  # channel: its change per metre of mean payout (the shaft's z axis points up)
STUCK = 5  # a sensor repeating its reading to the bit this many times running is stuck


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
    payout [m] then; a channel whose readings repeat to the bit is stuck (`StuckReadings`) and not given."""

    def __init__(self, staleness: float):
        self.staleness = staleness
        self.values: dict[str, tuple[float, float, float]] = {}
        self.stuck = StuckReadings()

    def add(self, stamp: float, values: Mapping[str, float], payout: float) -> None:
        for name, value in values.items():
            if math.isfinite(value) and math.isfinite(stamp):
                self.values[name] = (stamp, value, payout)
                self.stuck.add(name, value, stamp)

    def at(self, stamp: float, payout: float) -> tuple[dict[str, float], dict[str, float]]:
        """The readings stamped within the staleness limit of `stamp`, carried to the mean payout then, and
        the stamp each was taken at (a stuck channel's left out)."""
        out, taken = {}, {}
        for name, (when, value, then) in self.values.items():
            if abs(stamp - when) <= self.staleness and not self.stuck.is_stuck(name):
                carry = CARRIED.get(name, 0.0) * (payout - then) if carry_known(payout, then) else 0.0
                out[name] = value + carry
                taken[name] = when
        return out, taken


class StuckReadings:
    """Channels whose sensor repeats its reading to the bit: no real sensor with noise does that STUCK
    times running, so such a sensor is stuck at a constant (a frozen load pin, a hung driver), whatever
    the model or the other sensors say. Its readings are not used until one differs again."""

    def __init__(self) -> None:
        self.last: dict[str, tuple[float, int, float]] = {}  # channel -> value, repeats, stamp of the first

    def add(self, name: str, value: float, stamp: float) -> None:
        last = self.last.get(name)
        if last is not None and last[0] == value:
            self.last[name] = (value, last[1] + 1, last[2])
        else:
            self.last[name] = (value, 1, stamp)

    def is_stuck(self, name: str) -> bool:
        last = self.last.get(name)
        return last is not None and last[1] >= STUCK

    def stuck(self) -> dict[str, tuple[float, float]]:
        """The stuck channels: the value each is stuck at and since when [s]."""
        return {name: (value, since) for name, (value, count, since) in self.last.items() if count >= STUCK}


def carry_known(payout: float, then: float) -> bool:
    return math.isfinite(payout) and math.isfinite(then)
