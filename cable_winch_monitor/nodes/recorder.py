"""`record`: ROS topics into a rosbag2 bag (MCAP) for sites without rosbag2.

Raw subscriptions hand over the CDR bytes exactly as they came off the wire; they are
written unchanged (rclpy's serialize_message may pad empty float64[] fields, which
rosbags then rejects). A topic is subscribed once it appears in the graph, with the
reliability its publishers offer. Log time is the node clock at receipt. Ctrl-C or
SIGTERM stops the recording and the bag is closed complete.
"""
from __future__ import annotations

import sys
from collections import Counter
from collections.abc import Sequence
from pathlib import Path

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

from ..bagio.reader import BagError
from ..bagio.typestore import knows
from ..bagio.writer import BagWriter
from ..messages.fields import input_topics
from .conversions import message_class
from .session import ros_session

NODE_NAME = "cable_winch_monitor_recorder"
GRAPH_PERIOD = 0.5  # [s] between looks for topics not yet subscribed
DEPTH = 1000


class Recorder(Node):
    """Subscribes the wanted topics as they appear and writes every message into the bag."""

    def __init__(self, writer: BagWriter, topics: Sequence[str]):
        super().__init__(NODE_NAME)
        self.writer = writer
        self.waiting = list(dict.fromkeys(topics))
        self.subscribed: dict[str, str] = {}
        self.refused: dict[str, str] = {}
        self.create_timer(GRAPH_PERIOD, self._look)
        self._look()

    def _look(self) -> None:
        graph = dict(self.get_topic_names_and_types())
        for topic in [t for t in self.waiting if t in graph]:
            self.waiting.remove(topic)
            msgtype = graph[topic][0]
            if not knows(self.writer.store, msgtype):
                self.refused[topic] = f"type {msgtype} unknown to the type store"
            else:
                self._subscribe(topic, msgtype)
            self.get_logger().info(f"{topic}: " + (f"recording ({msgtype})" if topic in self.subscribed
                                                    else f"not recorded: {self.refused[topic]}"))

    def _subscribe(self, topic: str, msgtype: str) -> None:
        try:
            kind = message_class(msgtype)
        except (ImportError, AttributeError, ValueError) as error:
            self.refused[topic] = f"no rclpy message for {msgtype} ({error})"
            return
        offered = self.get_publishers_info_by_topic(topic)
        reliable = offered and all(p.qos_profile.reliability == ReliabilityPolicy.RELIABLE for p in offered)
        qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=DEPTH,
                         reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT)
        # raw=True: rclpy hands the callback the serialised bytes, where its types say a message
        self.create_subscription(kind, topic, lambda data: self._write(topic, msgtype, data),  # type: ignore[arg-type]
                                 qos, raw=True)
        self.subscribed[topic] = msgtype

    def _write(self, topic: str, msgtype: str, data: bytes) -> None:
        self.writer.write_raw(topic, msgtype, self.get_clock().now().nanoseconds, data)


def record(out: str | Path, topics: Sequence[str] = ()) -> int:
    """Record until Ctrl-C / SIGTERM; 0 when the bag was closed, 2 if it could not be created."""
    topics = list(topics) or list(input_topics())
    try:
        writer = BagWriter(out)
    except BagError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    node: Recorder | None = None
    try:
        with ros_session(lambda: Recorder(writer, topics)) as node:
            print(f"recording into {out}: {', '.join(topics)} (Ctrl-C to stop)", file=sys.stderr)
            rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        writer.close()
    counts: Counter[str] = writer.counts
    print(f"recorded {sum(counts.values())} messages into {out}: "
          + (", ".join(f"{t} {n}" for t, n in sorted(counts.items())) or "none"))
    if node is not None:
        print("".join(f"  {t}: not recorded: {why}\n" for t, why in node.refused.items())
              + "".join(f"  {t}: never published\n" for t in node.waiting), end="")
    return 0
