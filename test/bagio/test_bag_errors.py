"""Damaged and strange bags: a clear error, or a partial replay whose summary says what it skipped.

Each case runs the CLI in a subprocess (exit status, no traceback) and calls the library.
The damaged bags hold camera images besides the monitor's inputs, so that they span
several MCAP chunks (rosbags closes a chunk at 1 MiB) and damage can hit one of them.
"""
from __future__ import annotations

import os
import shutil
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from simbags import assert_clean, run_cli, simulated

from cable_winch_monitor.bagio.reader import BagError, BagReader
from cable_winch_monitor.bagio.writer import BagWriter, new_bag
from cable_winch_monitor.messages.records import build
from cable_winch_monitor.replay import replay

JOINTS = "/winch/joint_states"
IMAGE_BYTES = 300_000


def camera_image(log_time: int) -> object:
    sec, nanosec = divmod(log_time, 1_000_000_000)
    return build("sensor_msgs/msg/Image", {
        "header": {"stamp": {"sec": sec, "nanosec": nanosec}, "frame_id": "camera"}, "height": 1,
        "width": IMAGE_BYTES, "encoding": "mono8", "is_bigendian": 0, "step": IMAGE_BYTES,
        "data": np.full(IMAGE_BYTES, 7, dtype=np.uint8)})


