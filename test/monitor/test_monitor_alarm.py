"""Clearance and alarm levels: geometry of the outline, hysteresis, slack and single-cable states."""
from __future__ import annotations

import numpy as np
import pytest

from cable_winch_monitor.model.solvers.energy import solve_energy
from cable_winch_monitor.monitor.alarm import AlarmLevel, AlarmPolicy, AlarmTracker
from cable_winch_monitor.monitor.clearance import clearance_at_pose, solution_clearance


def test_level_platform_clearance_is_shaft_radius_minus_deck_radius(plant):
    clearance = clearance_at_pose(plant, np.eye(3), np.array([0.0, 0.0, -100.0]))
    assert clearance.value == pytest.approx(4.0 - 3.6)


def test_clearance_is_the_horizontal_gap_of_the_worst_outline_point(plant):
    """Shift the level platform by 0.3 m in +x: the deck point furthest along +x is 0.1 m from the wall."""
    clearance = clearance_at_pose(plant, np.eye(3), np.array([0.3, 0.0, -50.0]))
    assert clearance.value == pytest.approx(0.1, abs=1e-9)
    assert clearance.point_platform[0] == pytest.approx(3.6)
    assert np.hypot(*clearance.point_shaft[:2]) == pytest.approx(3.9)


class _Sample:
    """A solved sample at a given clearance, via a level platform shifted sideways."""

    def __init__(self, plant):
        self.plant = plant
        self.solution = solve_energy(plant, [80.0] * 4)

    def clearance(self, value):
        return clearance_at_pose(self.plant, np.eye(3), np.array([4.0 - 3.6 - value, 0.0, -80.0]))


def test_hysteresis_prevents_chatter(plant):
    tracker = AlarmTracker(AlarmPolicy(warning_margin=0.15, critical_margin=0.05, hysteresis=0.02))
    sample = _Sample(plant)
    walk = [0.4, 0.2, 0.149, 0.16, 0.14, 0.165, 0.049, 0.06, 0.045, -0.01, 0.01, -0.005, 0.03, 0.065,
            0.08, 0.16, 0.175, 0.3]
    levels = [tracker.update(sample.solution, sample.clearance(c)).level for c in walk]
    assert levels == [AlarmLevel.OK, AlarmLevel.OK, AlarmLevel.WARNING, AlarmLevel.WARNING, AlarmLevel.WARNING,
                      AlarmLevel.WARNING, AlarmLevel.CRITICAL, AlarmLevel.CRITICAL, AlarmLevel.CRITICAL,
                      AlarmLevel.COLLISION, AlarmLevel.COLLISION, AlarmLevel.COLLISION, AlarmLevel.CRITICAL,
                      AlarmLevel.CRITICAL, AlarmLevel.WARNING, AlarmLevel.WARNING, AlarmLevel.OK, AlarmLevel.OK]


def test_slack_cable_raises_a_warning(plant):
    tracker = AlarmTracker(AlarmPolicy.from_plant(plant))
    solution = solve_energy(plant, [100.0, 100.0, 100.0, 100.5])
    alarm = tracker.update(solution, solution_clearance(plant, solution))
    assert not solution.taut[3] and solution.lengths[3] - solution.spans[3] > 0.4
    assert alarm.level >= AlarmLevel.WARNING and "cable_4" in alarm.reason
    assert alarm.sync_errors[alarm.sync_error_pairs.index("cable_1-cable_4")] == pytest.approx(-0.5)


def test_single_cable_state_warns_with_the_worst_swing_clearance(plant):
    tracker = AlarmTracker(AlarmPolicy.from_plant(plant))
    solution = solve_energy(plant, [20.0, 21.0, 22.0, 21.5])
    clearance = solution_clearance(plant, solution)
    assert clearance is not None
    alarm = tracker.update(solution, clearance)
    assert alarm.level >= AlarmLevel.WARNING and "cable_1 alone" in alarm.reason
    # Hanging from cable 1 puts C under A1 = (2, 2.5): the decks swing far off the shaft axis.
    assert clearance.value < 0.0


def test_a_run_of_samples_is_judged_in_order_with_each_ones_own_sync_errors_and_slack(plant):
    """The alarms of a run at once (replay's window, the node's samples taken together): the hysteresis carries
    from each sample to the next in order, each alarm's sync errors are its own sample's l_i - l_j, and only
    the sample with a loose rope says so."""
    level_one = _Sample(plant)
    loose = solve_energy(plant, [100.0, 100.0, 100.0, 100.5])
    walk = [0.4, 0.14, 0.16, 0.049, 0.06]
    solutions = [level_one.solution] * len(walk) + [loose]
    clearances = [level_one.clearance(c) for c in walk] + [solution_clearance(plant, loose)]
    alarms = list(AlarmTracker(AlarmPolicy(warning_margin=0.15, critical_margin=0.05, hysteresis=0.02)).update_many(
        solutions, clearances, ["tilt measured"] * len(solutions)))
    assert [a.level for a in alarms[:5]] == [AlarmLevel.OK, AlarmLevel.WARNING, AlarmLevel.WARNING,
                                              AlarmLevel.CRITICAL, AlarmLevel.CRITICAL]
    assert alarms[5].level == AlarmLevel.WARNING and alarms[5].reason.startswith("slack: ")
    assert "cable_4 loose by 0.4" in alarms[5].reason
    assert not any("slack" in a.reason for a in alarms[:5]) and all(a.reason.endswith("(tilt measured)") for a in alarms)
    for alarm, solution in zip(alarms, solutions):
        lengths = solution.lengths
        assert np.array_equal(alarm.sync_errors, [lengths[i] - lengths[j] for i in range(4) for j in range(i + 1, 4)])
