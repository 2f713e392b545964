"""Write a rosbag2 directory (MCAP storage, format version 9, metadata.yaml) through rosbags.

Connections are added on a topic's first message; message definitions come from the
type store, so the bag carries the schemas that other tools decode it with.
"""
from __future__ import annotations

from collections import Counter
from pathlib import Path
from typing import Any

from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.rosbag2.errors import WriterError
from rosbags.typesys.store import Typestore

from .reader import BagError
from .typestore import typestore


class BagWriter:
    """A new bag at `path` (never overwrites); use as a context manager so that it is always closed."""

    def __init__(self, path: str | Path, store: Typestore | None = None):
        self.path = Path(path)
        self.store = store or typestore()
        self.counts: Counter[str] = Counter()
        self._connections: dict[str, Any] = {}
        if self.path.exists():
            raise BagError(f"{self.path} exists already: give a new output path (a bag is never overwritten)")
        self._writer = Writer(self.path, version=9, storage_plugin=StoragePlugin.MCAP)
        try:
            self._writer.open()
        except (WriterError, OSError) as error:
            raise BagError(f"{self.path}: cannot create the bag ({error})") from None

    def write_raw(self, topic: str, msgtype: str, log_time: int, data: bytes) -> None:
        """CDR bytes as they are, at `log_time` [ns]."""
        connection = self._connections.get(topic)
        if connection is None:
            connection = self._connections[topic] = self._writer.add_connection(topic, msgtype, typestore=self.store)
        self._writer.write(connection, max(0, log_time), data)
        self.counts[topic] += 1

    def write(self, topic: str, msgtype: str, log_time: int, message: Any) -> None:
        """A rosbags message object, serialised to CDR."""
        self.write_raw(topic, msgtype, log_time, self.store.serialize_cdr(message, msgtype))

    def close(self) -> None:
        """Write the index and metadata.yaml (idempotent)."""
        if self._writer is not None:
            self._writer.close()
            self._writer = None

    def __enter__(self) -> "BagWriter":
        return self

    def __exit__(self, *_: object) -> None:
        self.close()
