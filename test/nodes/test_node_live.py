"""The winch_monitor node in its own process, over real DDS: what it publishes for good input.

Expected values come from the pure model (`solve`, cold) and are compared with what the
node publishes (warm-started): pose within 1 mm, tensions within 1 N.
"""
from __future__ import annotations

import time

import numpy as np
import pytest
import yaml
from ros_harness import PARAMS_FILE, ROOT, LiveNode, stamped

from cable_winch_monitor.messages.fields import STATUS_NUMBERS
from cable_winch_monitor.model.plantfile.plant import CABLE_NAMES
from cable_winch_monitor.model.solvers.solve import solve
from cable_winch_monitor.model.statics.geometry import (
    quaternion_from_rotation,
    roll_pitch_of_quaternion,
    rotation_from_vector,
)
from cable_winch_monitor.monitor.alarm import AlarmLevel, AlarmPolicy, AlarmTracker
from cable_winch_monitor.monitor.clearance import solution_clearance
from cable_winch_monitor.nodes.winch_monitor import NODE_NAME, PARAMETERS
from cable_winch_monitor.seed002 import TABLE_1

pytestmark = pytest.mark.timeout(60)

POSITION_TOL = 1e-3   # [m]
TENSION_TOL = 1.0     # [N]
LEVEL = 20.0          # [m] a payout with all four cables taut and the platform centred


@pytest.fixture(scope="module")
def live():
    node = LiveNode({"diagnostics_period": 0.2})
    yield node
    assert node.close() == 0, "winch_monitor did not exit cleanly on SIGINT"


def assert_pose(pose, expected) -> None:
    """A geometry_msgs/Pose within 1 mm of a solved pose (position, and orientation at the farthest point)."""
    np.testing.assert_allclose([pose.position.x, pose.position.y, pose.position.z], expected.position,
                               atol=POSITION_TOL)
    q = pose.orientation
    angle = 2.0 * np.arccos(min(1.0, abs(np.dot([q.x, q.y, q.z, q.w], expected.quaternion))))
    assert angle * np.linalg.norm(expected.points_b - expected.position, axis=1).max() < POSITION_TOL


def assert_tensions(tension_msg, expected) -> None:
    assert tension_msg.status == STATUS_NUMBERS[expected.status]
    assert [c.name for c in tension_msg.cables] == list(CABLE_NAMES)
    assert tuple(i + 1 for i, c in enumerate(tension_msg.cables) if c.taut) == expected.taut_set
    if expected.tensions is not None:
        np.testing.assert_allclose([c.tension for c in tension_msg.cables], expected.tensions, atol=TENSION_TOL)
    assert tension_msg.tension_state == expected.tension_state


def expected_level(plant, lengths) -> AlarmLevel:
    """The alarm a fresh tracker gives (no hysteresis history)."""
    solution = solve(plant, lengths)
    return AlarmTracker(AlarmPolicy.from_plant(plant)).update(solution, solution_clearance(plant, solution)).level


def test_seed002_examples_give_the_pose_and_tensions_of_solve(live, plant):
    single_cable_stamps = []
    for example in (1, 2, 3, 4, 1):  # example 1 once cold, once after a solved pose (warm start)
        lengths = TABLE_1[example]
        expected = solve(plant, lengths)
        out = live.client.solve(lengths, pose=expected.ok)
        assert_tensions(out.tension, expected)
        if expected.ok:
            assert_pose(out.pose.pose, expected)
            assert out.pose.header.frame_id == "shaft"
        else:
            single_cable_stamps.append(out.tension.header.stamp)
    live.client.solve((LEVEL,) * 4)  # its pose arrives after any pose of the earlier stamps
    assert len(single_cable_stamps) == 2
    for stamp in single_cable_stamps:  # example 1 hangs from cable 1 alone: never a pose
        assert not live.client.collectors["pose"].with_stamp(stamp)
        single = live.client.collectors["tension"].with_stamp(stamp)[0]
        assert single.status == single.STATUS_SINGLE_CABLE_INDETERMINATE
        assert single.tension_state == "single cable 1: pose indeterminate"
        assert [c.taut for c in single.cables] == [True, False, False, False]


def tilt_for_clearance(plant, target: float) -> tuple[float, ...]:
    """Lengths (L, L, L + d, L + d) whose solved clearance is `target` (bisection on d in [0, 0.25] m)."""
    warm = solve(plant, [LEVEL] * 4)

    def clearance(d: float) -> float:
        return solution_clearance(plant, solve(plant, [LEVEL, LEVEL, LEVEL + d, LEVEL + d], warm_start=warm)).value

    low, high = 0.0, 0.25
    assert clearance(low) > target > clearance(high)
    for _ in range(30):
        middle = 0.5 * (low + high)
        low, high = (middle, high) if clearance(middle) > target else (low, middle)
    d = 0.5 * (low + high)
    return (LEVEL, LEVEL, LEVEL + d, LEVEL + d)


