"""Write a rosbag2 directory (MCAP storage, format version 9, metadata.yaml) through rosbags.

Connections are added on a topic's first message; message definitions come from the
type store, so the bag carries the schemas that other tools decode it with. Messages go
into rosbags' open MCAP chunk by `_append` (the bytes rosbags' `Writer.write` writes for an
uncompressed bag), their index and counts kept here as arrays and counters and handed to
rosbags, which writes the summary and metadata.yaml, when the bag is closed.

Chunks are bounded, so that damage costs little: one is closed past CHUNK_SIZE bytes or
when its messages would span more than CHUNK_SPAN of log time, and each carries the
CRC-32 of its data (rosbags writes 0, "no CRC"), so that a reader can tell a damaged
chunk from an intact one; the footer carries the CRC of the summary section (the index)
for the same reason.
"""
from __future__ import annotations

import shutil
import struct
import zlib
from array import array
from collections import Counter, defaultdict
from collections.abc import Iterable, Iterator
from contextlib import contextmanager, suppress
from io import BytesIO
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
from rosbags.typesys.store import Typestore

from .reader import BagError
from .typestore import knows, typestore

if TYPE_CHECKING:
    from rosbags.rosbag2 import Writer

MESSAGE = struct.Struct("<BQHIQQ")  # opcode 0x05, record length, channel, sequence, log time, publish time
CHUNK_SIZE = 2 ** 20  # rosbags closes a chunk past this many bytes
_FOREVER = QosTime(0x7FFFFFFF, 0xFFFFFFFF)  # rosbag2's "infinite" deadline, lifespan and lease
# What tf2's static broadcaster offers: a player republishes the topic latched, so a late subscriber still gets it.
LATCHED = Qos(QosHistory.KEEP_LAST, 1, QosReliability.RELIABLE, QosDurability.TRANSIENT_LOCAL, _FOREVER, _FOREVER,
              QosLiveliness.AUTOMATIC, _FOREVER, False)
CHUNK_SPAN = 1_000_000_000  # [ns] of log time in one chunk at most
NO_TIME = 2 ** 63 - 1  # [ns] the earliest log time of a chunk or bag with no message yet (rosbags' own)
# opcode 0x06, record length, start and end time, uncompressed size and CRC, compression ('': length 0), compressed size
CHUNK = struct.Struct("<BQQQQIIQ")
MESSAGE_INDEX = struct.Struct("<BQHI")  # opcode 0x07, record length, channel, byte length of the (time, offset) pairs
FOOTER = struct.Struct("<BQQQI")  # opcode 0x02, record length, summary start, summary offset start, summary CRC
FOOTER_OPCODE = 0x02
MAGIC = b"\x89MCAP0\r\n"


