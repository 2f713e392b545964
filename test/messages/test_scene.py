"""The scene builder without ROS: rope colours, the slack look, the scene of a sample without a pose, the throttle."""
from __future__ import annotations

import numpy as np
import pytest

from cable_winch_monitor.messages.scene import DELETEALL, SLACK_COLOUR, SceneBuilder, SceneThrottle, tension_colour
from cable_winch_monitor.model.solvers.solve import solve
from cable_winch_monitor.monitor.alarm import AlarmLevel, AlarmPolicy, AlarmTracker
from cable_winch_monitor.monitor.clearance import solution_clearance
from cable_winch_monitor.seed002 import TABLE_1


def test_rope_colours_run_from_blue_to_red_and_never_look_slack():
    shares = np.linspace(0.0, 1.0, 101)
    colours = np.array([tension_colour(s)[:3] for s in shares])
    assert colours[0][2] > 0.9 and colours[-1][0] > 0.9 and colours[-1][2] < 0.1
    assert np.min(np.linalg.norm(colours - np.array(SLACK_COLOUR[:3]), axis=1)) > 0.3
    assert np.max(np.linalg.norm(np.diff(colours, axis=0), axis=1)) < 0.1, "no jumps along the scale"
    assert tension_colour(-5.0) == tension_colour(0.0) and tension_colour(3.0) == tension_colour(1.0)


def test_a_sample_without_a_pose_clears_the_platform_from_the_scene(plant):
    solution = solve(plant, TABLE_1[1])  # hangs from cable 1 alone: no definite pose
    alarm = AlarmTracker(AlarmPolicy.from_plant(plant)).update(solution, solution_clearance(plant, solution))
    markers = SceneBuilder(plant).scene((3, 0), solution, alarm)["markers"]
    assert markers[0]["action"] == DELETEALL
    assert not {"decks", "ropes", "rope_labels"} & {m["ns"] for m in markers}
    alarm_text = next(m for m in markers if m["ns"] == "alarm")["text"]
    assert alarm_text.startswith(AlarmLevel(alarm.level).name) and "cable_1 alone" in alarm_text
    wall = next(m for m in markers if m["ns"] == "shaft_wall")
    assert wall["scale"]["z"] > np.mean(TABLE_1[1]), "the wall reaches below the platform"


def test_throttle_lets_through_one_scene_per_period_and_restarts_when_stamps_go_back():
    throttle = SceneThrottle(10.0)
    stamps = np.arange(0.0, 2.0, 0.025)  # 40 Hz
    due = [t for t in stamps if throttle.due(float(t))]
    assert len(due) == pytest.approx(20, abs=1) and np.all(np.diff(due) >= 0.1 - 1e-12)
    assert not throttle.due(due[-1] - 0.002), "a sample made at another winch's message, stamped a little earlier"
    assert throttle.due(0.5), "a simulation restarted: stamps went back"
    with pytest.raises(ValueError):
        SceneThrottle(0.0)
