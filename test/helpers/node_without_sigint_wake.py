"""`winch_monitor` with the wake-up that rclpy's SIGINT handler gives the executor taken away: the executor's
signal guard condition is never registered with the handler, so a SIGINT only sets Python's pending signal,
as when a node was seen stopped in its wait after a SIGINT (a test's teardown, with use_sim_time and no more
/clock). Run as a script, with the node's ROS arguments."""
from __future__ import annotations

import sys

import rclpy.executors
from rclpy.guard_condition import GuardCondition


class _Unregistered(GuardCondition):
    """A guard condition in the signal guard's place that no signal triggers."""

    def __init__(self, context=None):
        super().__init__(callback=None, callback_group=None, context=context)


rclpy.executors.SignalHandlerGuardCondition = _Unregistered

if __name__ == "__main__":
    from cable_winch_monitor.nodes.winch_monitor import main

    sys.exit(main())
