"""Replay and the live node, fed the same joint states, publish the same outputs.

The node runs in its own process (`winch_monitor`, ROS_DOMAIN_ID from 60-69) and gets
the bag's /winch/joint_states over real DDS, as the CDR bytes stored in the bag, one
at a time in log order (each sample's outputs are awaited before the next is sent, so
that no queue can drop or reorder anything). Replay reads the same joint states (the
load pins with them) and no other sensor. Its outputs must equal the replay's to the bit:
the node estimates its samples as they come, replay a window of them at once, and a
sample's estimate does not depend on the samples estimated with it. (With each winch on
its own topic the node merges by the arrival of each message, which this feed does not
keep; that case is compared in one process, `test_monitor_fusion.py`.)
"""
from __future__ import annotations

import time
from collections import defaultdict
from pathlib import Path
from typing import Any

import ros_harness
from ros_harness import NodeProcess, TestClient, stamp_key
from simbags import simulated

from cable_winch_monitor.bagio.reader import BagReader
from cable_winch_monitor.bagio.writer import BagWriter
from cable_winch_monitor.channels import JOINT_STATE
from cable_winch_monitor.messages.outputs import ALARM, OUTPUT_TYPES, POSE, TENSION
from cable_winch_monitor.replay import replay

JOINTS = {"/winch/joint_states": JOINT_STATE}
COLLECTORS = {POSE: "pose", TENSION: "tension", ALARM: "alarm"}


def joint_states_only(bag: Path, out: Path) -> Path:
    """A copy of the bag with its joint states alone (the bytes as stored)."""
    with BagWriter(out) as writer:
        for item in BagReader(bag, JOINTS):
            writer.write_raw(item.topic, item.msgtype, item.log_time, item.data)
    return out


def replayed(bag: Path, out: Path) -> dict[str, dict[tuple[int, int], object]]:
    """Topic -> input stamp -> the replay's output message."""
    replay(bag, out, progress=False)
    outputs: dict[str, dict[tuple[int, int], object]] = defaultdict(dict)
    for item in BagReader(out, {topic: OUTPUT_TYPES[topic] for topic in COLLECTORS}):
        key = stamp_key(item.message.header.stamp)
        assert key not in outputs[item.topic], f"two {item.topic} for one stamp"
        outputs[item.topic][key] = item.message
    return outputs


def wait_connected(client: TestClient, node: NodeProcess, timeout: float = 20.0) -> None:
    deadline = time.monotonic() + timeout
    outputs = [client.subscriptions[list(ros_harness.OUTPUTS).index(key)] for key in COLLECTORS.values()]
    while not (client.winch.get_subscription_count() > 0 and all(s.get_publisher_count() > 0 for s in outputs)):
        node.assert_alive()
        assert time.monotonic() < deadline, f"winch_monitor did not match within {timeout} s:\n{node.output()}"
        time.sleep(0.05)
    time.sleep(1.0)  # let the node's side of discovery finish too


def fed_live(bag: Path, domain: int, expected: dict) -> dict[str, dict[tuple[int, int], object]]:
    """Publish the bag's joint states to a live node; topic -> stamp -> what it published."""
    node = NodeProcess(domain, {"stamp_behind": 1e10})  # the bag's stamps are its recording's, not today's
    client = TestClient(domain, node)
    try:
        wait_connected(client, node)
        tension = client.collectors["tension"]
        for item in BagReader(bag, JOINTS):
            key = stamp_key(item.message.header.stamp)
            start = tension.count()
            client.winch.publish(item.data)
            if key in expected[TENSION]:
                tension.wait_for(lambda m, key=key: stamp_key(m.header.stamp) == key, f"/cables/tension for {key}",
                                 start=start)
        time.sleep(0.5)  # anything published without a replay counterpart arrives too
        node.assert_alive()
        live: dict[str, dict[tuple[int, int], object]] = defaultdict(dict)
        for topic, name in COLLECTORS.items():
            for _, msg in client.collectors[name].messages:
                key = stamp_key(msg.header.stamp)
                assert key not in live[topic], f"two {topic} for stamp {key}"
                live[topic][key] = msg
        return live
    finally:
        client.close()
        node.stop()


def pose_values(pose: Any) -> list[float]:
    """A geometry_msgs/Pose's numbers (an rclpy message's or a rosbags one's)."""
    position, orientation = pose.position, pose.orientation
    return [position.x, position.y, position.z, orientation.x, orientation.y, orientation.z, orientation.w]


def test_replay_equals_live_node(tmp_path, domain_id):
    bag = simulated(tmp_path, "lag_slack", "duration=16")  # taut, then cable 2 slack with a WARNING
    expected = replayed(joint_states_only(bag, tmp_path / "joint_states"), tmp_path / "replayed")
    live = fed_live(bag, domain_id, expected)
    assert len(expected[TENSION]) > 150 and {m.level for m in expected[ALARM].values()} == {0, 1}
    for topic in COLLECTORS:
        assert live[topic].keys() == expected[topic].keys(), topic
    for key, want in expected[POSE].items():
        assert pose_values(live[POSE][key].pose) == pose_values(want.pose), key
    for key, want in expected[TENSION].items():
        got = live[TENSION][key]
        assert (got.status, got.tension_state, got.solver, got.equilibrium_residual) == \
            (want.status, want.tension_state, want.solver, want.equilibrium_residual)
        assert list(got.sensors_used) == list(want.sensors_used)
        assert list(got.length_corrections_sigma) == list(want.length_corrections_sigma)
        assert [(c.name, c.taut, c.tension, c.span, c.length) for c in got.cables] == \
            [(c.name, c.taut, c.tension, c.span, c.length) for c in want.cables], key
    for key, want in expected[ALARM].items():
        got = live[ALARM][key]
        assert (got.level, got.closest_point_name, got.reason, got.clearance) == \
            (want.level, want.closest_point_name, want.reason, want.clearance)
        assert list(got.sync_error_pairs) == list(want.sync_error_pairs)
        assert list(got.sync_errors) == list(want.sync_errors)
