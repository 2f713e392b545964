"""MCAP records as they lie in a file or a chunk: their framing, the definitions, messages, a chunk's data.

Every failure is a McapDamage carrying the offset where the unreadable part starts, so
that a reader can skip it and count what it cost.
"""
from __future__ import annotations

import struct
import zlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from io import BytesIO
from typing import BinaryIO, TypeVar

from mcap.data_stream import ReadDataStream
from mcap.opcode import Opcode
from mcap.records import Channel, Chunk, ChunkIndex, Schema

RECORD_HEADER = struct.Struct("<BQ")
MESSAGE_HEADER = struct.Struct("<HIQQ")  # channel id, sequence, log time, publish time
CHUNK_HEAD = struct.Struct("<QQQII")  # start time, end time, uncompressed size, CRC, compression name length
R = TypeVar("R")  # the record type a reader parses


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


def read_records(stream: BinaryIO, start: int, end: int) -> Iterator[tuple[int, int, bytes]]:
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


def parse_record(reader: Callable[[ReadDataStream], R], body: bytes, what: str, offset: int) -> R:
    try:
        return reader(ReadDataStream(BytesIO(body)))
    except Exception as error:
        raise McapDamage(f"{what} record at byte {offset} unreadable ({type(error).__name__}: {error})",
                         offset) from None


def keep_definition(opcode: int, body: bytes, offset: int, schemas: dict[int, Schema],
                channels: dict[int, Channel]) -> bool:
    """Keep a schema or channel record; False for any other kind of record."""
    if opcode == Opcode.SCHEMA:
        schema = parse_record(Schema.read, body, "schema", offset)
        schemas[schema.id] = schema
    elif opcode == Opcode.CHANNEL:
        channel = parse_record(Channel.read, body, "channel", offset)
        channels[channel.id] = channel
    else:
        return False
    return True


def read_message(body: bytes, where: str, offset: int) -> RawMessage:
    """The message in a message record's body."""
    if len(body) < MESSAGE_HEADER.size:
        raise McapDamage(f"message record too short at {where}", offset)
    channel_id, _, log_time, _ = MESSAGE_HEADER.unpack_from(body)
    return RawMessage(channel_id, log_time, body[MESSAGE_HEADER.size:])


def chunk_layout(body: bytes, offset: int, index: ChunkIndex | None = None) -> Chunk:
    """The chunk record's fields; where the summary indexes the chunk, its times, sizes and compression are
    taken from there (the summary's CRC checked), so that a damaged chunk header still locates the data."""
    if index is None:
        return parse_record(Chunk.read, body, "chunk", offset)
    start = CHUNK_HEAD.size + len(index.compression.encode()) + 8
    if len(body) < start + index.compressed_size:
        raise McapDamage(f"the chunk at byte {offset} holds {len(body)} bytes, its index says "
                         f"{start + index.compressed_size}", offset)
    crc = CHUNK_HEAD.unpack_from(body)[3]
    return Chunk(compression=index.compression, data=body[start:start + index.compressed_size],
                 message_start_time=index.message_start_time, message_end_time=index.message_end_time,
                 uncompressed_crc=crc, uncompressed_size=index.uncompressed_size)


def chunk_data(chunk: Chunk, offset: int) -> bytes:
    """The chunk's records, decompressed, of the size and CRC its header gives; McapDamage otherwise."""
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
    except Exception as error:
        raise McapDamage(f"{chunk.compression} decompression failed ({error})", offset) from None
    if len(data) != chunk.uncompressed_size:
        raise McapDamage(f"chunk holds {len(data)} bytes, its header says {chunk.uncompressed_size}", offset)
    if chunk.uncompressed_crc and zlib.crc32(data) != chunk.uncompressed_crc:
        raise McapDamage("chunk CRC mismatch", offset)
    return data
