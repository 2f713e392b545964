"""A multi-chunk bag written by the package's writer (or by mcap's writer, compressed), and where each of
its messages lies in the file.

The offsets are found by a parser of its own (MCAP framing per the specification), not by
the reader under test. A message in a compressed chunk has no bytes of its own in the file:
its range is its chunk's.
"""
from __future__ import annotations

import shutil
import struct
from dataclasses import dataclass
from pathlib import Path

import lz4.frame
import zstandard
from mcap.writer import CompressionType, Writer

from cable_winch_monitor.bagio.reader import BagError, BagReader
from cable_winch_monitor.bagio.typestore import typestore
from cable_winch_monitor.bagio.writer import BagWriter
from cable_winch_monitor.messages.records import build

T0 = 1_700_000_000 * 10 ** 9
TOPICS = {"/winch/joint_states": "sensor_msgs/msg/JointState", "/platform/imu": "sensor_msgs/msg/Imu"}


@dataclass(frozen=True)
class Located:
    topic: str
    log_time: int
    data: bytes
    start: int  # first byte of its record in the file
    end: int  # one past its last byte
    chunk: tuple[int, int]  # the chunk record holding it: first byte, one past the last


def write_bag(path: Path, seconds: float = 12.0, rate: float = 50.0) -> Path:
    """Winch and inclinometer messages at `rate` each for `seconds`: one chunk per second of log time."""
    with BagWriter(path) as writer:
        for k in range(int(seconds * rate)):
            ns = T0 + int(k * 1e9 / rate)
            header = {"stamp": {"sec": ns // 10 ** 9, "nanosec": ns % 10 ** 9}, "frame_id": ""}
            writer.write("/winch/joint_states", TOPICS["/winch/joint_states"], ns, build(
                TOPICS["/winch/joint_states"], {"header": header, "name": ["cable_1", "cable_2", "cable_3", "cable_4"],
                                                "position": [20.0 + k * 1e-3] * 4, "velocity": [0.05] * 4,
                                                "effort": [24_500.0 + k] * 4}))
            quaternion = {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}
            writer.write("/platform/imu", TOPICS["/platform/imu"], ns + 35_000_000, build(TOPICS["/platform/imu"], {
                "header": header, "orientation": quaternion, "orientation_covariance": [float(k)] * 9,
                "angular_velocity": {"x": 0.0, "y": 0.0, "z": 0.0}, "angular_velocity_covariance": [0.0] * 9,
                "linear_acceleration": {"x": 0.0, "y": 0.0, "z": 9.81},
                "linear_acceleration_covariance": [0.0] * 9}))
    return path


def locate(mcap: bytes) -> list[Located]:
    """Every message of a chunked MCAP file with its byte range and its chunk's."""
    channels: dict[int, str] = {}
    found: list[Located] = []

    def channel(records: bytes, body: int) -> None:  # id, schema id, topic
        channel_id, _, topic_length = struct.unpack_from("<HHI", records, body)
        channels[channel_id] = records[body + 8:body + 8 + topic_length].decode()

    offset = 8
    while offset + 9 <= len(mcap):
        opcode, length = struct.unpack_from("<BQ", mcap, offset)
        body = offset + 9
        if opcode == 0x04:
            channel(mcap, body)
        elif opcode == 0x06:  # chunk: times, sizes, CRC, compression, records
            compression_length = struct.unpack_from("<I", mcap, body + 28)[0]
            compression = mcap[body + 32:body + 32 + compression_length].decode()
            data = body + 32 + compression_length + 8
            records, base = _chunk_records(compression, mcap[data:body + length]), data
            inner = 0
            while inner < len(records):
                kind, size = struct.unpack_from("<BQ", records, inner)
                if kind == 0x04:
                    channel(records, inner + 9)
                elif kind == 0x05:
                    channel_id, _, log_time, _ = struct.unpack_from("<HIQQ", records, inner + 9)
                    start, end = (base + inner, base + inner + 9 + size) if not compression else (offset, body + length)
                    found.append(Located(channels[channel_id], log_time, records[inner + 31:inner + 9 + size],
                                         start, end, (offset, body + length)))
                inner += 9 + size
        elif opcode == 0x0F:  # data end
            break
        offset = body + length
    return found


def _chunk_records(compression: str, data: bytes) -> bytes:
    if compression == "zstd":
        return zstandard.ZstdDecompressor().decompressobj().decompress(data)
    if compression == "lz4":
        return lz4.frame.decompress(data)
    return data


def write_compressed(bag: Path, path: Path, compression: CompressionType, chunk_size: int = 2 ** 20) -> Path:
    """A copy of the rosbag2 directory `bag` (its metadata.yaml, its messages) whose .mcap file mcap's writer
    writes, with its defaults otherwise (CRCs, message indexes, summary)."""
    store = typestore()
    original = next(bag.glob("*.mcap"))
    path.mkdir()
    shutil.copy(bag / "metadata.yaml", path)
    with (path / original.name).open("wb") as stream:
        writer = Writer(stream, chunk_size=chunk_size, compression=compression)
        writer.start("ros2", "cable_winch_monitor")
        ids: dict[str, int] = {}
        for topic, msgtype in TOPICS.items():
            schema = writer.register_schema(msgtype, "ros2msg", store.generate_msgdef(msgtype, ros_version=2)[0].encode())
            ids[topic] = writer.register_channel(topic, "cdr", schema)
        for sequence, m in enumerate(locate(original.read_bytes())):
            writer.add_message(ids[m.topic], m.log_time, m.data, m.log_time, sequence)
        writer.finish()
    return path


def read_damaged(bag: Path, directory: Path, content: bytes) -> tuple[list[tuple[str, int, bytes]] | None, object]:
    """The messages the reader delivers from a copy of `bag` whose .mcap holds `content`
    (None if it refuses the bag as a whole), with its report."""
    copy = directory / "copy"
    shutil.rmtree(copy, ignore_errors=True)
    copy.mkdir()
    shutil.copy(bag / "metadata.yaml", copy)
    (copy / next(bag.glob("*.mcap")).name).write_bytes(content)
    try:
        reader = BagReader(copy, TOPICS)
    except BagError:
        return None, None
    return [(m.topic, m.log_time, m.data) for m in reader], reader.report


def check_replayed(located, delivered, report, damage: tuple[int, int]) -> int:
    """Every message wholly before the damage is replayed; every replayed message is the intact bag's message of
    that topic and log time, byte for byte, unless its bytes overlap the damaged range (returned: how many such
    messages came out altered); the messages replayed and the ones counted as lost add up to the intact bag's."""
    start, end = damage
    intact = {(m.topic, m.log_time): m for m in located}
    assert len(intact) == len(located)
    before = {(m.topic, m.log_time, m.data) for m in located if m.end <= start}
    assert before <= set(delivered), f"damage at {start}: {len(before - set(delivered))} messages before it lost"
    assert len(delivered) == len(set(delivered)), "a message replayed twice"
    altered = 0
    for topic, log_time, data in delivered:
        original = intact.get((topic, log_time))
        assert original is not None, f"damage at {start}: a message the bag does not hold ({topic} at {log_time})"
        if data != original.data:
            assert original.start < end and original.end > start, f"damage at {start}: {topic} at {log_time} altered"
            altered += 1
    assert len(delivered) + report.missing == len(located)
    if not any("not known" in line for line in report.damage):
        assert len(delivered) + sum(report.lost.values()) == len(located), report.damage
    assert report.complete == (len(delivered) == len(located)) or report.damage
    return altered
