"""Operating conditions of a sample: what a physical effect may depend on besides the pose.

For each sample: its time, the payout speed and payout acceleration of every winch, the
direction of motion, and the extra inputs effects declare (a shaft temperature, ...).
Speeds are the winches' reported velocities, or the lengths differentiated where a winch
reports none; accelerations are the speeds differentiated. Both derivatives are the
slope of a straight line fitted over a window of ACCELERATION_WINDOW seconds: encoder
noise of 1 mm and speed noise of 2 mm/s at 10 Hz leave a few mm/s^2 over one second,
against the 0.1 m/s^2 of a winch starting or braking. As the samples come (`ConditionsTracker`,
the node's one or few at a time, replay's window at once, to the same bits) the window ends at
the sample; over a recording (`derivatives`) it is centred on it.
"""
from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..frozen import fast_init

DEADBAND = 0.02               # [m/s] slower payout counts as standing still (encoder speed noise is ~2 mm/s)
ACCELERATION_WINDOW = 1.0     # [s] speeds and accelerations are line slopes over this window
NAN = float("nan")


@fast_init
@dataclass(frozen=True)
class Conditions:
    """Conditions of one sample.

    time           [s] the sample's stamp (NaN: not known, e.g. a command check)
    speeds         payout speed of each winch [m/s], + paying out (NaN where not known)
    accelerations  payout acceleration of each winch [m/s^2] (0 where not known)
    direction      +1 paying out (lowering), -1 hauling in (hoisting), 0 not yet moved; held through stops
    inputs         extra inputs by key "topic.field" (channels.Input.key), at the sample's stamp
    """

    time: float = NAN
    speeds: np.ndarray = field(default_factory=lambda: np.full(4, NAN))
    accelerations: np.ndarray = field(default_factory=lambda: np.zeros(4))
    direction: np.ndarray = field(default_factory=lambda: np.zeros(4))
    inputs: Mapping[str, float] = field(default_factory=dict)

    @property
    def acceleration(self) -> float:
        """The platform's downward acceleration [m/s^2]: the mean payout acceleration of the winches."""
        return float(np.mean(self.accelerations))


@dataclass(frozen=True)
class StackedConditions:
    """The conditions of n stacked states as arrays (what measurement hooks written for many states
    read); `stacked[k]` is state k's own `Conditions`, for hooks written per sample.

    time (n,), speeds, accelerations, direction (n, 4), inputs {key: (n,)} (NaN where a state has none).
    """

    time: np.ndarray
    speeds: np.ndarray
    accelerations: np.ndarray
    direction: np.ndarray
    inputs: Mapping[str, np.ndarray]

    @classmethod
    def of(cls, conditions: Sequence[Conditions] | StackedConditions) -> StackedConditions:
        """Samples' conditions stacked (stacked ones as they are)."""
        if isinstance(conditions, StackedConditions):
            return conditions
        keys = sorted({key for c in conditions for key in c.inputs})
        return cls(np.array([c.time for c in conditions], dtype=float),
                   np.array([c.speeds for c in conditions], dtype=float).reshape(-1, 4),
                   np.array([c.accelerations for c in conditions], dtype=float).reshape(-1, 4),
                   np.array([c.direction for c in conditions], dtype=float).reshape(-1, 4),
                   {key: np.array([c.inputs.get(key, NAN) for c in conditions], dtype=float) for key in keys})

    def take(self, index: np.ndarray) -> StackedConditions:
        """The conditions of the states `index` (e.g. each candidate state's sample)."""
        return StackedConditions(self.time[index], self.speeds[index], self.accelerations[index],
                                 self.direction[index], {key: value[index] for key, value in self.inputs.items()})

    def __len__(self) -> int:
        return len(self.time)

    def __getitem__(self, k: int) -> Conditions:
        return Conditions(float(self.time[k]), self.speeds[k], self.accelerations[k], self.direction[k],
                          {key: float(value[k]) for key, value in self.inputs.items() if np.isfinite(value[k])})

    def __iter__(self) -> Iterator[Conditions]:
        return (self[k] for k in range(len(self)))


def line_slopes(times: np.ndarray, values: np.ndarray, start: np.ndarray, stop: np.ndarray,
                least: int = 2) -> np.ndarray:
    """Least-squares slopes (m, k) of values (n, k) against times (n,) over the rows start[j]:stop[j] of each
    of m windows; NaN where a window has fewer than `least` rows (two at least: one row's sums leave rounding
    errors for a slope) or its times do not spread.

    Each window's sums run over its own rows in order, about its first time, so that its slope does not
    depend on the rows around it: the node, which fits the latest samples as they come, and replay, which
    fits a window of them at once, get the same bits."""
    count = np.asarray(stop) - np.asarray(start)
    slope = np.full((len(count), values.shape[1]), np.nan)
    width = int(count.max()) if count.size else 0
    if width < max(least, 2):
        return slope
    rows = np.asarray(start)[None, :] + np.arange(width)[:, None]          # (width, m)
    inside = rows < np.asarray(stop)[None, :]
    rows = np.where(inside, rows, np.asarray(start)[None, :])
    t = np.where(inside, times[rows] - times[rows[0]], 0.0)
    v = np.where(inside[..., None], values[rows], 0.0)
    last = -1  # cumulative sums add in row order whatever the windows' number (a sum may not)
    sum_t, sum_tt = np.cumsum(t, axis=0)[last], np.cumsum(t * t, axis=0)[last]
    sv, stv = np.cumsum(v, axis=0)[last], np.cumsum(v * t[..., None], axis=0)[last]
    denominator = count * sum_tt - sum_t ** 2
    with np.errstate(invalid="ignore", divide="ignore"):
        fitted = (count[:, None] * stv - sum_t[:, None] * sv) / denominator[:, None]
    return np.where(((count >= max(least, 2)) & (denominator > 0.0))[:, None], fitted, slope)


