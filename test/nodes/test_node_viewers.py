"""What a viewer gets from the live node over real DDS: /tf, the latched /tf_static, and the 3-D scene at a
bounded rate, each checked against the physics of the pure model's solve."""
from __future__ import annotations

import math

import pytest
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from ros_harness import DEEP_QOS, Collector, LiveNode, stamped
from scene_checks import check_outline, check_scene, check_static_tf, check_transform
from tf2_msgs.msg import TFMessage
from visualization_msgs.msg import MarkerArray

from cable_winch_monitor.model.solvers.solve import solve
from cable_winch_monitor.monitor.alarm import AlarmLevel
from cable_winch_monitor.seed002 import TABLE_1

pytestmark = pytest.mark.timeout(60)

SCENE_RATE = 5.0  # [1/s]
LATCHED = QoSProfile(reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST, depth=1,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)


@pytest.fixture(scope="module")
def live():
    node = LiveNode({"scene_rate": SCENE_RATE})
    collectors = {"tf": Collector(), "tf_static": Collector(), "scene": Collector(), "outline": Collector()}
    # subscribed after the node has published them: only a latched topic reaches this late subscriber
    node.client.node.create_subscription(TFMessage, "/tf_static", collectors["tf_static"], LATCHED)
    node.client.node.create_subscription(MarkerArray, "/platform/outline", collectors["outline"], LATCHED)
    node.client.node.create_subscription(TFMessage, "/tf", collectors["tf"], DEEP_QOS)
    node.client.node.create_subscription(MarkerArray, "/platform/scene", collectors["scene"], DEEP_QOS)
    yield node, collectors
    assert node.close() == 0


def test_sheave_frames_and_deck_outlines_reach_a_late_subscriber(live, plant):
    _, collectors = live
    check_static_tf(collectors["tf_static"].wait_for(lambda m: True, "/tf_static"), plant)
    check_outline(collectors["outline"].wait_for(lambda m: True, "/platform/outline"), plant)


def test_tf_and_scene_of_a_solved_sample(live, plant):
    node, collectors = live
    lengths = TABLE_1[4]  # cable 3 hangs 0.5 m loose
    expected = solve(plant, lengths)
    node.client.solve((20.0,) * 4)
    stamp = node.client.stamps.next(advance=1.0 / SCENE_RATE)  # a scene is due
    out = node.client.outputs(node.client.publish(lengths, stamp=stamp), pose=True)
    transform = collectors["tf"].wait_for(lambda m: stamped(stamp)(m.transforms[0]), "/tf of the sample")
    pose = out.pose.pose
    check_transform(transform.transforms[0], "shaft", "platform",
                    [pose.position.x, pose.position.y, pose.position.z],
                    [pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w])
    scene = collectors["scene"].wait_for(lambda m: stamped(stamp)(m.markers[0]), "/platform/scene of the sample")
    check_scene(scene, plant, expected, AlarmLevel(out.alarm.level), out.alarm.clearance)
    assert out.alarm.level >= AlarmLevel.WARNING and "slack" in scene.markers[-1].text


def test_scene_rate_is_bounded_by_the_stamps(live):
    node, collectors = live
    node.client.stamps.catch_up()  # 0.2 s + 40 stamps at 50 Hz lead the clock by about 1 s, inside stamp_ahead
    first = node.client.stamps.next(advance=1.0 / SCENE_RATE)  # a scene is due
    stamps = [first] + [node.client.stamps.next(advance=0.02) for _ in range(39)]  # 50 Hz of stamps for 0.8 s
    for k, stamp in enumerate(stamps):
        node.client.publish((20.0 + 0.01 * k,) * 4, stamp=stamp)
    node.client.outputs(stamps[-1], pose=True)
    collectors["tf"].wait_for(lambda m: stamped(stamps[-1])(m.transforms[0]), "/tf of the last sample")
    keys = {(s.sec, s.nanosec) for s in stamps}

    def of_these(scene):
        return (scene.markers[0].header.stamp.sec, scene.markers[0].header.stamp.nanosec) in keys

    collectors["scene"].wait_for(of_these, "/platform/scene of a sample")  # it may come after the last /tf
    seconds = [s.sec + s.nanosec * 1e-9 for s in stamps]
    tf_count = sum((m.transforms[0].header.stamp.sec, m.transforms[0].header.stamp.nanosec) in keys
                   for _, m in collectors["tf"].messages)
    scenes = [m for _, m in collectors["scene"].messages if of_these(m)]
    poses = sum(bool(node.client.outputs_with_stamp(stamp)["pose"]) for stamp in stamps)  # the node may skip
    assert tf_count == poses >= 1, "a transform for every solved pose"  # samples under load (newest first)
    assert 1 <= len(scenes) <= math.floor((seconds[-1] - seconds[0]) * SCENE_RATE) + 1
