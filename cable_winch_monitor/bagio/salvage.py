"""The intact records of a damaged chunk, so that damage costs only the records from it on.

A chunk whose CRC fails, or that a cut or a broken record length leaves incomplete, says
that it is damaged, not where. Its data is decompressed as far as it goes (a streaming
decompressor gives the bytes before a cut; after a corrupted byte it may give garbage)
and its records are kept one by one while each is well formed: a whole record of a kind
that belongs in a chunk; a definition that does not contradict an earlier one; a message
on a defined channel, stamped inside the chunk's [start, end], at the offset and with the
channel and log time the chunk's message index lists (where that index is readable), whose
payload decodes as the channel's message type. The first record that is not ends the walk;
the rest of the chunk is lost. There is no order check: MCAP promises no log-time order
inside a chunk, and this package's writer interleaves topics whose stamps differ.
A corrupted number inside a payload that still decodes cannot be detected without a
per-record checksum: the record holding the damage may be replayed with altered values.
"""
from __future__ import annotations

from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from io import BytesIO

from mcap.opcode import Opcode
from mcap.records import Channel, Schema

from .framing import McapDamage, RawMessage, parse_record, read_message, read_records

PayloadCheck = Callable[[str, bytes], bool]  # (message type, CDR bytes) -> decodes as that type
IndexEntries = dict[int, tuple[int, int]]  # offset in the chunk's data -> (channel id, log time)
STEP = 4096  # compressed bytes fed to a decompressor at a time: the output before an error is kept


def readable_prefix(compression: str, data: bytes, limit: int) -> bytes:
    """As much of a chunk's uncompressed records as `data` yields before it ends or breaks, at most `limit` bytes."""
    if compression == "":
        return data[:limit]
    out = bytearray()
    try:
        if compression == "zstd":
            import zstandard

            with zstandard.ZstdDecompressor().stream_reader(BytesIO(data), read_size=STEP) as stream:
                while len(out) < limit and (piece := stream.read(min(STEP, limit - len(out)))):
                    out += piece
        elif compression == "lz4":
            import lz4.frame

            decompressor = lz4.frame.LZ4FrameDecompressor()
            for start in range(0, len(data), STEP):
                if len(out) >= limit or decompressor.eof:
                    break
                out += decompressor.decompress(data[start:start + STEP], max_length=limit - len(out))
    except Exception:
        pass
    return bytes(out[:limit])


@dataclass
class Salvage:
    """The records kept from a damaged chunk, the definitions among them, and why the walk ended."""

    messages: list[RawMessage] = field(default_factory=list)
    schemas: dict[int, Schema] = field(default_factory=dict)
    channels: dict[int, Channel] = field(default_factory=dict)
    end: str = ""  # where and why the walk stopped ('' if every record checks)

    def lost(self, entries: IndexEntries | None) -> Counter[int] | None:
        """Messages per channel the index lists that were not kept (None: the chunk's index is not readable)."""
        if entries is None:
            return None
        return Counter(channel for channel, _ in entries.values()) - Counter(m.channel_id for m in self.messages)


@dataclass(frozen=True)
class ChunkContext:
    """What a chunk's records are checked against: the file's definitions so far, the chunk's time range
    and message index, and the payload decoder."""

    schemas: dict[int, Schema]
    channels: dict[int, Channel]
    start_time: int
    end_time: int
    entries: IndexEntries | None
    decodes: PayloadCheck


def salvage(data: bytes, context: ChunkContext) -> Salvage:
    """The well-formed records at the start of a damaged chunk's (decompressed) `data`."""
    kept = Salvage()
    schemas, channels = dict(context.schemas), dict(context.channels)
    try:
        for offset, opcode, body in read_records(BytesIO(data), 0, len(data)):
            if opcode == Opcode.MESSAGE:
                message = read_message(body, f"byte {offset}", offset)
                defect = _defect(message, offset, context, schemas, channels)
                if defect:
                    kept.end = f"the message at byte {offset} of its data {defect}"
                    return kept
                kept.messages.append(message)
            elif opcode in (Opcode.SCHEMA, Opcode.CHANNEL):
                is_channel = opcode == Opcode.CHANNEL
                known, found = (channels, kept.channels) if is_channel else (schemas, kept.schemas)
                definition = parse_record(Channel.read if is_channel else Schema.read, body, "definition", offset)
                if known.get(definition.id, definition) != definition:
                    kept.end = f"the definition at byte {offset} of its data contradicts an earlier one"
                    return kept
                known[definition.id] = found[definition.id] = definition
            else:
                kept.end = f"record type 0x{opcode:02x} at byte {offset} of its data cannot stand in a chunk"
                return kept
    except McapDamage as error:
        kept.end = str(error)
    return kept


def _defect(message: RawMessage, offset: int, context: ChunkContext, schemas: dict[int, Schema],
            channels: dict[int, Channel]) -> str:
    """Why a message record of a damaged chunk is not to be trusted ('' if nothing says so)."""
    channel = channels.get(message.channel_id)
    if channel is None:
        return f"names channel {message.channel_id}, which is not defined"
    if not context.start_time <= message.log_time <= context.end_time:
        return f"is stamped {message.log_time} ns, outside the chunk's [{context.start_time}, {context.end_time}]"
    if context.entries is not None and context.entries.get(offset) != (message.channel_id, message.log_time):
        return "is not the message the chunk's index lists there"
    schema = schemas.get(channel.schema_id)
    if schema is None or channel.message_encoding != "cdr":
        return f"on {channel.topic} cannot be checked (no CDR schema)"
    if not context.decodes(schema.name, message.data):
        return f"does not decode as {schema.name}"
    return ""
