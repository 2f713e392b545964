"""Read a rosbag2 directory or a bare .mcap file as a stream of decoded messages in log order.

Nothing is skipped in silence and nothing raises mid-stream: a message that is not
delivered is counted in the report with its reason (topic not asked for, wrong or
unknown type, undecodable), and damaged parts of the files are listed with the messages
they cost. Only a path that holds no bag at all raises BagError, before any reading.
"""
from __future__ import annotations

from collections import Counter
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rosbags.typesys.store import Typestore

from ..safe_yaml import YamlLimitError, load_yaml_file
from .decode import decode, decodes_as
from .mcapfile import McapError, McapFile
from .typestore import knows, typestore


class BagError(Exception):
    """The path cannot be read as a bag at all; the message says why."""


@dataclass(frozen=True)
class BagMessage:
    topic: str
    msgtype: str
    log_time: int  # [ns]
    data: bytes  # the CDR bytes as stored
    message: Any  # decoded (rosbags message object)


@dataclass
class ReadReport:
    """What reading a bag did with every message in it."""

    path: Path
    files: list[Path] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    types: dict[str, str] = field(default_factory=dict)  # topic -> message type
    read: Counter[str] = field(default_factory=Counter)  # messages found per topic
    skipped: Counter[tuple[str, str]] = field(default_factory=Counter)  # (topic, reason) -> count
    damage: list[str] = field(default_factory=list)
    lost: Counter[str] = field(default_factory=Counter)  # per topic, in unreadable chunks (where indexed)
    expected: int | None = None  # messages the bag says it holds, when it says

    @property
    def complete(self) -> bool:
        """True if every part of every file was read."""
        return not self.damage

    @property
    def missing(self) -> int | None:
        """Messages the bag says it holds that were not found (None when it does not say)."""
        return None if self.expected is None else max(self.expected - sum(self.read.values()), 0)


def _metadata(path: Path) -> tuple[list[Path] | None, int | None, str]:
    """Files and message count listed by metadata.yaml, or None and why it cannot be used."""
    meta = path / "metadata.yaml"
    if not meta.is_file():
        return None, None, f"{path} has no metadata.yaml"
    try:
        info = load_yaml_file(meta)["rosbag2_bagfile_information"]
        storage = info.get("storage_identifier", "mcap")
        files = [path / str(name) for name in info["relative_file_paths"]]
        count = info.get("message_count")
    except (OSError, YamlLimitError, KeyError, TypeError, AttributeError) as error:
        return None, None, f"{meta} is unreadable ({type(error).__name__}: {error})"
    if storage != "mcap":
        raise BagError(f"{path}: storage '{storage}' is not supported; only MCAP bags are read")
    if info.get("compression_mode") == "file":
        raise BagError(f"{path}: file-compressed bags are not supported; decompress the files first")
    return files, count if isinstance(count, int) else None, ""


def bag_files(path: Path, report: ReadReport) -> list[Path]:
    """The .mcap files of a rosbag2 directory or a bare .mcap file, noting how they were found."""
    if not path.exists():
        raise BagError(f"{path}: no such file or directory")
    if path.is_file():
        return [path]
    files, report.expected, why_not = _metadata(path)
    if files is not None:
        missing = [f for f in files if not f.is_file()]
        for file in missing:
            report.damage.append(f"{file.name}, listed in metadata.yaml, is missing: its messages are lost")
        return [f for f in files if f.is_file()]
    files = sorted(path.glob("*.mcap"))
    if not files:
        raise BagError(f"{path}: neither metadata.yaml nor .mcap files: not a rosbag2 directory")
    report.notes.append(f"{why_not}: reading its {len(files)} .mcap file(s) directly")
    return files


