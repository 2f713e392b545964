"""The conditions as the samples come (ConditionsTracker): the same bits whether they come one at a time (the
node) or in windows (replay), and the recording's (`derivatives` over causal windows, `directions`)."""
from __future__ import annotations

import itertools

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from cable_winch_monitor.model.conditions import ConditionsTracker, derivatives, directions, line_slopes


def winch_series(seed: int, count: int, silent: int | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Stamps (jittered 10 Hz), lengths and reported speeds (n, 4) of a lowering that stops and hauls back in;
    winch `silent` reports no speed (its lengths' slope stands in)."""
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.08, 0.12, count))
    speed = np.where(t < t[count // 3], 0.5, np.where(t < t[count // 2], 0.0, -0.3))[:, None] + \
        rng.normal(0.0, 0.002, (count, 4))
    lengths = 100.0 + np.cumsum(speed * np.gradient(t)[:, None], axis=0) + rng.normal(0.0, 0.001, (count, 4))
    speeds = speed.copy()
    if silent is not None:
        speeds[:, silent] = np.nan
    return t, lengths, speeds


def one_at_a_time(tracker: ConditionsTracker, t: np.ndarray, lengths: np.ndarray, speeds: np.ndarray) -> list:
    return [tracker.update(t[k:k + 1], lengths[k:k + 1], speeds[k:k + 1])[0] for k in range(len(t))]


def columns(conditions: list) -> np.ndarray:
    """Stamps, speeds, accelerations and directions of a run of conditions, one row each (n, 13)."""
    return np.array([[c.time, *c.speeds, *c.accelerations, *c.direction] for c in conditions])


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 10_000), count=st.integers(3, 120), silent=st.sampled_from([None, 0, 3]),
       cuts=st.lists(st.integers(1, 119), max_size=6))
def test_conditions_one_at_a_time_are_those_of_windows_to_the_bit(seed, count, silent, cuts):
    """The node's samples come one at a time, replay's in windows cut anywhere: the same bits either way, and
    the recording's causal line fits (`derivatives`, `directions`) to rounding."""
    t, lengths, speeds = winch_series(seed, count, silent)
    live = one_at_a_time(ConditionsTracker(), t, lengths, speeds)
    tracker, windows = ConditionsTracker(), []
    for a, b in itertools.pairwise([0, *sorted(c for c in set(cuts) if c < count), count]):
        windows += tracker.update(t[a:b], lengths[a:b], speeds[a:b])
    np.testing.assert_array_equal(columns(windows), columns(live))
    stacked_speeds, stacked_accelerations = derivatives(t, lengths, speeds, centred=False)
    np.testing.assert_allclose([c.speeds for c in live], stacked_speeds, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose([c.accelerations for c in live], stacked_accelerations, rtol=1e-7, atol=1e-9)
    np.testing.assert_array_equal([c.direction for c in live], directions(stacked_speeds))
    assert np.isfinite(columns(live)).all()  # a silent winch's speed is its lengths' slope


def test_directions_hold_through_a_stop_and_from_the_window_before():
    """Within the dead band a winch keeps the direction it last moved in, across the windows' boundary too;
    one that has not moved yet stands (0)."""
    speeds = np.array([[0.5, 0.0, -0.5, 0.0], [0.01, 0.0, 0.0, 0.0], [np.nan, -0.3, 0.0, 0.0]])
    np.testing.assert_array_equal(directions(speeds), [[1, 0, -1, 0], [1, 0, -1, 0], [1, -1, -1, 0]])
    np.testing.assert_array_equal(directions(speeds[1:], np.array([-1.0, 1.0, 1.0, 1.0])),
                                  [[-1, 1, 1, 1], [-1, -1, 1, 1]])


def test_a_sample_stamped_a_little_before_the_one_before_it_keeps_the_windows_line():
    """Samples made at each winch's message are not quite in stamp order: one stamped 2 ms before the sample
    before it is part of the same motion, not a replay starting again, and its speeds and accelerations are
    the line through the window as it is (a restart would have made its acceleration 0: an effect reading it,
    the platform's inertia, would lose m a from the load)."""
    t = np.arange(40) * 0.1
    t[21] = t[20] - 0.002  # merged after sample 20, stamped before it
    lengths = 100.0 + 0.5 * 0.4 * t[:, None] ** 2 * np.ones(4)  # paying out at 0.4 m/s^2
    speeds = 0.4 * t[:, None] * np.ones(4)
    tracker = ConditionsTracker()
    live = one_at_a_time(tracker, t, lengths, speeds)
    assert all(abs(c.acceleration - 0.4) < 1e-9 for c in live[1:])
    restarted = tracker.update(t[:1], lengths[:1], speeds[:1])[0]  # the bag played again: afresh
    assert restarted.acceleration == 0.0


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10_000), count=st.integers(1, 40), least=st.integers(1, 4))
def test_line_slopes_are_least_squares_lines_over_each_window(seed, count, least):
    """Each window's slope is numpy's least-squares line through its rows; NaN where it has fewer than `least`
    rows or one time only."""
    rng = np.random.default_rng(seed)
    t = 50.0 + np.cumsum(rng.uniform(0.05, 0.15, count))
    values = rng.normal(0.0, 1.0, (count, 2)) + np.outer(t, [0.3, -2.0])
    stop = rng.integers(1, count + 1, 10)
    start = np.maximum(stop - rng.integers(1, 8, 10), 0)
    slopes = line_slopes(t, values, start, stop, least)
    for j, (a, b) in enumerate(zip(start, stop)):
        if b - a < max(least, 2):
            assert np.isnan(slopes[j]).all()
        else:
            np.testing.assert_allclose(slopes[j], np.polyfit(t[a:b], values[a:b], 1)[0], rtol=1e-6, atol=1e-6)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10_000), count=st.integers(2, 60), before=st.integers(0, 30))
def test_a_windows_slope_does_not_depend_on_the_rows_around_it(seed, count, before):
    """A window's slope is the same to the last bit whether it is fitted alone, among other windows, or in an
    array with `before` more rows ahead of it: the node fits its latest samples as they come, replay fits a
    window of them at once, and the two must agree."""
    rng = np.random.default_rng(seed)
    t = 1e4 + np.cumsum(rng.uniform(0.01, 0.03, count + before))
    values = rng.normal(0.0, 1e-3, (count + before, 2)) + np.outer(t - t[0], [0.3, -2.0])
    stop = rng.integers(before + 2, count + before + 1, 8)
    start = np.maximum(stop - rng.integers(2, 12, 8), before)
    together = line_slopes(t, values, start, stop)
    for j, (a, b) in enumerate(zip(start, stop)):
        alone = line_slopes(t[a:b], values[a:b], np.array([0]), np.array([b - a]))[0]
        np.testing.assert_array_equal(together[j], alone)