def test_alarm_walks_up_and_down_without_chatter(live, plant):
    policy = AlarmPolicy.from_plant(plant)
    warning, critical, band = policy.warning_margin, policy.critical_margin, policy.hysteresis
    inside = band / 2  # oscillations that stay inside the hysteresis band above a threshold
    walk = [  # target clearance, expected level
        (0.30, AlarmLevel.OK),
        (warning - 0.01, AlarmLevel.WARNING), (warning + inside, AlarmLevel.WARNING),
        (warning - 0.01, AlarmLevel.WARNING),
        (critical - 0.01, AlarmLevel.CRITICAL), (critical + inside, AlarmLevel.CRITICAL),
        (critical - 0.01, AlarmLevel.CRITICAL),
        (-0.01, AlarmLevel.COLLISION), (inside, AlarmLevel.COLLISION), (-0.01, AlarmLevel.COLLISION),
        (band + 0.01, AlarmLevel.CRITICAL), (critical + inside, AlarmLevel.CRITICAL),
        (critical + band + 0.03, AlarmLevel.WARNING), (warning + inside, AlarmLevel.WARNING),
        (0.30, AlarmLevel.OK),
    ]
    live.client.solve((LEVEL,) * 4)
    levels, clearances = [], []
    for target, _ in walk:
        alarm = live.client.solve(tilt_for_clearance(plant, target)).alarm
        levels.append(alarm.level)
        clearances.append(alarm.clearance)
        assert alarm.reason, "an alarm always says why"
    np.testing.assert_allclose(clearances, [t for t, _ in walk], atol=1e-4)
    assert levels == [int(level) for _, level in walk], f"levels {levels} for clearances {clearances}"
    entered = [level for k, level in enumerate(levels) if k == 0 or level != levels[k - 1]]
    assert entered == [0, 1, 2, 3, 2, 1, 0], "each level entered once, up then down"


def test_a_cable_going_slack_is_flagged_in_the_same_sample(live):
    before = live.client.solve((LEVEL,) * 4)
    assert all(c.taut for c in before.tension.cables) and before.alarm.level == AlarmLevel.OK
    slack = live.client.solve((LEVEL, LEVEL, LEVEL + 0.06, LEVEL))
    stamp = slack.tension.header.stamp
    assert slack.alarm.header.stamp == stamp and slack.pose.header.stamp == stamp
    assert [c.taut for c in slack.tension.cables] == [True, True, False, True]
    assert slack.tension.cables[2].tension == 0.0
    assert slack.alarm.level >= AlarmLevel.WARNING
    assert "slack: cable_3" in slack.alarm.reason


@pytest.mark.parametrize("example, names", [(2, ()), (3, ()), (4, ("cable_4", "cable_2", "cable_1", "cable_3"))])
def test_service_answers_a_proposed_command_as_solve_would(live, plant, example, names):
    lengths = TABLE_1[example]
    by_name = dict(zip(CABLE_NAMES, lengths))
    response = live.client.call([by_name[n] for n in names] if names else lengths, names)
    expected = solve(plant, lengths)
    assert response.accepted, response.message
    assert_tensions(response.tension, expected)
    assert_pose(response.pose, expected)
    assert response.alarm.level == expected_level(plant, lengths)
    assert response.alarm.clearance == pytest.approx(solution_clearance(plant, expected).value, abs=POSITION_TOL)


def test_service_refuses_invalid_commands_with_a_reason(live):
    single = live.client.call(TABLE_1[1])
    assert not single.accepted and "pose indeterminate" in single.message
    assert single.tension.status == single.tension.STATUS_SINGLE_CABLE_INDETERMINATE
    for lengths, names, words in [
        ((20.0, float("nan"), 20.0, 20.0), (), "finite"),
        ((20.0, -1.0, 20.0, 20.0), (), "positive"),
        ((1e300, 20.1, 20.5, 20.2), (), "beyond the maximum payout"),
        ((20.0, 20.0, 20.0), (), "need 4 lengths"),
        ((20.0, 20.0, 20.0, 20.0), ("cable_1", "cable_1", "cable_2", "cable_3"), "each of"),
    ]:
        response = live.client.call(lengths, names)
        assert not response.accepted and words in response.message, response.message