class BagReader:
    """Iterate a bag's messages. `topics` maps the topics to deliver to their expected types
    (None: every topic whose type the type store knows)."""

    def __init__(self, path: str | Path, topics: Mapping[str, str] | None = None, store: Typestore | None = None):
        self.topics = topics
        self.store = store or typestore()
        self.report = ReadReport(Path(path))
        self.files = self._readable(bag_files(self.report.path, self.report))
        self.report.files = list(self.files)

    def _readable(self, files: list[Path]) -> list[Path]:
        """The files that open as MCAP (their summaries are read as the messages are); BagError if none does,
        damage noted for the others."""
        good, errors = [], []
        for file in files:
            try:
                McapFile.check(file)
                good.append(file)
            except McapError as error:
                errors.append(str(error))
            except OSError as error:
                errors.append(f"{file}: cannot be read ({error.strerror})")
        if not good:
            raise BagError("; ".join(errors or self.report.damage) or f"{self.report.path}: no MCAP file to read")
        self.report.damage += [f"skipped: {error}" for error in errors]
        return good

    def listed_types(self) -> dict[str, str]:
        """Topic -> message type of the delivered channels the files' summaries list, before any message is
        read (a file cut short lists none: its channels appear in `report.types` as they are read)."""
        out: dict[str, str] = {}
        for file in self.files:
            with McapFile(file) as mcap:
                for channel in mcap.channels.values():
                    schema = mcap.schemas.get(channel.schema_id)
                    msgtype = schema.name if schema is not None else ""
                    if not self._verdict(channel.topic, msgtype, channel.message_encoding):
                        out.setdefault(channel.topic, msgtype)
        return out

    def _verdict(self, topic: str, msgtype: str, encoding: str) -> str:
        """Why a channel's messages are not delivered ('' if they are)."""
        if encoding != "cdr":
            return f"message encoding '{encoding}' is not CDR"
        if self.topics is not None:
            if topic not in self.topics:
                return "not an input topic"
            if msgtype != self.topics[topic]:
                return f"type {msgtype}, expected {self.topics[topic]}"
        if not knows(self.store, msgtype):
            return f"unknown type {msgtype}"
        return ""

    def __iter__(self) -> Iterator[BagMessage]:
        for file in self.files:
            with McapFile(file, lambda msgtype, data: decodes_as(data, msgtype, self.store)) as mcap:
                yield from self._file_messages(mcap)
        report = self.report
        if report.damage and report.missing is not None:
            report.damage.append(f"in all {report.missing} of the {report.expected} messages the bag lists "
                                 "were not found" if report.missing else
                                 f"all {report.expected} messages the bag lists were found")

    def _file_messages(self, mcap: McapFile) -> Iterator[BagMessage]:
        report = self.report
        report.notes += mcap.notes
        if mcap.message_count is not None and report.expected is None and len(self.files) == 1:
            report.expected = mcap.message_count
        verdicts: dict[int, tuple[str, str, str]] = {}
        for raw in mcap.messages():
            if raw.channel_id not in verdicts:
                verdicts[raw.channel_id] = self._channel(mcap, raw.channel_id)
            topic, msgtype, reason = verdicts[raw.channel_id]
            report.read[topic] += 1
            if not reason:
                try:
                    message = decode(raw.data, msgtype, self.store)
                except Exception:
                    reason = f"cannot be decoded as {msgtype}"
                else:
                    yield BagMessage(topic, msgtype, raw.log_time, raw.data, message)
                    continue
            report.skipped[topic, reason] += 1
        for damage in mcap.damage:
            report.damage.append(f"{mcap.path.name}: {damage.description}" + self._lost(mcap, damage.lost))

    def _channel(self, mcap: McapFile, channel_id: int) -> tuple[str, str, str]:
        """Topic, type and verdict of a channel."""
        channel = mcap.channels.get(channel_id)
        if channel is None:
            return f"<channel {channel_id}>", "", "channel not defined in the file (its definition is lost)"
        schema = mcap.schemas.get(channel.schema_id)
        msgtype = schema.name if schema is not None else ""
        self.report.types.setdefault(channel.topic, msgtype)
        return channel.topic, msgtype, self._verdict(channel.topic, msgtype, channel.message_encoding)

    def _lost(self, mcap: McapFile, lost: Counter[int] | None) -> str:
        if lost is None:
            return "; the number of messages lost is not known"
        by_topic: Counter[str] = Counter()
        for channel_id, count in lost.items():
            channel = mcap.channels.get(channel_id)
            by_topic[channel.topic if channel else f"<channel {channel_id}>"] += count
        self.report.lost.update(by_topic)
        if not by_topic:
            return "; no message lost"
        return f"; {sum(by_topic.values())} messages lost (" + ", ".join(
            f"{topic} {count}" for topic, count in sorted(by_topic.items())) + ")"
