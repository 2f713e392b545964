"""What the monitor fuses with each sample's lengths: the latest readings of every channel, and which
sensor each belongs to.

A sensor is a load pin (one channel) or a topic's instrument (the inclinometer's roll and
pitch, the position gauge's x, y and depth, a user's declared channel). A sample fuses
each channel's latest reading stamped at or before it, within the staleness limit; the depth gauge's is
first carried to the sample's stamp by the payout since it was taken (the platform hangs
on vertical ropes: its depth follows the mean payout), as a stale depth reading of a
moving platform would otherwise be centimetres off. A channel whose readings repeat to
the bit is stuck and not fused (`StuckReadings`); which sensors contradict the others is
the estimator's to say (monitor.estimator).

What a sample takes depends only on the readings' stamps, not on when they came, once every
reading stamped at or before it is in: a channel's reading is *due* at a sample when its next one,
a period after its latest, is stamped at or before the sample (`LatestReadings.due`). The node
and replay hold a sample while one is due (monitor.waiting), so that both fuse the same readings
whatever order the topics came in.

"Before it" is `lag` seconds before its stamp (READING_LAG): a sample fuses the readings stamped at
least that long before it, which are in when its winch message comes unless a sensor's topic runs
later than the winches' by more than that. A sensor sampled as fast as the winches, its stamps
jittering by a good part of their period, would otherwise hold a third of the samples for its
next reading: at 50 Hz, 20 ms at the 99th percentile of a node's latency. The readings so taken
are carried to the sample's stamp as every reading is (the depth by the payout, the inclinometer
by the model's tilt rate: monitor.estimator).
"""
from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Mapping

CARRIED = {"depth": -1.0}  # channel: its change per metre of mean payout (the shaft's z axis points up)
STUCK = 5  # a sensor repeating its reading to the bit this many times running is stuck
# readings kept per channel: those that came before a sample but are stamped after it, and one more. A node behind its
# inputs takes every reading queued (50 a sensor topic, nodes/winch_monitor.SENSOR_QOS) before the winch messages
# queued with them: with 16 kept, a node 2.6 s behind at its start at ten times real time lost the inclinometer
# readings its first samples fuse, and its first update of the model's error was not replay's
HISTORY = 64
READING_LAG = 0.03  # [s] a sample fuses the readings stamped at least this long before it
LATE = 3.0  # [periods] a channel's reading is due at most this long after its latest: later, the sensor is late or silent
PAYOUTS = 1024  # complete samples whose payout is kept: a staleness limit's worth at up to 2 kHz


