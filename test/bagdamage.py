"""A multi-chunk bag written by the package's writer, and where each of its messages lies in the file.

The offsets are found by a parser of its own (MCAP framing per the specification), not by
the reader under test.
"""
from __future__ import annotations

import shutil
import struct
from dataclasses import dataclass
from pathlib import Path

from cable_winch_monitor.bagio.reader import BagError, BagReader
from cable_winch_monitor.bagio.records import build
from cable_winch_monitor.bagio.writer import BagWriter

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
    """Every message of an uncompressed, chunked MCAP file with its byte range and its chunk's."""
    channels: dict[int, str] = {}
    found: list[Located] = []

    def channel(body: int) -> None:  # id, schema id, topic
        channel_id, _, topic_length = struct.unpack_from("<HHI", mcap, body)
        channels[channel_id] = mcap[body + 8:body + 8 + topic_length].decode()

    offset = 8
    while offset + 9 <= len(mcap):
        opcode, length = struct.unpack_from("<BQ", mcap, offset)
        body = offset + 9
        if opcode == 0x04:
            channel(body)
        elif opcode == 0x06:  # chunk: times, sizes, CRC, compression, records
            compression_length = struct.unpack_from("<I", mcap, body + 28)[0]
            data = body + 32 + compression_length + 8
            inner = data
            while inner < body + length:
                kind, size = struct.unpack_from("<BQ", mcap, inner)
                if kind == 0x04:
                    channel(inner + 9)
                elif kind == 0x05:
                    channel_id, _, log_time, _ = struct.unpack_from("<HIQQ", mcap, inner + 9)
                    found.append(Located(channels[channel_id], log_time, mcap[inner + 31:inner + 9 + size], inner,
                                         inner + 9 + size, (offset, body + length)))
                inner += 9 + size
        elif opcode == 0x0F:  # data end
            break
        offset = body + length
    return found


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