def test_per_winch_topics_merge_into_one_solve(live, plant):
    lengths = TABLE_1[4]
    live.client.solve((LEVEL,) * 4)
    stamp = live.client.stamps.next(advance=1.0)  # older readings are stale: only the merged four count
    for i, length in enumerate(lengths):
        live.client.publish([length], names=[CABLE_NAMES[i]], stamp=stamp, topic=i + 1)
    out = live.client.outputs(stamp, pose=True)
    expected = solve(plant, lengths)
    assert_pose(out.pose.pose, expected)
    assert_tensions(out.tension, expected)
    time.sleep(0.3)
    assert len(live.client.collectors["tension"].with_stamp(stamp)) == 1, "one solve for the four winch messages"
    statuses = live.client.diagnostics(lambda s: True, "any status")
    for i in range(1, 5):
        assert int(statuses["winch_monitor: inputs"][2][f"/winch_{i}/joint_states used"]) >= 1
    solver = statuses["winch_monitor: solver"][2]
    for name in ("queued before the solve", "merged to outputs"):  # the node's own latency, for the operator
        value = next(v for k, v in solver.items() if k.startswith(f"{name} [ms], latest "))
        p50, p99, most = (float(part.split()[1]) for part in value.split(", "))
        assert 0.0 <= p50 <= p99 <= most < 5e3, value


def quaternion_rpy(roll: float, pitch: float, yaw: float) -> np.ndarray:
    rotation = (rotation_from_vector(np.array([0.0, 0.0, yaw])) @ rotation_from_vector(np.array([0.0, pitch, 0.0]))
                @ rotation_from_vector(np.array([roll, 0.0, 0.0])))
    return quaternion_from_rotation(rotation)


def test_measurements_give_model_residuals(live, plant):
    lengths = TABLE_1[4]
    expected = solve(plant, lengths)
    offsets = np.array([100.0, -200.0, 50.0, 0.0])
    efforts = expected.tensions + offsets
    stamp = live.client.publish(lengths, efforts=efforts)
    out = live.client.outputs(stamp, pose=True)
    tensions = live.client.collectors["residuals"].wait_for(stamped(stamp), "/model/residuals of the load pins")
    assert list(tensions.channels) == [f"tension_{name}" for name in CABLE_NAMES]
    # the published state is the estimate fusing the pins (the plant file gives the encoders 1 mm):
    # the residuals are the pins against it, smaller than against the lengths taken as exact
    assert list(out.tension.sensors_used) == [f"tension_{name}" for name in CABLE_NAMES]
    published = np.array([c.tension for c in out.tension.cables])
    np.testing.assert_allclose(tensions.predicted, published, atol=1e-6)
    np.testing.assert_allclose(tensions.residuals, efforts - published, atol=0.01)
    assert np.sum(np.square(tensions.residuals)) < np.sum(np.square(offsets))
    np.testing.assert_allclose(np.array(tensions.measured) - tensions.predicted, tensions.residuals)

    q = out.pose.pose.orientation
    roll, pitch = roll_pitch_of_quaternion((q.x, q.y, q.z, q.w))
    imu_stamp = live.client.stamps.next()
    live.client.publish_imu(quaternion_rpy(roll + 0.002, pitch - 0.001, 0.3), imu_stamp)
    imu = live.client.collectors["residuals"].wait_for(stamped(imu_stamp), "/model/residuals of the inclinometer")
    assert list(imu.channels) == ["roll", "pitch"]
    np.testing.assert_allclose(imu.residuals, [0.002, -0.001], atol=1e-7)

    depth_stamp = live.client.stamps.next()
    live.client.publish_position((float("nan"), float("nan"), out.pose.pose.position.z - 0.05), depth_stamp)
    depth = live.client.collectors["residuals"].wait_for(stamped(depth_stamp), "/model/residuals of the depth gauge")
    assert list(depth.channels) == ["depth"]
    np.testing.assert_allclose(depth.residuals, [-0.05], atol=1e-6)
    assert depth.noise[0] == pytest.approx(plant.noise["depth"])

    statuses = live.client.diagnostics(lambda s: "depth rms" in s["winch_monitor: model vs measurement"][2],
                                       "model vs measurement with the depth channel")
    values = statuses["winch_monitor: model vs measurement"][2]
    assert {"tension_cable_1 rms", "roll rms", "pitch rms", "depth rms/noise"} <= set(values)


def test_parameter_file_holds_the_defaults_and_the_launch_file_compiles():
    """The shipped YAML lists every parameter at its default (the fixture's node reads it);
    the launch file (launch_ros is not installable here) at least compiles."""
    parameters = yaml.safe_load(PARAMS_FILE.read_text())[NODE_NAME]["ros__parameters"]
    assert parameters == {name: default for name, default, _ in PARAMETERS}
    launch_file = ROOT / "launch" / "winch_monitor.launch.py"
    source = launch_file.read_text()
    compile(source, str(launch_file), "exec")
    assert "get_package_share_directory" in source and "LaunchConfiguration(\"plant_file\")" in source
