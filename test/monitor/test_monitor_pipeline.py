"""The monitor pipeline without ROS: merging by name, rejections with reasons, warm-started solves."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from cable_winch_monitor.model.plantfile.plant import CABLE_NAMES
from cable_winch_monitor.model.solvers.solve import solve
from cable_winch_monitor.monitor.inputs import JointSample, small_mean
from cable_winch_monitor.monitor.pipeline import MonitorPipeline


@pytest.fixture
def pipeline(plant):
    return MonitorPipeline(plant, staleness=0.5)


def all_cables(stamp, lengths, **kwargs):
    return JointSample(stamp, list(CABLE_NAMES), list(lengths), **kwargs)


def test_one_message_with_all_cables_is_solved_as_solve_would(plant, pipeline):
    output = pipeline.on_joint_state(all_cables(1.0, [20.3, 20.1, 20.5, 20.2]))
    reference = solve(plant, [20.3, 20.1, 20.5, 20.2])
    assert output.stamp == 1.0 and output.solution.taut_set == (1, 2, 4)
    np.testing.assert_allclose(output.solution.points_b, reference.points_b, atol=1e-9)


def test_per_winch_messages_merge_by_name_in_any_order(plant, pipeline):
    order = [2, 0, 3]
    for k, cable in enumerate(order):
        assert pipeline.on_joint_state(JointSample(1.0 + 0.01 * k, [CABLE_NAMES[cable]], [20.0 + cable * 0.1],
                                                   topic=f"/winch_{cable + 1}/joint_states")) is None
    assert pipeline.stats.waiting == "waiting for cable_2"
    output = pipeline.on_joint_state(JointSample(1.05, ["cable_2"], [20.1], topic="/winch_2/joint_states"))
    assert output is not None and output.stamp == 1.05
    np.testing.assert_allclose(output.solution.lengths, [20.0, 20.1, 20.2, 20.3])


def test_readings_are_carried_to_the_sample_stamp_with_their_speed(pipeline):
    """Winch 4 reports last, 0.06 s after winch 1: the others moved on at 0.5 m/s meanwhile."""
    for cable in range(4):
        stamp = 1.0 + 0.02 * cable
        output = pipeline.on_joint_state(JointSample(stamp, [CABLE_NAMES[cable]], [30.0 + 0.5 * (stamp - 1.0)],
                                                     velocities=[0.5], topic=f"/winch_{cable + 1}/joint_states"))
    np.testing.assert_allclose(output.solution.lengths, 30.03, atol=1e-12)


@pytest.mark.parametrize("sample, reason", [
    (all_cables(1.0, [np.nan, 20, 20, 20]), "bad length"),
    (all_cables(1.0, [np.inf, 20, 20, 20]), "bad length"),
    (all_cables(1.0, [-3.0, 20, 20, 20]), "bad length"),
    (JointSample(1.0, ["cable_1", "cable_1", "cable_3", "cable_4"], [20, 20, 20, 20]), "duplicate cable names"),
    (JointSample(1.0, ["drum_brake"], [1.0]), "no cable in message"),
    (JointSample(1.0, list(CABLE_NAMES), [20, 20, 20]), "malformed message"),
])
def test_bad_input_is_rejected_with_a_reason_and_never_solved(pipeline, sample, reason):
    assert pipeline.on_joint_state(sample) is None
    assert any(reason in key for key in pipeline.stats.rejected), pipeline.stats.rejected
    assert reason in pipeline.stats.last_rejection


def test_other_joints_in_a_message_are_ignored_and_counted(pipeline):
    sample = JointSample(1.0, ["cable_1", "drum_brake", "cable_2", "cable_3", "cable_4"], [30, 1, 30, 30, 30])
    assert pipeline.on_joint_state(sample).solution.ok
    assert pipeline.stats.ignored_names["drum_brake"] == 1


def test_stamps_going_backwards_are_rejected_and_the_next_good_sample_solves(pipeline):
    assert pipeline.on_joint_state(all_cables(2.0, [30.0] * 4)).solution.ok
    assert pipeline.on_joint_state(all_cables(1.5, [30.1] * 4)) is None
    assert "stamp not increasing" in pipeline.stats.last_rejection
    assert pipeline.on_joint_state(all_cables(2.1, [30.2] * 4)).solution.ok


def test_a_stale_winch_stops_solving(pipeline):
    pipeline.on_joint_state(all_cables(1.0, [30.0] * 4))
    for k in range(1, 4):
        output = pipeline.on_joint_state(JointSample(1.0 + 0.3 * k, CABLE_NAMES[:3], [30.0 + 0.01 * k] * 3))
    assert output is None and "cable_4" in pipeline.stats.waiting and "stale" in pipeline.stats.waiting


def test_every_message_is_accounted_for(pipeline):
    rng = np.random.default_rng(7)
    for k in range(300):
        lengths = 40.0 + rng.normal(0.0, 0.01, 4)
        if k % 7 == 0:
            lengths[k % 4] = np.nan
        pipeline.on_joint_state(all_cables(0.1 * k, lengths))
    stats = pipeline.stats
    topic = "/winch/joint_states"
    rejected_messages = stats.messages[topic] - stats.used[topic]
    assert stats.messages[topic] == 300
    assert rejected_messages == sum(stats.rejected.values()) == 43
    assert stats.solved == 300 - 43



def point(x: float, y: float, z: float) -> SimpleNamespace:
    """A geometry_msgs/PointStamped's fields as the channels read them."""
    return SimpleNamespace(point=SimpleNamespace(x=x, y=y, z=z))


def orientation(x: float, y: float, z: float, w: float) -> SimpleNamespace:
    """A sensor_msgs/Imu's orientation as the channels read it."""
    return SimpleNamespace(orientation=SimpleNamespace(x=x, y=y, z=z, w=w))

def test_measurements_give_residuals_against_the_latest_pose(plant, pipeline):
    output = pipeline.on_joint_state(all_cables(1.0, [20.3, 20.1, 20.5, 20.2], efforts=[6000.0, 49000.0, 0.0, 43000.0]))
    channels = dict(zip(output.residuals.channels, output.residuals.values))
    assert channels["tension_cable_1"] == pytest.approx(6000.0 - output.solution.tensions[0])
    depth = pipeline.on_measurement("/platform/position", 1.02, point(np.nan, np.nan, -25.0))
    assert depth.channels == ("depth",)
    assert depth.values[0] == pytest.approx(-25.0 - output.solution.position[2])
    imu = pipeline.on_measurement("/platform/imu", 1.03, orientation(0.0, 0.0, 0.0, 1.0))
    assert set(imu.channels) == {"roll", "pitch"}
    assert pipeline.on_measurement("/platform/imu", 5.0, orientation(0.0, 0.0, 0.0, 1.0)) is None
    assert "staleness" in pipeline.stats.last_rejection


def test_small_mean_is_numpys_mean_bit_for_bit():
    """The payout mean the depth gauge is carried by must not move by an ulp against numpy's."""
    rng = np.random.default_rng(7)
    for _ in range(20_000):
        values = (rng.normal(size=rng.integers(1, 8)) * 10.0 ** rng.uniform(-4, 4)).tolist()
        assert small_mean(values) == float(np.mean(values))
    assert str(small_mean([-0.0] * 4)) == str(float(np.mean([-0.0] * 4)))  # the sign of zero too
    assert np.isnan(small_mean([1.0, float("nan"), 2.0, 3.0])) and np.isnan(small_mean([np.inf, -np.inf]))
    with pytest.raises(ValueError, match="1 to 7 values"):
        small_mean([1.0] * 8)
