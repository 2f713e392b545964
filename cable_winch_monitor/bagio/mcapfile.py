"""One MCAP file read record by record, so that damage costs only the part it touches.

mcap's own readers stop at the first bad record. Here each chunk is read on its own: of a
chunk that does not read whole (broken framing, failed decompression or CRC) the
well-formed records before the damage are salvaged (salvage.py), the rest counted as
lost from the chunk's message index where that survived, and reading goes on at the
next chunk the summary lists. A file without a readable summary (a recording cut short)
is walked from its start: a chunk cut off by the end of the file, or whose record length
is damaged, is salvaged the same way, and where the framing breaks inside the file
reading resumes at the next chunk whose CRC checks. Messages come out in log-time order:
chunks are merged where their time ranges overlap, so memory stays at about one chunk.
"""
from __future__ import annotations

import heapq
import mmap
import os
import struct
import zlib
from collections import Counter
from collections.abc import Callable, Generator, Iterable, Iterator
from dataclasses import dataclass
from io import BytesIO
from pathlib import Path

from mcap.opcode import Opcode
from mcap.records import Channel, Chunk, ChunkIndex, MessageIndex, Schema, Statistics

from .decode import decodes_as
from .framing import (
    CHUNK_HEAD,
    RECORD_HEADER,
    McapDamage,
    RawMessage,
    chunk_data,
    chunk_layout,
    keep_definition,
    parse_record,
    read_message,
    read_records,
)
from .salvage import ChunkContext, IndexEntries, PayloadCheck, Salvage, readable_prefix, salvage
from .typestore import typestore

MAGIC = b"\x89MCAP0\r\n"
FOOTER_SIZE = RECORD_HEADER.size + 20 + len(MAGIC)
MAX_CHUNK_DATA = 2 ** 28  # bytes of one chunk's data read at most, whatever a damaged header claims
MAX_COMPRESSION_NAME = 16  # bytes; "zstd" and "lz4" are the names in use


class McapError(Exception):
    """The file is not an MCAP file at all."""


@dataclass
class Damage:
    """A skipped part of the file: where, why, and the messages lost per channel (None: not known)."""

    offset: int
    description: str
    lost: Counter[int] | None


def merge_by_log_time(chunks: Iterable[tuple[int, list[RawMessage]]]) -> Iterator[RawMessage]:
    """Messages of chunks given in order of their start times, merged into log-time order.

    A message is released once the next chunk starts after it, so memory holds only the
    chunks whose time ranges overlap. Ties keep file order.
    """
    heap: list[tuple[int, int, int, RawMessage]] = []
    for ordinal, (start, messages) in enumerate(chunks):
        while heap and heap[0][0] < start:
            yield heapq.heappop(heap)[3]
        for index, message in enumerate(messages):
            heapq.heappush(heap, (message.log_time, ordinal, index, message))
    while heap:
        yield heapq.heappop(heap)[3]


def _check_magic(path: Path, head: bytes) -> None:
    if head != MAGIC:
        raise McapError(f"{path} is empty" if not head else f"{path} is not an MCAP file (it starts with {head[:8]!r})")


