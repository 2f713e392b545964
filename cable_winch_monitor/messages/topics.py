"""What a bag holds before it is read: its topics as its files' summaries list them.

A command refuses a bag that lacks a topic the plant's effects read (a shaft temperature)
before it starts the work, not after a replay of samples it could not solve. A file
without a summary (a recording cut short) lists nothing: its topics are known only once
it is read, and the reading refuses the bag then (analysis.data).
"""
from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from ..bagio.mcapfile import McapError, McapFile
from ..bagio.reader import BagError, ReadReport, bag_files
from ..channels import Input


def listed_topics(bag: str | Path) -> dict[str, int | None] | None:
    """Topic -> messages (None where the summary gives no count) over every file of the bag; None if some
    file has no summary listing its channels. BagError if the path holds no bag."""
    path = Path(bag)
    topics: dict[str, int | None] = {}
    for file in bag_files(path, ReadReport(path)):
        try:
            with McapFile(file) as mcap:
                if not mcap.channels:
                    return None
                for channel_id, channel in mcap.channels.items():
                    count = None if mcap.channel_counts is None else mcap.channel_counts.get(channel_id, 0)
                    known = topics.get(channel.topic, 0)
                    topics[channel.topic] = None if count is None or known is None else known + count
        except (McapError, OSError):
            return None  # the reader says what is wrong with the file
    return topics


def missing_input(bag: str | Path, spec: Input) -> BagError:
    """The error for a bag without any message of an input the plant's effects read."""
    return BagError(f"{bag}: the plant's effects read {spec.key} ({spec.msgtype}), which the bag does not have: "
                    "record that topic, or switch the effect off")


def require_inputs(bag: str | Path, inputs: Sequence[Input]) -> None:
    """Refuse (BagError) a bag whose summaries show no message of an input the plant's effects read."""
    if not inputs:
        return
    topics = listed_topics(bag)
    if topics is None:
        return
    for spec in inputs:
        if topics.get(spec.topic, 0) == 0:
            raise missing_input(bag, spec)