class LatestReadings:
    """The recent finite readings of each channel read off a sensor topic, with their stamps and the mean
    payout [m] then; a channel whose readings repeat to the bit is stuck (`StuckReadings`) and not given.

    A sample takes each channel's latest reading stamped at least `lag` before it, whatever came first: the
    node receives the sensors' topics each in its own order (a reading stamped after a winch sample may be
    taken before it when the callbacks are busy), a replay in log order; both take the same readings. Every
    method takes the sample's stamp."""

    def __init__(self, staleness: float, lag: float = READING_LAG):
        self.staleness, self.lag = staleness, lag
        self.values: dict[str, deque[tuple[float, float]]] = {}  # channel -> (stamp, value), recent ones
        self.periods: dict[str, float] = {}  # channel -> the shortest interval between its recent readings [s]
        self.intervals: dict[str, deque[float]] = {}  # channel -> the intervals between its recent readings [s]
        self.stuck = StuckReadings()

    def add(self, stamp: float, values: Mapping[str, float]) -> None:
        if not math.isfinite(stamp):
            return
        for name, value in values.items():
            if math.isfinite(value):
                history = self.values.get(name)
                if history is None:
                    history = self.values[name] = deque(maxlen=HISTORY)
                else:
                    intervals = self.intervals.get(name)
                    if intervals is None:
                        intervals = self.intervals[name] = deque(maxlen=HISTORY - 1)
                    intervals.append(stamp - history[-1][0])
                    self.periods[name] = min(intervals)
                history.append((stamp, value))
                self.stuck.add(name, value, stamp)

    def latest(self, stamp: float = math.inf) -> dict[str, float]:
        """Each channel's latest stamp a sample stamped `stamp` may take."""
        stamp -= self.lag
        out = {}
        for name, history in self.values.items():
            when = next((when for when, _ in reversed(history) if when <= stamp), None)
            if when is not None:
                out[name] = when
        return out

    def due(self, stamp: float) -> bool:
        """Whether a reading that a sample stamped `stamp` would take is expected and not in yet: a channel's
        latest is at least its shortest interval before the sample's time (`lag` before its stamp), and not
        LATE intervals (a sensor that late is late or silent, and not waited for)."""
        stamp -= self.lag
        for name, period in self.periods.items():
            if period > 0.0 and 0.0 <= stamp - self.values[name][-1][0] - period < (LATE - 1.0) * period:
                return True
        return False

    def at(self, stamp: float, payout: float, payout_at: Callable[[float], float]
           ) -> tuple[dict[str, float], dict[str, float]]:
        """Each channel's latest reading a sample stamped `stamp` may take, within the staleness limit of its
        time, carried to the mean payout then (`payout`; `payout_at` gives it at the reading's stamp), and the
        stamp it was taken at (a stuck channel's left out)."""
        stamp -= self.lag
        out, taken = {}, {}
        for name, history in self.values.items():
            if self.stuck.is_stuck(name, stamp):
                continue
            for when, value in reversed(history):
                if when <= stamp:
                    if stamp - when <= self.staleness:
                        per_metre = CARRIED.get(name)
                        then = payout_at(when) if per_metre is not None else math.nan
                        out[name] = value + (per_metre * (payout - then)
                                              if per_metre is not None and carry_known(payout, then) else 0.0)
                        taken[name] = when
                    break
        return out, taken

    def stuck_at(self, stamp: float) -> dict[str, tuple[float, float]]:
        """The channels stuck at a sample stamped `stamp` (`StuckReadings.stuck` at the sample's time)."""
        return self.stuck.stuck(stamp - self.lag)


class StuckReadings:
    """Channels whose sensor repeats its reading to the bit: no real sensor with noise does that STUCK
    times running, so such a sensor is stuck at a constant (a frozen load pin, a hung driver), whatever
    the model or the other sensors say. Its readings are not used until one differs again."""

    def __init__(self) -> None:
        # channel -> value, repeats, stamp of the first, stamp of the STUCK-th (inf: not that many yet)
        self.last: dict[str, tuple[float, int, float, float]] = {}

    def add(self, name: str, value: float, stamp: float) -> None:
        last = self.last.get(name)
        if last is not None and last[0] == value:
            count = last[1] + 1
            self.last[name] = (value, count, last[2], stamp if count == STUCK else last[3])
        else:
            self.last[name] = (value, 1, stamp, math.inf)

    def is_stuck(self, name: str, stamp: float = math.inf) -> bool:
        """Whether the channel is stuck at a sample stamped `stamp` (its STUCK-th repeat stamped at or before it)."""
        last = self.last.get(name)
        return last is not None and last[1] >= STUCK and last[3] <= stamp

    def stuck(self, stamp: float = math.inf) -> dict[str, tuple[float, float]]:
        """The channels stuck at a sample stamped `stamp`: the value each is stuck at and since when [s]."""
        return {name: (value, since) for name, (value, count, since, found) in self.last.items()
                if count >= STUCK and found <= stamp}


class PayoutHistory:
    """The mean payout [m] of the recent complete samples, to carry a reading to a sample by: the payout at
    a reading's stamp is interpolated between the samples around it (beyond the newest, carried by its
    payout speed), whenever the reading came."""

    def __init__(self) -> None:
        self.samples: deque[tuple[float, float, float]] = deque(maxlen=PAYOUTS)  # stamp, payout, payout speed

    def add(self, stamp: float, payout: float, speed: float) -> None:
        self.samples.append((stamp, payout, speed))

    def at(self, stamp: float) -> float:
        """The mean payout at `stamp` (NaN before the first sample kept)."""
        later = None
        for sample in reversed(self.samples):
            when, payout, speed = sample
            if when <= stamp:
                if later is None:
                    return payout + speed * (stamp - when)
                after, beyond, _ = later
                return payout + (beyond - payout) * (stamp - when) / (after - when) if after > when else payout
            later = sample
        return math.nan


def carry_known(payout: float, then: float) -> bool:
    return math.isfinite(payout) and math.isfinite(then)
