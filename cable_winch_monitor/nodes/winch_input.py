"""A winch topic read to the end of its queue at every callback, counting what DDS dropped unseen.

rclpy's executor hands over one message per wake-up, at a cost of a few hundred
microseconds; at 1 kHz on a shared core it fell behind and the queue held a second of
stale samples. A callback here takes every message waiting in the subscription's queue
at once. The queue is short (KEEP_LAST), so that it can never hold stale work; what it
overwrites shows as a gap in the publisher's sequence numbers and is counted. The sensors'
queues are emptied too before the winch messages are merged (`waiting`): a reading sent
before a winch message must reach the sample first, as it does in a replay in log order.
"""
from __future__ import annotations

from typing import Any

from rclpy.subscription import Subscription


class WinchInput:
    """The messages of one winch topic: `drain` them; `unseen` counts those DDS dropped before the node took them."""

    def __init__(self, topic: str):
        self.topic = topic
        self.subscription: Subscription | None = None
        self.unseen = 0
        self._last_sequence = 0

    def drain(self, message: Any, info: dict[str, Any]) -> list[Any]:
        """`message` (just delivered, with its `info`) and every message waiting behind it, in arrival order."""
        messages = [message]
        counted = self.subscription is not None and self.subscription.get_publisher_count() == 1
        self._note(info, counted)
        for taken, taken_info in waiting(self.subscription) if self.subscription is not None else ():
            messages.append(taken)
            self._note(taken_info, counted)
        return messages

    def _note(self, info: dict[str, Any], counted: bool) -> None:
        """Count the gap before this message's publication sequence number (one publisher only: the numbers of
        several publishers interleave)."""
        sequence = int(info.get("publication_sequence_number") or 0)
        if counted and self._last_sequence and sequence > self._last_sequence + 1:
            self.unseen += sequence - self._last_sequence - 1
        self._last_sequence = sequence


def waiting(subscription: Subscription) -> list[tuple[Any, dict[str, Any]]]:
    """Every message waiting in `subscription`'s queue, with its info, in arrival order."""
    out: list[tuple[Any, dict[str, Any]]] = []
    while True:
        with subscription.handle:
            taken = subscription.handle.take_message(subscription.msg_type, False)
        if taken is None:
            return out
        out.append(taken)
