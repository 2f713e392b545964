"""Simulated bags replayed through the monitor; the output bag read back with rosbags and with mcap."""
from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rosbags.rosbag2 import Reader
from simbags import assert_clean, messages, run_cli, simulated, truth

from cable_winch_monitor.bagio.typestore import typestore
from cable_winch_monitor.messages.fields import input_topics
from cable_winch_monitor.messages.outputs import (
    ALARM,
    DIAGNOSTICS,
    OUTLINE,
    OUTPUT_TYPES,
    PARAMETERS,
    POSE,
    RESIDUALS,
    SCENE,
    TENSION,
    TF,
    TF_STATIC,
)
from cable_winch_monitor.monitor.alarm import AlarmPolicy
from cable_winch_monitor.replay import replay
from cable_winch_monitor.replay import worker as forked

SLACK_TOLERANCE = AlarmPolicy().slack_tolerance


def ns(stamp) -> int:
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def header(item):
    """The header of a stamped output (of the first transform or marker for /tf, /tf_static and the scene)."""
    if item.topic in (TF, TF_STATIC):
        return item.message.transforms[0].header
    return item.message.markers[0].header if item.topic in (SCENE, OUTLINE) else item.message.header


@pytest.fixture(scope="module")
def all_channels(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, object]:
    """The all-channels scenario cut to 12 s, and its replay."""
    directory = tmp_path_factory.mktemp("all_channels")
    bag = simulated(directory, "all_channels", "duration=12")
    out = directory / "replayed"
    return bag, out, replay(bag, out, progress=False)


def rosbags_messages(bag: Path) -> list[tuple[str, int, bytes, object]]:
    """(topic, log time, raw, decoded) with rosbags' own rosbag2 reader, independently of bagio."""
    store = typestore()
    with Reader(bag) as reader:
        return [(c.topic, t, bytes(raw), store.deserialize_cdr(raw, c.msgtype))
                for c, t, raw in reader.messages()]


