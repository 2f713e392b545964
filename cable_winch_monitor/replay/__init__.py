"""Replay: a recorded bag through the monitor, a window of messages at a time, every output into a new bag.

`run` (the `replay` function and its summary), `windows` (the scheduler: merge, then the stages, then the
messages in log order), `stages` (what becomes of a window's samples), `second_process` and `worker` (the
stages run in a forked process beside the reading).
"""
from .run import INVALID, ReplaySummary, TopicCount, replay

__all__ = ["INVALID", "ReplaySummary", "TopicCount", "replay"]
