"""`play`: a bag's messages published on their topics at their log times, with /clock, as `ros2 bag play --clock`.

For sites without rosbag2 (PyPI's ROS 2 has none) and for tests that feed the live node a
recording over DDS: every message goes out as the CDR bytes stored in the bag, `rate` times
as fast as it was recorded, and /clock (rosgraph_msgs/Clock) carries each message's log
time just before it, so that a node with `use_sim_time` lives in the recording's time. The
player waits (up to `wait`) until something subscribes to the winches' topics, then until
the other topics are matched too (or no match comes for a second), before it starts; Ctrl-C
stops it.
"""
from __future__ import annotations

import math
import sys
import time
from collections.abc import Sequence
from pathlib import Path

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock

from ..bagio.reader import BagError, BagReader
from ..messages.fields import input_topics
from .conversions import message_class
from .session import ros_session

NODE_NAME = "cable_winch_monitor_player"
QOS = QoSProfile(reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST, depth=100)
WINCHES = ("/winch/joint_states", *(f"/winch_{i}/joint_states" for i in range(1, 5)))
SETTLE = 5.0  # [s] longest wait for the other topics' subscribers once the winches' are there
QUIET = 1.0  # [s] without a new match: the topics left have no subscriber


class Player(Node):
    """Publishers for a bag's topics and /clock."""

    def __init__(self, topics: dict[str, str]):
        super().__init__(NODE_NAME)
        self.clock = self.create_publisher(Clock, "/clock", QOS)
        self.publishers_: dict[str, Publisher] = {}
        for topic, msgtype in topics.items():
            self.publisher(topic, msgtype)

    def publisher(self, topic: str, msgtype: str) -> Publisher:
        """The topic's publisher, made at its first message where the bag's summary did not list it."""
        if topic not in self.publishers_:
            self.publishers_[topic] = self.create_publisher(message_class(msgtype), topic, QOS)
        return self.publishers_[topic]

    def listened(self) -> bool:
        """Something subscribes to one of the winches' topics."""
        return any(self.publishers_[t].get_subscription_count() > 0 for t in WINCHES if t in self.publishers_)

    def matched(self) -> tuple[int, ...]:
        """How many subscribers each topic has (discovery matches the topics one by one)."""
        return tuple(publisher.get_subscription_count() for publisher in self.publishers_.values())


def play(bag: str | Path, rate: float = 1.0, clock: bool = True, wait: float = 30.0,
         topics: Sequence[str] | None = None, until: float = math.inf) -> int:
    """Publish the bag's messages (the monitor's inputs, or `topics`) at their log times sped up by `rate`,
    with /clock where `clock`, the first `until` seconds of the bag; the exit status."""
    if not rate > 0.0:
        print(f"play: the rate must be positive, got {rate}", file=sys.stderr)
        return 2
    wanted = input_topics() if topics is None else None
    try:
        reader = BagReader(bag, wanted)
    except BagError as error:
        print(f"play: {error}", file=sys.stderr)
        return 2
    types = {topic: msgtype for topic, msgtype in reader.listed_types().items() if topics is None or topic in topics}
    try:
        with ros_session(lambda: Player(types)) as node:
            deadline = time.monotonic() + wait
            while not node.listened() and time.monotonic() < deadline:
                rclpy.spin_once(node, timeout_sec=0.05)
            _settle(node, min(deadline, time.monotonic() + SETTLE))
            published = _publish(node, reader, rate, clock, until, topics)
    except (KeyboardInterrupt, ExternalShutdownException):
        return 130
    print(f"played {published} messages of {bag}")
    return 0


def _settle(node: Player, deadline: float) -> None:
    """Wait until every topic has a subscriber, or until no new match has come for QUIET seconds (a topic
    nothing subscribes to), or `deadline`: a subscriber matched to the winches' topics may not be matched
    to the inclinometer's yet, and a reliable publisher's first messages go nowhere before the match."""
    counts, since = node.matched(), time.monotonic()
    while time.monotonic() < deadline and not all(counts) and time.monotonic() - since < QUIET:
        rclpy.spin_once(node, timeout_sec=0.05)
        now = node.matched()
        if now != counts:
            counts, since = now, time.monotonic()


def _publish(node: Player, reader: BagReader, rate: float, clock: bool, until: float,
             topics: Sequence[str] | None) -> int:
    """Every message (of `topics`, None: all the reader delivers) at its log time (`rate` times as fast),
    /clock before it, the first `until` seconds; the count published."""
    started, first, count = time.monotonic(), None, 0
    for item in reader:
        if topics is not None and item.topic not in topics:
            continue
        publisher = node.publisher(item.topic, item.msgtype)
        first = item.log_time if first is None else first
        if (item.log_time - first) * 1e-9 > until:
            break
        delay = started + (item.log_time - first) * 1e-9 / rate - time.monotonic()
        if delay > 0.0:
            time.sleep(delay)
        if clock:
            sec, nanosec = divmod(item.log_time, 1_000_000_000)
            node.clock.publish(Clock(clock=rclpy.time.Time(seconds=sec, nanoseconds=nanosec).to_msg()))
        publisher.publish(item.data)
        count += 1
    return count