def mcap_messages(bag: Path) -> list[tuple[str, int, bytes, object]]:
    """The same with mcap + mcap-ros2-support, types decoded from the schemas stored in the bag."""
    (file,) = bag.glob("*.mcap")
    with file.open("rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        return [(c.topic, m.log_time, bytes(m.data), decoded) for _, c, m, decoded in reader.iter_decoded_messages()]


def test_every_input_is_accounted_for(all_channels):
    bag, _, summary = all_channels
    inputs = Counter(topic for topic, *_ in rosbags_messages(bag))
    assert set(inputs) == {"/winch_1/joint_states", "/winch_2/joint_states", "/winch_3/joint_states",
                           "/winch_4/joint_states", "/platform/imu", "/platform/position"}
    rows = {row.topic: row for row in summary.topics()}
    assert {topic: row.read for topic, row in rows.items()} == inputs
    assert all(row.balanced and row.skipped == 0 for row in rows.values())
    stats = summary.stats
    for topic in inputs:
        rejected = sum(n for key, n in stats.rejected.items() if key.startswith(f"{topic}: "))
        assert stats.messages[topic] == stats.used[topic] + rejected
    assert summary.complete and summary.samples == stats.solved > 400 and stats.failures == 0
    text = summary.format()
    for expected in ("/platform/imu", "samples:", "tension states:", "alarm levels:", "samples/s"):
        assert expected in text


def test_output_bag_reads_back_with_rosbags_and_mcap(all_channels):
    bag, out, summary = all_channels
    ours, theirs = rosbags_messages(out), mcap_messages(out)
    assert sorted((t, lt, raw) for t, lt, raw, _ in ours) == sorted((t, lt, raw) for t, lt, raw, _ in theirs)
    assert Counter(t for t, *_ in ours) == summary.written + summary.report.read
    # the inputs are in the output bag unchanged, at their own log times
    assert sorted((t, lt, raw) for t, lt, raw, _ in rosbags_messages(bag)) == sorted(
        (t, lt, raw) for t, lt, raw, _ in ours if t in input_topics())
    # custom types decode the same from the bag's schemas (mcap) as from msg_defs (rosbags)
    decoded = {(t, lt): m for t, lt, _, m in theirs if t in (TENSION, ALARM)}
    for topic, log_time, _, message in ours:
        if topic == TENSION:
            other = decoded[topic, log_time]
            assert other.tension_state == message.tension_state
            assert [(c.name, c.tension, c.taut) for c in other.cables] == [
                (c.name, c.tension, c.taut) for c in message.cables]
        elif topic == ALARM:
            assert (decoded[topic, log_time].level, decoded[topic, log_time].reason) == (message.level, message.reason)


def test_outputs_carry_input_stamps_and_physics(all_channels):
    bag, out, _ = all_channels
    joint_stamps = {ns(m.message.header.stamp) for m in messages(bag) if m.topic.endswith("joint_states")}
    input_stamps = {ns(m.message.header.stamp) for m in messages(bag)}
    outputs = messages(out, OUTPUT_TYPES)
    assert Counter(m.topic for m in outputs).keys() == set(OUTPUT_TYPES) - {PARAMETERS}  # the plant tracks nothing
    first = min(m.log_time for m in messages(bag))
    log_times = {m.log_time for m in messages(bag)}
    for item in outputs:
        stamp = ns(header(item).stamp)
        if item.topic == DIAGNOSTICS:  # on the clock, as the node publishes them: replay's clock is the log time
            assert item.log_time == stamp and stamp in log_times and header(item).frame_id == ""
            continue
        assert item.log_time == stamp and header(item).frame_id == ("platform" if item.topic == OUTLINE else "shaft")
        if item.topic in (TF_STATIC, OUTLINE):
            assert stamp == first, "what does not change comes first"
        else:
            assert stamp in (input_stamps if item.topic == RESIDUALS else joint_stamps)
    poses = {ns(m.message.header.stamp) for m in outputs if m.topic == POSE}
    assert poses == {ns(header(m).stamp) for m in outputs if m.topic == TF}, "a transform with every pose"
    for item in outputs:
        if item.topic != TENSION:
            continue
        message = item.message
        assert (message.status == 0) == (ns(message.header.stamp) in poses)
        for cable in message.cables:
            assert cable.tension >= 0.0
            if cable.taut:
                assert abs(cable.span - cable.length) < 1e-6 and cable.tension > 0.0
            else:
                assert cable.tension == 0.0 and cable.span <= cable.length + 1e-9


def loose_cables(out: Path) -> Counter[str]:
    """Cables reported slack and looser than the alarm's tolerance, per cable."""
    loose: Counter[str] = Counter()
    for item in messages(out, {TENSION: OUTPUT_TYPES[TENSION]}):
        loose.update(c.name for c in item.message.cables if not c.taut and c.length - c.span > SLACK_TOLERANCE)
    return loose


def test_lag_event_slackens_a_cable(tmp_path):
    bag = simulated(tmp_path, "lag_slack", "duration=20")
    summary = replay(bag, tmp_path / "out", progress=False)
    assert summary.complete and summary.stats.levels["WARNING"] > 0
    assert loose_cables(tmp_path / "out")["cable_2"] > 20
    reasons = [m.message.reason for m in messages(tmp_path / "out", {ALARM: OUTPUT_TYPES[ALARM]})]
    assert any("slack: cable_2 loose" in reason for reason in reasons)
    # the truth agrees: with elastic ropes all four carry load until the lag unloads cable 2
    states = Counter(row["taut"] for row in truth(bag))
    assert states["1 2 3 4"] > 0 and states["1 3 4"] > 20


def test_sync_error_raises_critical(tmp_path):
    bag = simulated(tmp_path, "sync_critical", "duration=20")
    result = run_cli("replay", bag, "--out", tmp_path / "out")
    assert_clean(result, 0)
    assert "CRITICAL" in result.stdout
    levels = Counter(m.message.level for m in messages(tmp_path / "out", {ALARM: OUTPUT_TYPES[ALARM]}))
    assert levels[2] > 5 and levels[3] == 0
    clearances = np.array([float(row["clearance"]) for row in truth(bag)])
    assert 0.0 < clearances.min() < 0.05


def test_nominal_lowering_stays_ok(tmp_path):
    bag = simulated(tmp_path, "nominal_lowering", "duration=15")
    summary = replay(bag, tmp_path / "out", progress=False)
    assert summary.stats.levels.keys() == {"OK"} and summary.samples == summary.stats.solved == 150


def test_a_second_process_writes_the_bag_one_process_writes(tmp_path, monkeypatch):
    """The second process estimates, judges and encodes the samples (replay.stages.WindowStages) while the
    replay merges and writes; the bag is the one a single process writes, byte for byte, /diagnostics
    included, here with an inclinometer knocked 2 deg off its mounting halfway through."""
    monkeypatch.setattr(forked, "SPOOL", str(tmp_path / "spool"))
    (tmp_path / "spool").mkdir()
    bag = simulated(tmp_path, "all_channels", "duration=20",
                    "sensors.faults=[{sensor: imu, kind: offset, roll: 0.0349, start: 10.0}]")
    one = replay(bag, tmp_path / "one" / "out", progress=False, second_process=False)
    two = replay(bag, tmp_path / "two" / "out", progress=False)
    assert one.stats.levels == two.stats.levels and one.stats.faults == two.stats.faults
    assert "/platform/imu" in two.stats.faults and two.written["/diagnostics"] >= 19
    files = [sorted((tmp_path / name / "out").glob("*.mcap")) for name in ("one", "two")]
    assert [f.read_bytes() for f in files[0]] == [f.read_bytes() for f in files[1]]
    assert not any((tmp_path / "spool").iterdir())