class McapFile:
    """Schemas, channels and messages of one MCAP file, with every unreadable part in `damage`."""

    def __init__(self, path: Path, decodes: PayloadCheck | None = None):
        """`decodes` tells whether bytes salvaged from a damaged chunk decode as a message type
        (default: the package's decoders over its type store)."""
        self.path = path
        self._decodes = decodes or (lambda msgtype, data: decodes_as(data, msgtype, typestore()))
        self.size = path.stat().st_size
        self.schemas: dict[int, Schema] = {}
        self.channels: dict[int, Channel] = {}
        self.damage: list[Damage] = []
        self.notes: list[str] = []
        self.message_count: int | None = None
        self.channel_counts: dict[int, int] | None = None  # messages per channel, as the summary lists them
        self._file = path.open("rb")
        try:
            _check_magic(path, self._file.read(len(MAGIC)))
        except McapError:
            self._file.close()
            raise
        self._index = self._read_summary()

    @staticmethod
    def check(path: Path) -> None:
        """McapError where `path` is not an MCAP file at all (OSError where it cannot be read): what opening
        it would say, without reading its summary."""
        with path.open("rb") as file:
            _check_magic(path, file.read(len(MAGIC)))

    def close(self) -> None:
        self._file.close()

    def __enter__(self) -> McapFile:
        return self

    def __exit__(self, *_: object) -> None:
        self.close()

    def _read_summary(self) -> list[ChunkIndex] | None:
        """Chunk indexes in time order from the summary section; None if there is none to trust."""
        footer_offset = self.size - FOOTER_SIZE
        self._file.seek(max(footer_offset, 0))
        tail = self._file.read(FOOTER_SIZE)
        footer = footer_offset >= len(MAGIC) and tail[-len(MAGIC):] == MAGIC
        self._cut_short = not footer
        if not footer or RECORD_HEADER.unpack_from(tail) != (Opcode.FOOTER, 20):
            self.notes.append(f"{self.path.name}: no footer (the recording was cut short?): reading it from the start")
            return None
        summary_start, _, summary_crc = struct.unpack_from("<QQI", tail, RECORD_HEADER.size)
        if not len(MAGIC) <= summary_start < footer_offset:
            return None
        self._file.seek(summary_start)
        if summary_crc and zlib.crc32(self._file.read(footer_offset + FOOTER_SIZE - len(MAGIC) - 4
                                                      - summary_start)) != summary_crc:
            self.notes.append(f"{self.path.name}: summary section damaged (CRC mismatch): reading the file from "
                              "the start")
            return None
        chunks: list[ChunkIndex] = []
        try:
            for offset, opcode, body in read_records(self._file, summary_start, footer_offset):
                if keep_definition(opcode, body, offset, self.schemas, self.channels):
                    continue
                if opcode == Opcode.CHUNK_INDEX:
                    chunks.append(parse_record(ChunkIndex.read, body, "chunk index", offset))
                elif opcode == Opcode.STATISTICS:
                    statistics = parse_record(Statistics.read, body, "statistics", offset)
                    self.message_count, self.channel_counts = statistics.message_count, \
                        dict(statistics.channel_message_counts)
        except McapDamage as error:
            self.notes.append(f"{self.path.name}: summary section unreadable ({error}): "
                              "reading the file from the start")
            self.schemas.clear()
            self.channels.clear()
            self.message_count = self.channel_counts = None
            return None
        if not chunks:
            return None
        return sorted(chunks, key=lambda c: (c.message_start_time, c.chunk_start_offset))

    def messages(self) -> Iterator[RawMessage]:
        """Every readable message in log-time order."""
        chunks = self._indexed_chunks() if self._index is not None else self._scanned_chunks()
        return merge_by_log_time(chunks)

    def _chunk(self, body: bytes, offset: int, index: ChunkIndex | None,
               entries: Callable[[], IndexEntries | None]) -> tuple[int, list[RawMessage]]:
        """Start time and messages (sorted by log time) of one chunk record; of a damaged chunk, the ones its
        salvage keeps, the loss noted in `damage`. McapDamage if not even the chunk's layout can be read."""
        chunk = chunk_layout(body, offset, index)
        try:
            messages = self._whole(chunk, offset)
        except McapDamage as error:
            messages, damage = self._salvaged(chunk, offset, str(error), entries())
            self.damage.append(damage)
        messages.sort(key=lambda m: m.log_time)
        return chunk.message_start_time, messages

    def _whole(self, chunk: Chunk, offset: int) -> list[RawMessage]:
        """The messages of a chunk that reads whole with a matching CRC; its definitions kept."""
        data = chunk_data(chunk, offset)
        schemas: dict[int, Schema] = {}
        channels: dict[int, Channel] = {}
        messages: list[RawMessage] = []
        try:
            for inner, opcode, record in read_records(BytesIO(data), 0, len(data)):
                if opcode == Opcode.MESSAGE:
                    messages.append(read_message(record, f"byte {inner}", inner))
                elif not keep_definition(opcode, record, inner, schemas, channels):
                    raise McapDamage(f"record type 0x{opcode:02x} at byte {inner} cannot stand in a chunk", inner)
        except McapDamage as error:
            raise McapDamage(f"inside the chunk ({len(data)} bytes): {error}", offset) from None
        self.schemas.update(schemas)
        self.channels.update(channels)
        return messages

    def _salvaged(self, chunk: Chunk, offset: int, why: str,
                  entries: IndexEntries | None) -> tuple[list[RawMessage], Damage]:
        """The well-formed records before the damage in a chunk, and the damage with the messages it cost."""
        data = readable_prefix(chunk.compression, chunk.data, min(chunk.uncompressed_size, MAX_CHUNK_DATA))
        kept = salvage(data, ChunkContext(self.schemas, self.channels, chunk.message_start_time,
                                          chunk.message_end_time, entries, self._decodes))
        self.schemas.update(kept.schemas)
        self.channels.update(kept.channels)
        held = "" if entries is None else f" of the {len(entries)} its index lists"
        if not kept.end and len(data) < chunk.uncompressed_size:
            kept.end = f"its data ends after {len(data)} of its {chunk.uncompressed_size} bytes"
        end = (f"reading stopped where {kept.end}" if kept.end else "every record checks, so the damage lies in a "
               "payload or the CRC field: one of these messages may carry altered values")
        return kept.messages, Damage(offset, f"chunk at byte {offset} damaged ({why}): {len(kept.messages)} messages"
                                     f"{held} salvaged; {end}", kept.lost(entries))

    def _record_at(self, offset: int, length: int | None = None) -> tuple[int, bytes]:
        """Opcode and body of the record at `offset`, of `length` bytes if given (else as its header says)."""
        header = os.pread(self._file.fileno(), RECORD_HEADER.size, offset)
        if len(header) < RECORD_HEADER.size:
            raise McapDamage(f"no record at byte {offset}", offset)
        opcode, stated = RECORD_HEADER.unpack(header)
        length = stated if length is None else length
        if length > self.size - offset - RECORD_HEADER.size:
            raise McapDamage(f"the record at byte {offset} claims {length} bytes, only "
                             f"{self.size - offset - RECORD_HEADER.size} follow", offset)
        return opcode, os.pread(self._file.fileno(), length, offset + RECORD_HEADER.size)

    def _index_entries(self, offsets: Iterable[int]) -> IndexEntries | None:
        """Channel and log time of each message a chunk's message index records list, by offset in the chunk's
        data (None if there are none or one is unreadable)."""
        entries: IndexEntries = {}
        offsets = list(offsets)
        for offset in offsets:
            try:
                opcode, body = self._record_at(offset)
                if opcode != Opcode.MESSAGE_INDEX:
                    return None
                index = parse_record(MessageIndex.read, body, "message index", offset)
            except McapDamage:
                return None
            entries.update({position: (index.channel_id, time) for time, position in index.records})
        return entries if offsets else None

    def _indexes_after(self, offset: int) -> list[int]:
        """Offsets of the message index records that follow a chunk ending at `offset`."""
        found = []
        while offset < self.size:
            try:
                opcode, body = self._record_at(offset)
            except McapDamage:
                break
            if opcode != Opcode.MESSAGE_INDEX:
                break
            found.append(offset)
            offset += RECORD_HEADER.size + len(body)
        return found

    def _indexed_chunks(self) -> Iterator[tuple[int, list[RawMessage]]]:
        assert self._index is not None  # read only where the file has its summary's chunk index
        for index in self._index:
            offset = index.chunk_start_offset

            def entries(index: ChunkIndex = index) -> IndexEntries | None:
                return self._index_entries(index.message_index_offsets.values())

            try:
                opcode, body = self._record_at(offset, index.chunk_length - RECORD_HEADER.size)
                if opcode != Opcode.CHUNK:
                    raise McapDamage(f"the summary points to a chunk at byte {offset}, found record type "
                                     f"0x{opcode:02x}", offset)
                yield self._chunk(body, offset, index, entries)
            except McapDamage as error:
                self.damage.append(Damage(offset, f"chunk at byte {offset} unreadable: {error}",
                                          Salvage().lost(entries())))

    def _scanned_chunks(self) -> Iterator[tuple[int, list[RawMessage]]]:
        """Records from the start, in file order, until the data section ends; past a break in the framing,
        from the next chunk whose CRC checks."""
        start: int | None = len(MAGIC)
        while start is not None:
            start = yield from self._scan_from(start)

    def _scan_from(self, start: int) -> Generator[tuple[int, list[RawMessage]], None, int | None]:
        """Records from `start` in file order; returns where to go on after a break in the framing (None: done)."""
        try:
            for offset, opcode, body in read_records(self._file, start, self.size):
                if opcode == Opcode.CHUNK:
                    end = offset + RECORD_HEADER.size + len(body)

                    def entries(end: int = end) -> IndexEntries | None:
                        return self._index_entries(self._indexes_after(end))

                    try:
                        yield self._chunk(body, offset, None, entries)
                    except McapDamage as error:
                        self.damage.append(Damage(offset, f"chunk at byte {offset} unreadable: {error}",
                                                  Salvage().lost(entries())))
                elif opcode == Opcode.MESSAGE:
                    message = read_message(body, f"byte {offset}", offset)
                    yield message.log_time, [message]
                elif opcode in (Opcode.DATA_END, Opcode.FOOTER):
                    return None
                elif opcode != Opcode.MESSAGE_INDEX:
                    keep_definition(opcode, body, offset, self.schemas, self.channels)
        except McapDamage as error:
            resume = self._next_intact_chunk(error.offset + 1)
            end = self.size if resume is None else resume
            broken = self._broken_chunk(error.offset, end, str(error))
            if broken is not None:
                yield broken[0]
            where = f"file damaged or cut short at byte {error.offset} of {self.size}: "
            went_on = "" if resume is None else f", reading went on at the chunk at byte {resume}"
            if broken is not None:
                self.damage.append(Damage(error.offset, where + broken[1].description + went_on, broken[1].lost))
            else:
                self.damage.append(Damage(error.offset, f"{where}{error}; bytes {error.offset}-{end} "
                                          f"({100.0 * (end - error.offset) / self.size:.1f}%) could not be read"
                                          + went_on, None))
            return resume
        self.damage.append(Damage(self.size, f"the file ends at byte {self.size} without its data-end record: "
                                  "the recording was cut short; everything before was read", None))
        return None

    def _broken_chunk(self, offset: int, end: int,
                      why: str) -> tuple[tuple[int, list[RawMessage]], Damage] | None:
        """The salvage of a chunk at `offset` whose record does not fit before `end` (a cut, or a damaged
        length): its start time, the messages kept and the damage (None if no chunk header starts there)."""
        head = os.pread(self._file.fileno(), RECORD_HEADER.size + CHUNK_HEAD.size, offset)
        if len(head) < RECORD_HEADER.size + CHUNK_HEAD.size or head[0] != Opcode.CHUNK:
            return None
        start_time, end_time, size, crc, name_length = CHUNK_HEAD.unpack_from(head, RECORD_HEADER.size)
        name_start = offset + len(head)
        tail = os.pread(self._file.fileno(), name_length + 8, name_start) if name_length <= MAX_COMPRESSION_NAME else b""
        if len(tail) < name_length + 8:
            return None
        data_start, length = name_start + len(tail), struct.unpack_from("<Q", tail, name_length)[0]
        data = os.pread(self._file.fileno(), max(min(length, end - data_start, MAX_CHUNK_DATA), 0), data_start)
        chunk = Chunk(compression=tail[:name_length].decode(errors="replace"), data=data,
                      message_start_time=start_time, message_end_time=end_time, uncompressed_crc=crc,
                      uncompressed_size=size)
        entries = self._index_entries(self._indexes_after(data_start + length)) if data_start + length <= end else None
        messages, damage = self._salvaged(chunk, offset, why, entries)
        messages.sort(key=lambda m: m.log_time)
        return (start_time, messages), damage

    def _next_intact_chunk(self, start: int) -> int | None:
        """Offset of the first chunk record at or after `start` that reads whole with a matching CRC (None: none)."""
        with mmap.mmap(self._file.fileno(), 0, access=mmap.ACCESS_READ) as data:
            candidate = data.find(bytes([Opcode.CHUNK]), start)
            while candidate >= 0:
                if candidate + RECORD_HEADER.size + CHUNK_HEAD.size <= self.size:
                    _, length = RECORD_HEADER.unpack_from(data, candidate)
                    crc = CHUNK_HEAD.unpack_from(data, candidate + RECORD_HEADER.size)[3]
                    end = candidate + RECORD_HEADER.size + length
                    if crc and end <= self.size and self._intact(data[candidate + RECORD_HEADER.size:end], candidate):
                        return candidate
                candidate = data.find(bytes([Opcode.CHUNK]), candidate + 1)
        return None

    @staticmethod
    def _intact(body: bytes, offset: int) -> bool:
        try:
            chunk_data(parse_record(Chunk.read, body, "chunk", offset), offset)
        except McapDamage:
            return False
        return True
