"""One rclpy node for the life of a command (play, record): rclpy started, the node made, both ended on the way out."""
from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import TypeVar

import rclpy
from rclpy.node import Node

N = TypeVar("N", bound=Node)


@contextmanager
def ros_session(make: Callable[[], N]) -> Iterator[N]:
    """rclpy initialised and the node `make` builds; the node destroyed and rclpy shut down whatever happens
    (Ctrl-C, an external shutdown, an error), so that a command leaves no DDS participant behind."""
    rclpy.init()
    node: N | None = None
    try:
        node = make()
        yield node
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
