"""Which readings a sample fuses: the latest stamped the lag before it, whenever they came; when one is still due;
and a sensor stuck from the stamp of its STUCK-th repeat on."""
from __future__ import annotations

import math

from hypothesis import given
from hypothesis import strategies as st

from cable_winch_monitor.monitor.sensors import LATE, READING_LAG, STUCK, LatestReadings, StuckReadings


def no_carry(stamp: float) -> float:
    """The payout at a reading's stamp: not known (nothing carried)."""
    return math.nan


@given(st.lists(st.floats(0.01, 0.5), min_size=2, max_size=12), st.floats(0.0, 1.0), st.floats(0.0, 1.0),
       st.sampled_from([0.0, READING_LAG, 0.2]))
def test_a_reading_that_will_come_stamped_before_a_sample_is_due_there(intervals, longer, where, lag):
    """Readings at the intervals given; the next one at least the shortest of them later. At any sample
    stamped `lag` or more after it (and within LATE intervals of the latest), the next reading is due;
    before that, a sample takes the latest reading in, as it would with every reading in."""
    readings = LatestReadings(staleness=10.0, lag=lag)
    stamp = 100.0
    for k, interval in enumerate([0.0, *intervals]):
        stamp += interval
        readings.add(stamp, {"roll": float(k)})
    shortest = min(intervals)  # all of them kept (HISTORY)
    following = stamp + shortest * (1.0 + longer)
    sample = stamp + lag + where * LATE * shortest
    if following + lag <= sample < stamp + lag + LATE * shortest - 1e-9:
        assert readings.due(sample)
    if sample < following + lag:
        values, taken = readings.at(sample, 0.0, no_carry)
        assert taken["roll"] == stamp and values["roll"] == float(len(intervals))
    if sample >= stamp + lag + LATE * shortest + 1e-9:
        assert not readings.due(sample)  # that late, the sensor is late or silent: not waited for


def test_a_sample_takes_the_readings_stamped_the_lag_before_it():
    readings = LatestReadings(staleness=1.0, lag=0.03)
    readings.add(1.0, {"roll": 1.0})
    readings.add(1.08, {"roll": 2.0})
    readings.add(1.1, {"roll": 3.0})
    assert readings.at(1.1, 0.0, no_carry) == ({"roll": 1.0}, {"roll": 1.0})  # 1.08 is later than 1.07
    assert readings.at(1.11, 0.0, no_carry) == ({"roll": 2.0}, {"roll": 1.08})
    assert readings.latest(1.14) == {"roll": 1.1}
    assert readings.at(2.09, 0.0, no_carry) == ({"roll": 3.0}, {"roll": 1.1})  # staleness counted from 2.06
    assert readings.at(2.2, 0.0, no_carry) == ({}, {})


def test_a_reading_in_after_later_ones_is_taken_by_its_stamp():
    readings = LatestReadings(staleness=1.0)
    readings.add(1.0, {"roll": 1.0})
    readings.add(1.2, {"roll": 3.0})
    assert readings.at(1.1, 0.0, no_carry) == ({"roll": 1.0}, {"roll": 1.0})
    assert readings.latest(1.1) == {"roll": 1.0} and readings.latest() == {"roll": 1.2}
    assert not readings.due(1.1)  # the reading after 1.0 is in: none due


def test_a_sensor_is_stuck_from_the_stamp_of_its_last_repeat_needed_on():
    stuck = StuckReadings()
    for k in range(STUCK):
        stuck.add("tension_cable_2", 5000.0, 10.0 + k)
    found = 10.0 + STUCK - 1
    assert stuck.is_stuck("tension_cable_2", found) and not stuck.is_stuck("tension_cable_2", found - 0.5)
    assert stuck.stuck(found) == {"tension_cable_2": (5000.0, 10.0)} and stuck.stuck(found - 0.5) == {}
    stuck.add("tension_cable_2", 5000.5, found + 1.0)
    assert not stuck.is_stuck("tension_cable_2")