class BagWriter:
    """A new bag at `path` (never overwrites); use as a context manager so that it is always closed.
    `at_first_message`: the bag is created when the first message is written (or as it is closed, empty), not
    at once: rosbags' writer loads ruamel.yaml and importlib.metadata (34 ms), which a replay then does while
    its second process estimates the first window rather than before."""

    def __init__(self, path: str | Path, store: Typestore | None = None, *, at_first_message: bool = False):
        self.path = Path(path)
        self.store = store or typestore()
        self._channels: dict[str, int] = {}  # topic -> channel id
        if self.path.exists():
            raise BagError(f"{self.path} exists already: give a new output path (a bag is never overwritten)")
        self._writer: Writer | None = None  # rosbags' writer while the bag is open
        self._closed = False
        self._written: Counter[int] = Counter()  # messages per channel
        self._index: dict[int, array[int]] = {}  # the open chunk's (log time, offset) of each message, by channel
        self._first, self._last = NO_TIME, 0  # [ns] the open chunk's earliest and latest log time
        self._span = [NO_TIME, 0]  # [ns] the bag's
        if not at_first_message:
            self._open()

    def _open(self) -> None:
        """Create the bag through rosbags' writer, its chunks ended by `_close_chunk`."""
        from rosbags.rosbag2 import StoragePlugin, Writer
        from rosbags.rosbag2.errors import WriterError
        from rosbags.rosbag2.storage_mcap import McapWriter

        assert not self._closed  # nothing is written after close
        writer = Writer(self.path, version=9, storage_plugin=StoragePlugin.MCAP)
        try:
            writer.open()
        except (WriterError, OSError) as error:
            raise BagError(f"{self.path}: cannot create the bag ({error})") from None
        assert isinstance(writer.storage, McapWriter)  # open() made the storage of the plugin asked for
        self._writer = writer
        self._storage: McapWriter = writer.storage
        # rosbags' own close() ends the last chunk through it too (mypy: rosbags has no hook, its method is replaced)
        self._storage.close_chunk = self._close_chunk  # type: ignore[method-assign]

    def _close_chunk(self) -> None:
        """End the open chunk: what rosbags' McapWriter.close_chunk writes for an uncompressed chunk (the
        chunk, its message indexes, its entry of the chunk index), packed a record at a time rather than
        a field at a time, and with the CRC-32 of the chunk's data where rosbags writes 0 ("no CRC")."""
        storage, out = self._storage, self._storage.bio
        data = storage.chunk.bio.getvalue()
        start_time, end_time = self._first, self._last
        chunk_start = out.tell()
        out.write(CHUNK.pack(0x06, CHUNK.size - 9 + len(data), start_time, end_time, len(data), zlib.crc32(data), 0,
                             len(data)))
        out.write(data)
        chunk_end = out.tell()
        offsets = []
        for channel, entries in self._index.items():  # (log time, offset in the chunk) of each message
            offsets.append((channel, out.tell()))
            out.write(MESSAGE_INDEX.pack(0x07, MESSAGE_INDEX.size - 9 + 8 * len(entries), channel, 8 * len(entries)))
            out.write(entries.tobytes())
        entry = BytesIO()
        entry.write(struct.pack("<QQQQI", start_time, end_time, chunk_start, chunk_end - chunk_start, 10 * len(offsets)))
        entry.write(b"".join(struct.pack("<HQ", *offset) for offset in offsets))
        entry.write(struct.pack("<QIQQ", out.tell() - chunk_end, 0, len(data), len(data)))
        storage.chunks.append(entry)
        if self._index:  # (rosbags' chunk may hold the records of connections alone)
            self._span = [min(self._span[0], start_time), max(self._span[1], end_time)]
        storage.chunk = type(storage.chunk)(NO_TIME, 0, BytesIO(), defaultdict(list))  # rosbags' PendingChunk
        self._index, self._first, self._last = {}, NO_TIME, 0

    def write_raw(self, topic: str, msgtype: str, log_time: int, data: bytes | memoryview, latched: bool = False) -> None:
        """CDR bytes as they are, at `log_time` [ns]; a `latched` topic is recorded as offered transient-local
        (its first message decides)."""
        self.write_records(log_time, ((topic, msgtype, data),), latched)

    def write_records(self, log_time: int, records: Iterable[tuple[str, str, bytes | memoryview]],
                      latched: bool = False) -> None:
        """`write_raw` for each (topic, message type, CDR bytes), all at `log_time` [ns], in one call (a replay
        writes a message's outputs so, several tens of thousands a second)."""
        time = log_time if log_time > 0 else 0
        channels, append = self._channels, self._append
        for topic, msgtype, data in records:
            channel = channels.get(topic)
            append(self._connect(topic, msgtype, latched) if channel is None else channel, time, data)

    def _connect(self, topic: str, msgtype: str, latched: bool) -> int:
        """The channel id of a new connection for `topic` (a Jazzy type the store starts without is added
        first; rosbags refuses a type it cannot define)."""
        knows(self.store, msgtype)
        if self._writer is None:
            self._open()
        assert self._writer is not None  # opened
        connection = self._writer.add_connection(topic, msgtype, typestore=self.store,
                                                 offered_qos_profiles=[LATCHED] if latched else ())
        self._channels[topic] = connection.id
        return connection.id

    @property
    def counts(self) -> Counter[str]:
        """Messages written per topic."""
        return Counter({topic: self._written[channel] for topic, channel in self._channels.items()})

    def _append(self, channel: int, time: int, data: bytes | memoryview) -> None:
        """A message into the open chunk (a new one where it would span more than CHUNK_SPAN), indexed."""
        if self._index and (time - self._first > CHUNK_SPAN or self._last - time > CHUNK_SPAN):
            self._close_chunk()
        assert self._writer is not None  # nothing is written after close
        self._written[channel] += 1
        if time < self._first:
            self._first = time
        if time > self._last:
            self._last = time
        chunk = self._storage.chunk.bio
        offset = chunk.tell()
        index = self._index.get(channel)
        if index is None:
            index = self._index[channel] = array("Q")
        index.append(time)
        index.append(offset)
        chunk.write(MESSAGE.pack(0x05, MESSAGE.size - 9 + len(data), channel, 0, time, time))
        chunk.write(data)
        if offset + MESSAGE.size + len(data) > CHUNK_SIZE:
            self._close_chunk()

    def _hand_over(self) -> None:
        """The last chunk ended, and what rosbags writes into the summary and metadata.yaml as it closes the bag
        handed to it: the messages per channel, and the earliest and latest log time."""
        if self._index:
            self._close_chunk()
        writer, storage = self._writer, self._storage
        assert writer is not None  # handed over once, as the bag is closed
        for channel, count in self._written.items():
            writer.counts[channel] = storage.channel_stats[channel] = count
        if self._written:
            writer.min_timestamp = storage.message_start_time = self._span[0]
            writer.max_timestamp = storage.message_end_time = self._span[1]

    def write(self, topic: str, msgtype: str, log_time: int, message: Any) -> None:
        """A rosbags message object, serialised to CDR."""
        self.write_raw(topic, msgtype, log_time, self.store.serialize_cdr(message, msgtype))

    def close(self) -> None:
        """Write the index and metadata.yaml (idempotent); a bag nothing was written to is created empty."""
        if self._closed:
            return
        if self._writer is None:
            self._open()
        assert self._writer is not None  # opened
        self._hand_over()
        self._writer.close()
        self._writer, self._closed = None, True
        _seal_summary(self._storage.path)

    def discard(self) -> None:
        """Remove the bag (a job that failed leaves none)."""
        if self._writer is not None:
            with suppress(Exception):  # the failure is the job's, reported by the caller
                self._hand_over()
                self._writer.close()
        self._writer, self._closed = None, True
        shutil.rmtree(self.path, ignore_errors=True)

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, *_: object) -> None:
        self.close()


@contextmanager
def new_bag(path: str | Path) -> Iterator[BagWriter]:
    """A new bag at `path` for a job, created at its first message: closed when the job ends or is stopped
    (KeyboardInterrupt), so that it holds what was written; removed where the job fails with an error."""
    writer = BagWriter(path, at_first_message=True)
    try:
        yield writer
    except Exception:
        writer.discard()
        raise
    finally:
        writer.close()


def _seal_summary(mcap: Path) -> None:
    """Write the footer's summary CRC: CRC-32 of the summary section and the footer's first two fields."""
    with mcap.open("r+b") as file:
        footer = file.seek(0, 2) - FOOTER.size - len(MAGIC)
        file.seek(footer)
        opcode, _, summary_start, _, _ = FOOTER.unpack(file.read(FOOTER.size))
        if opcode != FOOTER_OPCODE or summary_start == 0:
            return
        file.seek(summary_start)
        crc = zlib.crc32(file.read(footer + FOOTER.size - 4 - summary_start))
        file.seek(footer + FOOTER.size - 4)
        file.write(struct.pack("<I", crc))

