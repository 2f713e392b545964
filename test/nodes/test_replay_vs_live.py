"""Replay and the live node, fed the same joint states, publish the same outputs.

The node runs in its own process (`winch_monitor`, ROS_DOMAIN_ID from 60-69) and gets
the bag's /winch/joint_states over real DDS, as the CDR bytes stored in the bag, one
at a time in log order (each sample's outputs are awaited before the next is sent, so
that no queue can drop or reorder anything). Replay reads the same joint states (the
load pins with them) and no other sensor. Its outputs must equal the replay's: the
fused estimate converges to TOLERANCE (the node warm-starts each sample from the last,
replay starts each window's samples from their forward kinematics).
"""
from __future__ import annotations

import time
from collections import defaultdict
from pathlib import Path

import ros_harness
from ros_harness import NodeProcess, TestClient, stamp_key
from simbags import simulated

from cable_winch_monitor.bagio.reader import BagReader
from cable_winch_monitor.bagio.writer import BagWriter
from cable_winch_monitor.messages.records import ALARM, OUTPUT_TYPES, POSE, TENSION
from cable_winch_monitor.replay import replay

JOINTS = "/winch/joint_states"
COLLECTORS = {POSE: "pose", TENSION: "tension", ALARM: "alarm"}
TOLERANCE = 1e-6  # [m, rad, relative] the estimator's convergence (model.fusion.STEP_TOL)


def joint_states_only(bag: Path, out: Path) -> Path:
    """A copy of the bag with its joint states alone (the bytes as stored)."""
    with BagWriter(out) as writer:
        for item in BagReader(bag, {JOINTS: "sensor_msgs/msg/JointState"}):
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
        for item in BagReader(bag, {JOINTS: "sensor_msgs/msg/JointState"}):
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


def close(a: float, b: float) -> bool:
    return abs(a - b) <= TOLERANCE * max(1.0, abs(a), abs(b))


def test_replay_equals_live_node(tmp_path, domain_id):
    bag = simulated(tmp_path, "lag_slack", "duration=16")  # taut, then cable 2 slack with a WARNING
    expected = replayed(joint_states_only(bag, tmp_path / "joint_states"), tmp_path / "replayed")
    live = fed_live(bag, domain_id, expected)
    assert len(expected[TENSION]) > 150 and {m.level for m in expected[ALARM].values()} == {0, 1}
    for topic in COLLECTORS:
        assert live[topic].keys() == expected[topic].keys(), topic
    for key, want in expected[POSE].items():
        got = live[POSE][key].pose
        pairs = [(got.position.x, want.pose.position.x), (got.position.y, want.pose.position.y),
                 (got.position.z, want.pose.position.z), (got.orientation.x, want.pose.orientation.x),
                 (got.orientation.y, want.pose.orientation.y), (got.orientation.z, want.pose.orientation.z),
                 (got.orientation.w, want.pose.orientation.w)]
        assert all(abs(a - b) <= TOLERANCE for a, b in pairs), (key, pairs)
    for key, want in expected[TENSION].items():
        got = live[TENSION][key]
        assert (got.status, got.tension_state, got.solver) == (want.status, want.tension_state, want.solver)
        assert list(got.sensors_used) == list(want.sensors_used)
        assert all(abs(g - w) <= 1e-3 for g, w in zip(got.length_corrections_sigma, want.length_corrections_sigma))
        assert [(c.name, c.taut) for c in got.cables] == [(c.name, c.taut) for c in want.cables]
        assert all(close(g.tension, w.tension) and close(g.span, w.span) and close(g.length, w.length)
                   for g, w in zip(got.cables, want.cables)), key
    for key, want in expected[ALARM].items():
        got = live[ALARM][key]
        assert (got.level, got.closest_point_name, got.reason) == (want.level, want.closest_point_name, want.reason)
        assert close(got.clearance, want.clearance)
        assert list(got.sync_error_pairs) == list(want.sync_error_pairs)
        assert all(close(g, w) for g, w in zip(got.sync_errors, want.sync_errors))
