"""Every numeric field of a bag's other topics as a time series, for asking what a residual follows.

A series is keyed "topic.field.path" ("/shaft/temperature.temperature",
"/winch/motor_current.data", "/crane/state.position[0]"). Nested messages are flattened;
numbers and booleans (as 0/1: a brake or mode flag is exactly what an error may follow)
are kept, strings dropped; arrays and sequences are taken element-wise up to
MAX_ELEMENTS elements and skipped beyond (images, scans); header stamps, other
builtin_interfaces/Time fields and covariances are not series. A series is timed at its
message's header stamp, or at the log time where the message has no header (or a zero
stamp). Topics whose type the type store does not know are skipped and named.

Memory and time stay bounded on long bags: at most MAX_SERIES series, and each topic is
thinned evenly while it is read (every 2nd, 4th, ... message once it passes twice
MAX_SAMPLES), then cut to MAX_SAMPLES; what was capped is said in `notes`.
"""
from __future__ import annotations

from collections import defaultdict
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from rosbags.interfaces import Nodetype
from rosbags.typesys.store import Typestore

from ..bagio.mcapfile import McapError, McapFile
from ..bagio.reader import BagReader
from ..messages.fields import input_topics, seconds
from ..messages.outputs import OUTPUT_TYPES

MAX_SERIES = 256
MAX_SAMPLES = 4000   # per series
MAX_ELEMENTS = 8     # longer arrays and sequences are not taken element-wise
HEADER, TIME, DURATION = "std_msgs/msg/Header", "builtin_interfaces/msg/Time", "builtin_interfaces/msg/Duration"
NOT_NUMBERS = ("string", "wstring")


@dataclass
class BagFields:
    """Time series [s, value] of numeric fields keyed "topic.field.path", the topics left out and why,
    and notes on what was capped or thinned."""

    series: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)
    skipped: dict[str, str] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    def remarks(self) -> list[str]:
        """What was not searched, in words: topics left out and caps."""
        return [f"not searched: {topic} ({why})" for topic, why in sorted(self.skipped.items())] + self.notes


class _Topic:
    """One topic's samples while reading: thinned evenly by a doubling stride."""

    def __init__(self, cap: int) -> None:
        self.cap = cap
        self.seen = 0
        self.stride = 1
        self.kept = 0
        self.values: dict[str, tuple[list[float], list[float]]] = defaultdict(lambda: ([], []))

    def wants_next(self) -> bool:
        self.seen += 1
        return (self.seen - 1) % self.stride == 0

    def add(self, time: float, values: dict[str, float]) -> None:
        for path, value in values.items():
            times, series = self.values[path]
            times.append(time)
            series.append(value)
        self.kept += 1
        if self.kept >= 2 * self.cap:
            self.stride *= 2
            self.kept //= 2
            for path, (times, series) in self.values.items():
                self.values[path] = (times[::2], series[::2])


def flatten(message: Any, msgtype: str, store: Typestore, prefix: str = "") -> dict[str, float]:
    """The numeric fields of a message keyed by their path (".a.b[0]"), as described in the module."""
    out: dict[str, float] = {}
    argument: Any  # as `node` says: a base type, a message type's name, or an array's (element, length)
    for name, (node, argument) in store.fielddefs[msgtype][1]:
        if "covariance" in name:
            continue
        value, path = getattr(message, name), f"{prefix}.{name}"
        if node == Nodetype.NAME:
            if argument == DURATION:
                out[path] = value.sec + value.nanosec * 1e-9
            elif argument not in (TIME, HEADER):
                out.update(flatten(value, argument, store, path))
        elif node == Nodetype.BASE:
            if argument[0] not in NOT_NUMBERS:
                out[path] = float(value)
        elif len(value) <= MAX_ELEMENTS:  # ARRAY or SEQUENCE
            (inner, inner_argument), _ = argument
            for k, item in enumerate(value):
                if inner == Nodetype.NAME:
                    out.update(flatten(item, inner_argument, store, f"{path}[{k}]"))
                elif inner_argument[0] not in NOT_NUMBERS:
                    out[f"{path}[{k}]"] = float(item)
    return out


def _stamp(message: Any, msgtype: str, store: Typestore, log_time: int) -> float:
    """The header stamp [s], or the log time where there is no header or it is zero."""
    fields = store.fielddefs[msgtype][1]
    if fields and fields[0] == ("header", (Nodetype.NAME, HEADER)):
        stamp = message.header.stamp
        if stamp.sec or stamp.nanosec:
            return seconds(stamp)
    return log_time * 1e-9


def _topic_types(reader: BagReader, exclude: set[str]) -> dict[str, str] | None:
    """Topic -> type of every topic not excluded, from the files' summaries (None where a file has none:
    then every topic is decoded and the excluded ones dropped)."""
    topics: dict[str, str] = {}
    for path in reader.files:
        try:
            with McapFile(path) as mcap:
                if not mcap.channels:
                    return None
                for channel in mcap.channels.values():
                    schema = mcap.schemas.get(channel.schema_id)
                    if channel.topic not in exclude and schema is not None:
                        topics[channel.topic] = schema.name
        except (McapError, OSError):
            return None
    return topics


def package_topics() -> set[str]:
    """The topics the package reads as winches and channels (those declared so far) or writes itself."""
    return set(input_topics()) | set(OUTPUT_TYPES)


def read_fields(bag: str | Path, exclude: Iterable[str] | None = None, max_series: int = MAX_SERIES,
                max_samples: int = MAX_SAMPLES) -> BagFields:
    """Every numeric field of the bag's topics not in `exclude` (default: `package_topics`) as time series
    (BagError if it is not a bag)."""
    excluded = set(package_topics() if exclude is None else exclude)
    reader = BagReader(bag)
    reader.topics = _topic_types(reader, excluded)
    result = BagFields()
    if reader.topics == {}:  # the summaries list no other topic: nothing to read
        return result
    topics: dict[str, _Topic] = {}
    paths: set[str] = set()
    dropped: set[str] = set()
    for item in reader:
        if item.topic in excluded:
            continue
        topic = topics.setdefault(item.topic, _Topic(max_samples))
        if not topic.wants_next():
            continue
        values = {}
        for path, value in flatten(item.message, item.msgtype, reader.store).items():
            key = item.topic + path
            if key not in paths and len(paths) >= max_series:
                dropped.add(key)
                continue
            paths.add(key)
            values[key] = value
        topic.add(_stamp(item.message, item.msgtype, reader.store, item.log_time), values)
    for (skipped, reason), count in reader.report.skipped.items():
        if skipped not in excluded and reason != "not an input topic":
            result.skipped[skipped] = f"{reason}, {count} messages"
    if dropped:
        result.notes.append(f"more than {max_series} numeric fields: {len(dropped)} not read "
                            f"(e.g. {', '.join(sorted(dropped)[:3])})")
    for name, topic in sorted(topics.items()):
        thinned = False
        for key, (times, series) in sorted(topic.values.items()):
            t, v = np.asarray(times), np.asarray(series)
            order = np.argsort(t, kind="stable")
            if t.size > max_samples:
                order = order[np.linspace(0, t.size - 1, max_samples).round().astype(int)]
            thinned |= topic.stride > 1 or t.size > max_samples
            result.series[key] = (t[order], v[order])
        if thinned:
            result.notes.append(f"{name}: {topic.seen} messages thinned evenly to at most {max_samples} samples")
    return result
