"""The fast output path (compiled CDR encoders, direct MCAP append) gives the generic path's bytes.

The generic path is rosbags' own: `records.build` -> `Typestore.serialize_cdr` -> `Writer.write`, and
`McapWriter.close_chunk` with the chunk's CRC written in afterwards.
"""
from __future__ import annotations

import copy
import struct
import zlib
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rosbags.rosbag2.storage_mcap import McapWriter
from simbags import encoder_tracking_plant

from cable_winch_monitor.bagio.cdr import StackedEncoder, encoder, fixed_encoder
from cable_winch_monitor.bagio.typestore import typestore
from cable_winch_monitor.bagio.writer import CHUNK_SPAN, BagWriter
from cable_winch_monitor.messages import fields, frames, outputs, records, stacked
from cable_winch_monitor.paths import demo_bag
from cable_winch_monitor.replay import replay

BAG = demo_bag()  # bags/all_channels
NAN = float("nan")
TENSION = "cable_winch_monitor_msgs/msg/TensionDistribution"


def generic_encoder(msgtype: str) -> Any:
    store = typestore()
    return lambda values: bytes(store.serialize_cdr(records.build(msgtype, values), msgtype))


def generic_pose_records(stamps: list[Any], solutions: list[Any]) -> list[list[records.Record]]:
    """The pose and /tf of each solved pose, each message built and serialised by rosbags."""
    out = []
    for stamp, solution in zip(stamps, solutions):
        position, quaternion = solution.position.tolist(), solution.quaternion.tolist()
        out.append([generic_record(outputs.POSE, fields.pose_stamped(stamp, position, quaternion)),
                    generic_record(outputs.TF, frames.platform_tf(stamp, position, quaternion))])
    return out


def generic_record(topic: str, values: dict[str, Any]) -> records.Record:
    return topic, outputs.OUTPUT_TYPES[topic], generic_encoder(outputs.OUTPUT_TYPES[topic])(values)


def generic_stacked(patch: pytest.MonkeyPatch) -> None:
    """The outputs of a run of samples each laid out by `fields` and serialised by rosbags, not encoded together."""
    patch.setattr(stacked, "pose_records", generic_pose_records)
    patch.setattr(stacked, "tension_records", lambda stamps, solutions, estimates, channels: [
        generic_record(outputs.TENSION, fields.tension_distribution(stamp, solution, estimate, channels))
        for stamp, solution, estimate in zip(stamps, solutions, estimates)])
    patch.setattr(stacked, "alarm_records", lambda stamps, alarms: [
        generic_record(outputs.ALARM, fields.collision_alarm(stamp, alarm)) for stamp, alarm in zip(stamps, alarms)])
    patch.setattr(stacked, "model_error_records", lambda stamps, views, bases, estimates: [
        generic_record(outputs.MODEL_ERROR, fields.model_error(stamp, views[k], estimates[k], bases[k]))
        for k, stamp in enumerate(stamps)])
    patch.setattr(stacked, "residual_records", lambda stamps, residuals: [
        generic_record(outputs.RESIDUALS, fields.model_residuals(stamp, r)) for stamp, r in zip(stamps, residuals)])


def generic_append(self: BagWriter, channel: int, time: int, data: bytes) -> None:
    """rosbags' own write and counts, under the writer's chunk policy (bounded span; the CRC is added at
    close_chunk)."""
    chunk = self._storage.chunk
    if chunk.msgs and (time - chunk.message_start_time > CHUNK_SPAN or chunk.message_end_time - time > CHUNK_SPAN):
        self._storage.close_chunk()
    self._written[channel] += 1  # what the writer reports
    writer = self._writer
    writer.write(next(c for c in writer.connections if c.id == channel), time, data)


def generic_close_chunk(self: BagWriter) -> None:
    """rosbags' own close_chunk, then the CRC-32 of the chunk's data written into the chunk record."""
    storage = self._storage
    crc = zlib.crc32(storage.chunk.bio.getbuffer())
    start = storage.bio.tell()
    McapWriter.close_chunk(storage)
    end = storage.bio.tell()
    storage.bio.seek(start + 1 + 8 + 8 + 8 + 8)  # opcode, record length, start time, end time, uncompressed size
    storage.bio.write(struct.pack("<I", crc))
    storage.bio.seek(end)


def mcap_messages(bag: Path) -> list[tuple[str, int, bytes]]:
    """(topic, log time, CDR bytes) of every message, read with mcap; each one decoded by mcap-ros2."""
    (file,) = bag.glob("*.mcap")
    with file.open("rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        return [(channel.topic, message.log_time, message.data)
                for _, channel, message, _ in reader.iter_decoded_messages(log_time_order=False)]


