"""One MCAP file read record by record, so that damage costs only the part it touches.

mcap's own readers stop at the first bad record. Here each chunk is read on its own: a
chunk that cannot be read (broken framing, failed decompression or CRC) is skipped, its
messages counted from the message index where that survived, and reading goes on at the
next chunk the summary lists. A file without a readable summary (a recording cut short)
is walked from its start: the complete records of a chunk cut off by the end of the file
are kept (a cut changes no byte before it), and where the framing breaks inside the file
reading resumes at the next chunk whose CRC checks. Messages come out in log-time order:
chunks are merged where their time ranges overlap, so memory stays at about one chunk.
"""
from __future__ import annotations

import heapq
import mmap
import struct
import zlib
from collections import Counter
from dataclasses import dataclass
from io import BytesIO
from pathlib import Path
from typing import BinaryIO, Callable, Generator, Iterable, Iterator

from mcap.data_stream import ReadDataStream
from mcap.opcode import Opcode
from mcap.records import Channel, Chunk, ChunkIndex, MessageIndex, Schema, Statistics

MAGIC = b"\x89MCAP0\r\n"
RECORD_HEADER = struct.Struct("<BQ")
MESSAGE_HEADER = struct.Struct("<HIQQ")  # channel id, sequence, log time, publish time
CHUNK_HEAD = struct.Struct("<QQQII")  # start time, end time, uncompressed size, CRC, compression name length
FOOTER_SIZE = RECORD_HEADER.size + 20 + len(MAGIC)


class McapError(Exception):
    """The file is not an MCAP file at all."""


class McapDamage(Exception):
    """A part of the file that cannot be read; `offset` is where in the file it starts."""

    def __init__(self, message: str, offset: int = 0):
        super().__init__(message)
        self.offset = offset


@dataclass(frozen=True)
class RawMessage:
    channel_id: int
    log_time: int
    data: bytes


@dataclass
class Damage:
    """A skipped part of the file: where, why, and the messages lost per channel (None: not known)."""

    offset: int
    description: str
    lost: Counter[int] | None


def _records(stream: BinaryIO, start: int, end: int) -> Iterator[tuple[int, int, bytes]]:
    """(offset, opcode, body) of each record from `start` to `end`; McapDamage where the framing breaks."""
    offset = start
    stream.seek(start)
    while offset < end:
        header = stream.read(RECORD_HEADER.size)
        if len(header) < RECORD_HEADER.size:
            raise McapDamage(f"{end - offset} bytes at byte {offset} are too few for a record", offset)
        opcode, length = RECORD_HEADER.unpack(header)
        if length > end - offset - RECORD_HEADER.size:
            raise McapDamage(f"the record at byte {offset} claims {length} bytes, only "
                             f"{end - offset - RECORD_HEADER.size} follow", offset)
        body = stream.read(length)
        yield offset, opcode, body
        offset += RECORD_HEADER.size + length


def _parse(reader: Callable[[ReadDataStream], object], body: bytes, what: str, offset: int) -> object:
    try:
        return reader(ReadDataStream(BytesIO(body)))
    except Exception as error:  # noqa: BLE001 - any parse failure is damage, with its cause
        raise McapDamage(f"{what} record at byte {offset} unreadable ({type(error).__name__}: {error})",
                         offset) from None


def _definition(opcode: int, body: bytes, offset: int, schemas: dict[int, Schema],
                channels: dict[int, Channel]) -> bool:
    """Keep a schema or channel record; False for any other kind of record."""
    if opcode == Opcode.SCHEMA:
        schema = _parse(Schema.read, body, "schema", offset)
        schemas[schema.id] = schema
    elif opcode == Opcode.CHANNEL:
        channel = _parse(Channel.read, body, "channel", offset)
        channels[channel.id] = channel
    else:
        return False
    return True


def _message(body: bytes, where: str, offset: int) -> RawMessage:
    if len(body) < MESSAGE_HEADER.size:
        raise McapDamage(f"message record too short at {where}", offset)
    channel_id, _, log_time, _ = MESSAGE_HEADER.unpack_from(body)
    return RawMessage(channel_id, log_time, body[MESSAGE_HEADER.size:])