@pytest.fixture(scope="module")
def camera_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Nominal lowering (10 s, 100 joint states) with a 300 kB camera image every 0.5 s: 3 chunks."""
    directory = tmp_path_factory.mktemp("camera")
    source = simulated(directory, "nominal_lowering", "duration=10")
    out = directory / "camera_bag"
    next_image = 0
    with BagWriter(out) as writer:
        for item in BagReader(source):
            while next_image <= item.log_time:
                writer.write("/shaft/camera", "sensor_msgs/msg/Image", next_image, camera_image(next_image))
                next_image += 500_000_000
            writer.write_raw(item.topic, item.msgtype, item.log_time, item.data)
    return out


def copy_bag(bag: Path, directory: Path) -> tuple[Path, Path]:
    """A copy of the bag and its .mcap file."""
    copy = directory / "damaged"
    shutil.copytree(bag, copy)
    return copy, next(copy.glob("*.mcap"))


def chunk_spans(mcap: Path) -> list[tuple[int, int]]:
    with mcap.open("rb") as stream:
        return sorted((c.chunk_start_offset, c.chunk_length) for c in make_reader(stream).get_summary().chunk_indexes)


def test_camera_bag_replays_whole(camera_bag, tmp_path):
    summary = replay(camera_bag, tmp_path / "out", progress=False)
    assert summary.complete and len(chunk_spans(next(camera_bag.glob("*.mcap")))) >= 3
    assert summary.stats.used[JOINTS] == 100
    assert summary.report.skipped[("/shaft/camera", "not an input topic")] == summary.report.read["/shaft/camera"] > 0


def test_truncated_file(camera_bag, tmp_path):
    bag, mcap = copy_bag(camera_bag, tmp_path)
    os.truncate(mcap, int(mcap.stat().st_size * 0.6))
    result = run_cli("replay", bag, "--out", tmp_path / "out")
    assert_clean(result, 1)
    assert "no footer" in result.stdout and "PARTIAL REPLAY" in result.stdout
    assert "cut short at byte" in result.stdout
    summary = replay(bag, tmp_path / "out2", progress=False)
    assert not summary.complete and 0 < summary.stats.used[JOINTS] < 100
    assert all(row.balanced for row in summary.topics())


def test_corrupt_chunk(camera_bag, tmp_path):
    bag, mcap = copy_bag(camera_bag, tmp_path)
    start, length = chunk_spans(mcap)[1]
    data = bytearray(mcap.read_bytes())
    middle = start + length // 2
    data[middle:middle + 512] = bytes(b ^ 0xFF for b in data[middle:middle + 512])
    mcap.write_bytes(bytes(data))
    result = run_cli("replay", bag, "--out", tmp_path / "out")
    assert_clean(result, 1)
    assert f"chunk at byte {start} damaged" in result.stdout and "PARTIAL REPLAY" in result.stdout
    summary = replay(bag, tmp_path / "out2", progress=False)
    lost = summary.report.lost[JOINTS]
    assert lost > 0 and summary.stats.used[JOINTS] + lost == 100  # the message index tells what was lost
    assert summary.samples > 0 and all(row.balanced for row in summary.topics())


def test_unknown_topics_and_types(tmp_path):
    source = simulated(tmp_path, "nominal_lowering", "duration=3")
    store = get_typestore(Stores.ROS2_JAZZY)
    store.register(get_types_from_msg("float64 depth\nstring note", "vendor_msgs/msg/Depth"))
    bag = tmp_path / "strange"
    with BagWriter(bag, store) as writer:
        for item in BagReader(source):
            writer.write_raw(item.topic, item.msgtype, item.log_time, item.data)
            depth = store.types["vendor_msgs/msg/Depth"](depth=-50.0, note="laser")
            writer.write("/platform/position", "vendor_msgs/msg/Depth", item.log_time, depth)  # an input topic
            writer.write("/vendor/depth", "vendor_msgs/msg/Depth", item.log_time, depth)
            note = store.types["std_msgs/msg/String"]("hi")
            writer.write("/operator/note", "std_msgs/msg/String", item.log_time, note)
    result = run_cli("replay", bag, "--out", tmp_path / "out")
    assert_clean(result, 0)
    for line in ("skipped /platform/position: type vendor_msgs/msg/Depth, expected geometry_msgs/msg/PointStamped: 30",
                 "skipped /vendor/depth: not an input topic: 30", "skipped /operator/note: not an input topic: 30"):
        assert line in result.stdout
    summary = replay(bag, tmp_path / "out2", progress=False)
    assert summary.complete and summary.stats.used[JOINTS] == 30 and all(row.balanced for row in summary.topics())
    reader = BagReader(bag)  # every topic asked for: the vendor type is unknown to the type store
    assert sum(1 for _ in reader) == 60
    assert reader.report.skipped[("/vendor/depth", "unknown type vendor_msgs/msg/Depth")] == 30


def test_no_metadata(tmp_path):
    bag = simulated(tmp_path, "nominal_lowering", "duration=3")
    (bag / "metadata.yaml").unlink()
    result = run_cli("replay", bag, "--out", tmp_path / "out")
    assert_clean(result, 0)
    assert "has no metadata.yaml: reading its 1 .mcap file(s) directly" in result.stdout
    summary = replay(bag, tmp_path / "out2", progress=False)
    assert summary.complete and summary.stats.used[JOINTS] == 30
    bare = replay(next(bag.glob("*.mcap")), tmp_path / "out3", progress=False)  # a bare .mcap file
    assert bare.complete and bare.stats.used[JOINTS] == 30 and not bare.report.notes


@pytest.mark.parametrize("case, message", [
    ("missing", "no such file or directory"),
    ("empty file", "is empty"),
    ("empty directory", "neither metadata.yaml nor .mcap files"),
    ("text file", "is not an MCAP file"),
])
def test_no_bag_at_all(tmp_path, case, message):
    path = tmp_path / "input.mcap"
    if case == "empty file":
        path.write_bytes(b"")
    elif case == "empty directory":
        path.mkdir()
    elif case == "text file":
        path.write_text("not a bag\n")
    result = run_cli("replay", path, "--out", tmp_path / "out")
    assert_clean(result, 2)
    assert result.stderr.startswith("error: ") and message in result.stderr
    assert not (tmp_path / "out").exists()
    with pytest.raises(BagError, match=message):
        replay(path, tmp_path / "out", progress=False)


def test_output_exists(tmp_path):
    bag = simulated(tmp_path, "nominal_lowering", "duration=1")
    result = run_cli("replay", bag, "--out", bag)
    assert_clean(result, 2)
    assert "exists already" in result.stderr


def test_a_jobs_bag_is_created_at_its_first_message_and_a_job_without_one_leaves_an_empty_bag(tmp_path):
    """`new_bag` checks the path at once and creates the bag at the first message (a replay's second process
    estimates meanwhile); a job that writes nothing leaves an empty bag that readers open, one that fails
    leaves none."""
    with new_bag(tmp_path / "empty") as writer:
        assert not (tmp_path / "empty").exists()
    assert writer.counts == {} and list(BagReader(tmp_path / "empty")) == []
    with (tmp_path / "empty" / "empty.mcap").open("rb") as file:  # mcap's own reader: a summary, no message
        assert make_reader(file).get_summary() is not None and list(make_reader(file).iter_messages()) == []
    with new_bag(tmp_path / "one") as writer:
        writer.write("/clock", "rosgraph_msgs/msg/Clock", 5, build("rosgraph_msgs/msg/Clock", {"clock": {"sec": 0,
                                                                                                 "nanosec": 5}}))
        assert (tmp_path / "one").is_dir()
    assert [m.log_time for m in BagReader(tmp_path / "one")] == [5]
    with pytest.raises(BagError, match="exists already"):
        with new_bag(tmp_path / "one"):
            pass
    with pytest.raises(RuntimeError), new_bag(tmp_path / "failed"):
        raise RuntimeError("the job failed")
    assert not (tmp_path / "failed").exists()