@pytest.fixture(scope="module")
def replays(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """bags/all_channels replayed by the generic path and by the fast path (as `out`, in two directories), the
    bundled plant tracking its encoders' offsets (so that /model/parameters is written too)."""
    generic, fast = (tmp_path_factory.mktemp(name) / "out" for name in ("generic", "fast"))
    plant = encoder_tracking_plant(tmp_path_factory.mktemp("plant"))
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(records, "encoder", generic_encoder)
        patch.setattr(records, "sample_encoder", generic_encoder)
        patch.setattr(records, "scene_encoder", lambda: generic_encoder(outputs.OUTPUT_TYPES[outputs.SCENE]))
        generic_stacked(patch)
        patch.setattr(BagWriter, "_append", generic_append)
        patch.setattr(BagWriter, "_close_chunk", generic_close_chunk)
        patch.setattr(BagWriter, "_hand_over", lambda self: None)  # rosbags counted every message itself
        replay(BAG, generic, plant, progress=False)
    replay(BAG, fast, plant, progress=False)
    return generic, fast


def test_every_output_message_identical(replays: tuple[Path, Path]) -> None:
    generic, fast = (mcap_messages(bag) for bag in replays)
    written = [m for m in fast if m[0] in outputs.OUTPUT_TYPES]
    assert len(written) > 1000 and {m[0] for m in written} == set(outputs.OUTPUT_TYPES)
    assert len(fast) == len(generic)
    for index, (want, got) in enumerate(zip(generic, fast)):
        assert got == want, f"message {index} ({want[0]}) differs"


def test_bag_files_identical(replays: tuple[Path, Path]) -> None:
    generic, fast = replays
    for name in ("metadata.yaml", "out.mcap"):
        assert (fast / name).read_bytes() == (generic / name).read_bytes(), name


def header(sec: int = 12, nanosec: int = 345_678_901, frame_id: str = "shaft") -> dict[str, Any]:
    return {"stamp": {"sec": sec, "nanosec": nanosec}, "frame_id": frame_id}


def xyz(*values: float) -> dict[str, float]:
    return dict(zip("xyz", values))


EDGE_CASES = [
    ("cable_winch_monitor_msgs/msg/ModelResiduals",
     {"header": header(frame_id=""), "channels": [], "measured": [], "predicted": [], "residuals": [], "noise": []}),
    ("cable_winch_monitor_msgs/msg/ModelResiduals",
     {"header": header(-1, 0, "shäft"), "channels": ["a", "roll", ""], "measured": [1.0, -0.0, NAN],
      "predicted": [float("inf"), 2.5, 1e-300], "residuals": [0.1], "noise": [NAN, NAN]}),
    ("cable_winch_monitor_msgs/msg/CollisionAlarm",
     {"header": header(frame_id="ab"), "level": 3, "clearance": -0.25, "closest_point_name": "deck_1/p3",
      "closest_point_platform": xyz(1, 2, 3), "closest_point_shaft": xyz(NAN, NAN, NAN),
      "sync_error_pairs": ["cable_1-cable_2"], "sync_errors": [], "reason": "clearance"}),
    ("cable_winch_monitor_msgs/msg/TensionDistribution",
     {"header": header(frame_id="abc"), "status": 4, "tension_state": "", "cables": [
         {"name": f"cable_{i}" * i, "length": 1.0 * i, "span": NAN, "tension": 0.0, "taut": i % 2 == 0}
         for i in range(1, 4)], "equilibrium_residual": 1e-9, "solver": "energy", "iterations": 2 ** 32 - 1,
      "sensors_used": ["tension_cable_1", "/platform/imu", "x"], "length_corrections_sigma": [0.5, -1.0, NAN, 3.0]}),
    ("geometry_msgs/msg/PoseStamped",
     {"header": header(frame_id="abcd"), "pose": {"position": xyz(NAN, 0.5, -7), "orientation": {
         "x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}}}),
    ("sensor_msgs/msg/Imu",
     {"header": header(frame_id="x"), "orientation": {"x": 0.1, "y": 0.2, "z": 0.3, "w": 0.9},
      "orientation_covariance": [0.5] * 9, "angular_velocity": xyz(1, 2, 3),
      "angular_velocity_covariance": list(range(9)), "linear_acceleration": xyz(0, 0, 9.81),
      "linear_acceleration_covariance": [-1.0] * 9}),
    ("sensor_msgs/msg/JointState",
     {"header": header(), "name": ["cable_1", "cable_2"], "position": [1.0, 2.0], "velocity": [], "effort": [3.0]}),
    ("cable_winch_monitor_msgs/msg/ModelParameters",
     {"header": header(frame_id="ab"), "names": ["rope_elasticity.EA", "encoder_offset.d_1", ""], "units": ["N", "m"],
      "values": [6.8e7, -0.05, NAN], "sigmas": [1e5], "in_use": [True, False, True], "values_in_use": [],
      "file_values": [7.5e7, 0.0, 1.0], "tolerances": [3.4e6, 0.01, 1.0], "excited": [False],
      "drifting": [True, False], "drifting_since": [NAN, 12.5, -1.0], "updated": NAN}),
]


@pytest.mark.parametrize(("msgtype", "values"), EDGE_CASES, ids=[f"{t}-{i}" for i, (t, _) in enumerate(EDGE_CASES)])
def test_encoder_matches_rosbags(msgtype: str, values: dict[str, Any]) -> None:
    assert encoder(msgtype)(values) == generic_encoder(msgtype)(values)


def test_fixed_fields_give_the_bytes_of_the_full_encoder() -> None:
    """Fields fixed at generation (numbers, NaN, strings, empty sequences, partial sub-messages) are packed
    as the encoder packs them when it reads them, whatever the offset the variable fields leave."""
    imu = dict(EDGE_CASES[5][1])
    fixed = {"sensor_msgs/msg/Imu": {"orientation": {"x": NAN, "w": 1.0}, "orientation_covariance": [0.5] * 9,
                                     "linear_acceleration": xyz(0, 0, 9.81)},
             "std_msgs/msg/Header": {"frame_id": "x"}}
    imu["orientation"] = {"x": NAN, "y": 0.2, "z": 0.3, "w": 1.0}
    assert fixed_encoder("sensor_msgs/msg/Imu", fixed)(imu) == generic_encoder("sensor_msgs/msg/Imu")(imu)
    alarm = dict(EDGE_CASES[2][1])
    pinned = {"cable_winch_monitor_msgs/msg/CollisionAlarm": {"closest_point_name": "deck_1/p3", "sync_errors": [],
                                                              "reason": "clearance"}}
    for frame in ("", "a", "ab", "abc", "abcd"):  # every offset mod 8 before the fixed fields
        alarm["header"] = header(frame_id=frame)
        got = fixed_encoder("cable_winch_monitor_msgs/msg/CollisionAlarm", pinned)(alarm)
        assert got == generic_encoder("cable_winch_monitor_msgs/msg/CollisionAlarm")(alarm), frame


def test_stacked_encoder_gives_the_encoders_bytes() -> None:
    """Messages encoded together from columns (floats with NaN, infinities and -0.0; bools; unsigned and signed
    integers of every width the messages use) are each the bytes rosbags serialises, for strings of every
    length mod 8 before the columns."""
    rng = np.random.default_rng(3)
    count = 50
    floats = rng.normal(size=(13, count)) * 10.0 ** rng.integers(-300, 300, size=(13, count))
    floats[:, :4] = [NAN, float("inf"), -0.0, -float("inf")]
    for frame in ("", "a", "ab", "abc", "abcd", "abcdefgh"):
        template = dict(EDGE_CASES[3][1], header=header(frame_id=frame))
        paths = [("header", "stamp", "sec"), ("header", "stamp", "nanosec"), ("status",), ("iterations",),
                 ("equilibrium_residual",), *(("length_corrections_sigma", i) for i in range(4)),
                 *(("cables", i, name) for i in range(3) for name in ("length", "taut"))]
        columns = [rng.integers(-2 ** 31, 2 ** 31, count), rng.integers(0, 2 ** 32, count),
                   rng.integers(0, 256, count), rng.integers(0, 2 ** 32, count), *floats[:5],
                   *(column for i in range(3) for column in (floats[5 + i], rng.random(count) < 0.5))]
        encoded = StackedEncoder(TENSION, template, paths).encode(*columns)
        for k, got in enumerate(encoded):
            values = copy.deepcopy(template)
            for path, column in zip(paths, columns):
                holder = values
                for step in path[:-1]:
                    holder = holder[step]
                holder[path[-1]] = column[k].item()
            assert got == generic_encoder(TENSION)(values), (frame, k)


def test_stacked_encoder_takes_only_numbers() -> None:
    with pytest.raises(TypeError, match="neither a number nor a string"):
        StackedEncoder(TENSION, EDGE_CASES[3][1], [("cables",)])
    with pytest.raises(TypeError, match="no field"):
        StackedEncoder(TENSION, EDGE_CASES[3][1], [("cables", "length")])