def _decompress(chunk: Chunk, offset: int) -> bytes:
    try:
        if chunk.compression == "":
            data = chunk.data
        elif chunk.compression == "zstd":
            import zstandard

            data = zstandard.ZstdDecompressor().decompress(chunk.data, max_output_size=chunk.uncompressed_size)
        elif chunk.compression == "lz4":
            import lz4.frame

            data = lz4.frame.decompress(chunk.data)
        else:
            raise McapDamage(f"unsupported chunk compression {chunk.compression!r}", offset)
    except McapDamage:
        raise
    except Exception as error:  # noqa: BLE001 - corrupt compressed data raises library-specific errors
        raise McapDamage(f"{chunk.compression} decompression failed ({error})", offset) from None
    if len(data) != chunk.uncompressed_size:
        raise McapDamage(f"chunk holds {len(data)} bytes, its header says {chunk.uncompressed_size}", offset)
    if chunk.uncompressed_crc and zlib.crc32(data) != chunk.uncompressed_crc:
        raise McapDamage("chunk CRC mismatch", offset)
    return data


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


class McapFile:
    """Schemas, channels and messages of one MCAP file, with every unreadable part in `damage`."""

    def __init__(self, path: Path):
        self.path = path
        self.size = path.stat().st_size
        self.schemas: dict[int, Schema] = {}
        self.channels: dict[int, Channel] = {}
        self.damage: list[Damage] = []
        self.notes: list[str] = []
        self.message_count: int | None = None
        self._file = path.open("rb")
        head = self._file.read(len(MAGIC))
        if head != MAGIC:
            self._file.close()
            raise McapError(f"{path} is empty" if not head
                            else f"{path} is not an MCAP file (it starts with {head[:8]!r})")
        self._index = self._read_summary()

    def close(self) -> None:
        self._file.close()

    def __enter__(self) -> "McapFile":
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
            for offset, opcode, body in _records(self._file, summary_start, footer_offset):
                if _definition(opcode, body, offset, self.schemas, self.channels):
                    continue
                if opcode == Opcode.CHUNK_INDEX:
                    chunks.append(_parse(ChunkIndex.read, body, "chunk index", offset))
                elif opcode == Opcode.STATISTICS:
                    self.message_count = _parse(Statistics.read, body, "statistics", offset).message_count
        except McapDamage as error:
            self.notes.append(f"{self.path.name}: summary section unreadable ({error}): "
                              "reading the file from the start")
            self.schemas.clear()
            self.channels.clear()
            self.message_count = None
            return None
        if not chunks:
            return None
        return sorted(chunks, key=lambda c: (c.message_start_time, c.chunk_start_offset))

    def messages(self) -> Iterator[RawMessage]:
        """Every readable message in log-time order."""
        chunks = self._indexed_chunks() if self._index is not None else self._scanned_chunks()
        return merge_by_log_time(chunks)

    def _chunk(self, body: bytes, offset: int) -> tuple[int, list[RawMessage]]:
        """Start time and messages (sorted by log time) of one chunk record; schemas and channels
        it defines are kept only if the whole chunk reads."""
        chunk = _parse(Chunk.read, body, "chunk", offset)
        data = _decompress(chunk, offset)
        schemas, channels, messages = {}, {}, []
        try:
            for inner, opcode, record in _records(BytesIO(data), 0, len(data)):
                if opcode == Opcode.MESSAGE:
                    messages.append(_message(record, f"byte {inner}", inner))
                elif not _definition(opcode, record, inner, schemas, channels):
                    raise McapDamage(f"record type 0x{opcode:02x} at byte {inner} cannot stand in a chunk", inner)
        except McapDamage as error:
            raise McapDamage(f"inside the chunk ({len(data)} bytes): {error}", offset) from None
        self.schemas.update(schemas)
        self.channels.update(channels)
        messages.sort(key=lambda m: m.log_time)
        return chunk.message_start_time, messages

    def _index_counts(self, index: ChunkIndex) -> Counter[int] | None:
        """Messages per channel of an indexed chunk, from its message index records (None if unreadable)."""
        counts: Counter[int] = Counter()
        for channel_id, offset in index.message_index_offsets.items():
            try:
                _, opcode, body = next(_records(self._file, offset, self.size))
                if opcode != Opcode.MESSAGE_INDEX:
                    return None
                counts[channel_id] += len(_parse(MessageIndex.read, body, "message index", offset).records)
            except (McapDamage, StopIteration):
                return None
        return counts

    def _indexed_chunks(self) -> Iterator[tuple[int, list[RawMessage]]]:
        for index in self._index:
            offset = index.chunk_start_offset
            try:
                _, opcode, body = next(_records(self._file, offset, self.size))
                if opcode != Opcode.CHUNK:
                    raise McapDamage(f"the summary points to a chunk at byte {offset}, found record type "
                                     f"0x{opcode:02x}", offset)
                yield self._chunk(body, offset)
            except McapDamage as error:
                self.damage.append(Damage(offset, f"chunk at byte {offset} unreadable: {error}",
                                          self._index_counts(index)))

    def _scanned_chunks(self) -> Iterator[tuple[int, list[RawMessage]]]:
        """Records from the start, in file order, until the data section ends; past a break in the framing,
        from the next chunk whose CRC checks."""
        start: int | None = len(MAGIC)
        while start is not None:
            start = yield from self._scan_from(start)

    def _scan_from(self, start: int) -> Generator[tuple[int, list[RawMessage]], None, int | None]:
        """Records from `start` in file order; returns where to go on after a break in the framing (None: done)."""
        lost: Damage | None = None  # the last unreadable chunk: its message index records follow it
        try:
            for offset, opcode, body in _records(self._file, start, self.size):
                if opcode == Opcode.MESSAGE_INDEX and lost is not None:
                    try:
                        record = _parse(MessageIndex.read, body, "message index", offset)
                        lost.lost = (lost.lost or Counter()) + Counter({record.channel_id: len(record.records)})
                    except McapDamage:
                        lost.lost, lost = None, None  # the count is no longer known
                    continue
                lost = None
                if opcode == Opcode.CHUNK:
                    try:
                        yield self._chunk(body, offset)
                    except McapDamage as error:
                        lost = Damage(offset, f"chunk at byte {offset} unreadable: {error}", None)
                        self.damage.append(lost)
                elif opcode == Opcode.MESSAGE:
                    message = _message(body, f"byte {offset}", offset)
                    yield message.log_time, [message]
                elif opcode in (Opcode.DATA_END, Opcode.FOOTER):
                    return None
                else:
                    _definition(opcode, body, offset, self.schemas, self.channels)
        except McapDamage as error:
            cut = self._cut_chunk(error.offset) if self._cut_short else None
            if cut is not None:
                yield cut
                self.damage.append(Damage(error.offset, f"chunk at byte {error.offset} cut short at byte {self.size} "
                                          f"(the end of the file): its {len(cut[1])} complete messages were read, "
                                          "the rest of it and anything after it are lost", None))
                return None
            resume = self._next_intact_chunk(error.offset + 1)
            end = self.size if resume is None else resume
            self.damage.append(Damage(error.offset, f"file damaged or cut short at byte {error.offset} of "
                                      f"{self.size}: {error}; bytes {error.offset}-{end} "
                                      f"({100.0 * (end - error.offset) / self.size:.1f}%) could not be read"
                                      + ("" if resume is None else f", reading went on at the chunk at byte {resume}"),
                                      None))
            return resume
        self.damage.append(Damage(self.size, f"the file ends at byte {self.size} without its data-end record: "
                                  "the recording was cut short; everything before was read", None))
        return None

    def _cut_chunk(self, offset: int) -> tuple[int, list[RawMessage]] | None:
        """Start time and complete messages of an uncompressed chunk at `offset` that the end of the file cuts off
        (None if no such chunk starts there). Only for a file without footer: a cut changes no byte before it,
        while a chunk that runs past the footer has a damaged header and its contents are not to be trusted."""
        self._file.seek(offset)
        head = self._file.read(RECORD_HEADER.size + CHUNK_HEAD.size)
        if len(head) < RECORD_HEADER.size + CHUNK_HEAD.size or head[0] != Opcode.CHUNK:
            return None
        start_time, _, _, _, compression_length = CHUNK_HEAD.unpack_from(head, RECORD_HEADER.size)
        if compression_length != 0:
            return None  # compressed data cannot be read in part
        self._file.seek(offset + RECORD_HEADER.size + CHUNK_HEAD.size + 8)  # past the records' length
        data = self._file.read()
        messages = []
        try:
            for inner, opcode, record in _records(BytesIO(data), 0, len(data)):
                if opcode == Opcode.MESSAGE:
                    messages.append(_message(record, f"byte {inner}", inner))
                elif not _definition(opcode, record, inner, self.schemas, self.channels):
                    break
        except McapDamage:
            pass  # the cut: everything before it was kept
        messages.sort(key=lambda m: m.log_time)
        return start_time, messages

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
            _decompress(_parse(Chunk.read, body, "chunk", offset), offset)
        except McapDamage:
            return False
        return True