def _slopes(times: np.ndarray, values: np.ndarray, start: np.ndarray, stop: np.ndarray) -> np.ndarray:
    """`line_slopes` with a missing value counted as 0 and 0 where no slope is known (a speed not known)."""
    slope = line_slopes(times, np.nan_to_num(values), start, stop)
    return np.where(np.isfinite(slope), slope, 0.0)


def _windows(times: np.ndarray, window: float, centred: bool) -> tuple[np.ndarray, np.ndarray]:
    before = window / 2.0 if centred else window
    after = window / 2.0 if centred else 0.0
    slack = 1e-9 * max(window, 1.0)  # stamps exactly half a window away belong to it on both sides
    return np.searchsorted(times, times - before - slack, "left"), np.searchsorted(times, times + after + slack, "right")


def derivatives(times: np.ndarray, lengths: np.ndarray, speeds: np.ndarray, window: float = ACCELERATION_WINDOW,
                centred: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Speeds and accelerations (n, 4) of winch samples in time order: reported speeds where finite,
    else the lengths' slope; accelerations the speeds' slope, over `window` seconds."""
    times = np.asarray(times, dtype=float)
    if not len(times):
        return np.zeros((0, 4)), np.zeros((0, 4))
    start, stop = _windows(times, window, centred)
    speeds = np.where(np.isfinite(speeds), speeds, _slopes(times, lengths, start, stop))
    return speeds, _slopes(times, speeds, start, stop)


def directions(speeds: np.ndarray, before: np.ndarray | None = None) -> np.ndarray:
    """The direction of motion (n, 4) along a series of speeds (n, 4): +1 paying out, -1 hauling in; within
    the dead band the last direction holds (static friction keeps the slip state the rope had when it
    stopped), from `before` (standing, 0, where not given). Each sample takes the sign of the last sample
    moving faster than the dead band (a NaN speed holds)."""
    speeds = np.nan_to_num(np.asarray(speeds, dtype=float))
    moving = np.where(speeds > DEADBAND, 1.0, np.where(speeds < -DEADBAND, -1.0, 0.0))
    last = np.maximum.accumulate(np.where(moving != 0.0, np.arange(len(moving))[:, None], -1), axis=0)
    held = 0.0 if before is None else before
    return np.where(last >= 0, np.take_along_axis(moving, np.maximum(last, 0), axis=0), held)


class ConditionsTracker:
    """The conditions of winch samples as they come, from the samples before them (causal windows): one
    at a time (the node) or a window at once (replay), to the same bits -- each window's line is fitted
    over its own rows (`line_slopes`), whatever came with it."""

    def __init__(self, window: float = ACCELERATION_WINDOW):
        self.window = window
        # the latest samples within a window of the last one: stamps (h,), lengths and speeds (h, 4), the
        # speeds of a winch that reports none its lengths' slope
        self.times, self.lengths, self.speeds = np.zeros(0), np.zeros((0, 4)), np.zeros((0, 4))
        self.direction = np.zeros(4)

    def update(self, times: np.ndarray, lengths: np.ndarray, speeds: np.ndarray,
               inputs: Sequence[Mapping[str, float]] | None = None) -> list[Conditions]:
        """Record samples in the order they came (stamps [s] (n,), lengths and reported speeds (n, 4), NaN where
        a winch reports none; each one's extra inputs) and return their conditions."""
        count = len(times)
        if not count:
            return []
        held = len(self.times)
        times = np.concatenate([self.times, np.asarray(times, dtype=float)])
        lengths = np.concatenate([self.lengths, np.asarray(lengths, dtype=float).reshape(-1, 4)])
        speeds = np.concatenate([self.speeds, np.asarray(speeds, dtype=float).reshape(-1, 4)])
        start = self._starts(times, held)
        stop = np.arange(held + 1, held + count + 1)
        new = speeds[held:]
        missing = ~np.isfinite(new)
        if missing.any():  # a winch without velocity: its lengths' slope
            new[:] = np.where(missing, _slopes(times, lengths, start, stop), new)
        accelerations = _slopes(times, speeds, start, stop)
        direction = directions(new, self.direction)
        first = int(start[-1])
        self.times, self.lengths, self.speeds = times[first:], lengths[first:], speeds[first:]
        self.direction = direction[-1]
        stamps = times[held:].tolist()
        inputs = inputs if inputs is not None else [{}] * count
        return [Conditions(*row) for row in zip(stamps, new, accelerations, direction, map(dict, inputs))]

    def _starts(self, times: np.ndarray, held: int) -> np.ndarray:
        """The first row of each new sample's window (the rows `held` on): the rows stamped at most `window`
        before it, from where the window before it started; a sample stamped more than `window` before the
        one before it (a replay restarted) starts afresh (by less: one made at another winch's message
        stamped a little earlier, which the window's line holds)."""
        stamps, window = times.tolist(), self.window
        first, out = 0, []
        for k in range(held, len(stamps)):
            now = stamps[k]
            if k and now < stamps[k - 1] - window:
                first = k
            while stamps[first] < now - window:
                first += 1
            out.append(first)
        return np.array(out)
