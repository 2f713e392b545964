"""Implausible winch stamps are refused with their reason and never block the good samples after them."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from cable_winch_monitor.model.plantfile.plant import CABLE_NAMES
from cable_winch_monitor.monitor.inputs import CableLengthMerger, InputLimits, JointSample, StampWindow
from cable_winch_monitor.monitor.pipeline import MonitorPipeline

T0 = 1.7e9  # a wall-clock stamp [s]
FAR_FUTURE = (T0 + 1e6, float(2 ** 31 - 1))


def winch(cable: int, stamp: float, length: float, received: float | None = None, velocity: float | None = None):
    """A per-winch message arriving at `received` (default: its stamp plus 5 ms)."""
    return JointSample(stamp, [CABLE_NAMES[cable]], [length], [] if velocity is None else [velocity],
                       topic=f"/winch_{cable + 1}/joint_states", received=stamp + 0.005 if received is None else received)


def merged(stamp: float, lengths, received: float | None = None):
    return JointSample(stamp, list(CABLE_NAMES), list(lengths), received=stamp + 0.005 if received is None else received)


def lowering(pipeline: MonitorPipeline, start: float, steps: int, bad: dict[int, JointSample] | None = None):
    """Four winches at 10 Hz paying out 0.5 m/s from 20 m; message k replaced by bad[k]. The solved outputs."""
    outputs = []
    for k in range(steps):
        t = start + 0.1 * (k // 4)
        cable = k % 4
        sample = (bad or {}).get(k) or winch(cable, t + 0.001 * cable, 20.0 + 0.5 * (t - start) + 0.01 * cable)
        outputs.append(pipeline.on_joint_state(sample))
    return [o for o in outputs if o is not None]


@pytest.mark.parametrize("stamp", FAR_FUTURE)
def test_a_far_future_winch_stamp_is_refused_and_the_cable_keeps_solving(plant, stamp):
    pipeline = MonitorPipeline(plant)
    lowering(pipeline, T0, 8)
    arrival = T0 + 0.2
    bad = {0: winch(2, stamp, 20.3, received=arrival)}
    outputs = lowering(pipeline, T0 + 0.2, 400, bad)
    assert any(k.startswith("/winch_3/joint_states: stamp ahead of the clock") for k in pipeline.stats.rejected)
    assert sum(pipeline.stats.rejected.values()) == 1, pipeline.stats.rejected
    assert "stamp ahead of the clock: cable_3" in pipeline.stats.last_rejection
    assert len(outputs) == 399 and all(o.solution.ok for o in outputs)
    # cable 3 follows its winch to the end: its length is not frozen at the value before the bad stamp
    last = outputs[-1]
    assert last.solution.lengths[2] == pytest.approx(20.0 + 0.5 * (last.stamp - T0 - 0.2) + 0.02, abs=0.06)


def test_a_far_future_stamp_on_the_merged_topic_costs_one_message(plant):
    pipeline = MonitorPipeline(plant)
    assert pipeline.on_joint_state(merged(T0, [20.0] * 4)).solution.ok
    assert pipeline.on_joint_state(merged(T0 + 1e6, [20.1] * 4, received=T0 + 0.1)) is None
    outputs = [pipeline.on_joint_state(merged(T0 + 0.1 * k, [20.0 + 0.01 * k] * 4)) for k in range(2, 800)]
    assert all(o is not None and o.solution.ok for o in outputs)
    assert list(pipeline.stats.rejected) == ["/winch/joint_states: stamp ahead of the clock"]


def test_a_stamp_far_behind_its_arrival_is_refused(plant):
    pipeline = MonitorPipeline(plant)
    assert pipeline.on_joint_state(merged(5.0, [20.0] * 4, received=T0)) is None
    assert "stamp behind the clock: cable_1" in pipeline.stats.last_rejection
    assert pipeline.on_joint_state(merged(T0, [20.0] * 4)).solution.ok


def test_a_winch_ahead_of_the_other_winches_is_refused_within_the_clock_window(plant):
    """Winch 2's clock runs 1.5 s ahead: inside the 2 s clock window, outside a 1 s skew window."""
    pipeline = MonitorPipeline(plant, stamp_window=StampWindow(ahead=2.0, behind=10.0, skew=1.0))
    lowering(pipeline, T0, 8)
    assert pipeline.on_joint_state(winch(1, T0 + 1.7, 20.1, received=T0 + 0.2)) is None
    assert "stamp ahead of the other winches: cable_2" in pipeline.stats.last_rejection
    assert all(o.solution.ok for o in lowering(pipeline, T0 + 0.2, 40))


def test_without_a_clock_a_kept_far_future_reading_does_not_block_its_cable(plant):
    """Offline, with no arrival time: the other winches show the kept reading implausible; the cable recovers."""
    merger = CableLengthMerger(0.5)
    merger.add(JointSample(T0 + 1e6, ["cable_1"], [20.0]))
    for cable in range(1, 4):
        merger.add(JointSample(T0, [CABLE_NAMES[cable]], [20.0]))
    result = merger.add(JointSample(T0 + 0.05, ["cable_1"], [20.0]))
    assert result.accepted == [0] and not result.rejected
    lengths, why = merger.complete(T0 + 0.05)
    assert lengths is not None, why


def test_the_same_in_replay_a_bad_stamp_costs_one_message(plant):
    """The replay feed gives the log time as the arrival time: the same window applies."""
    from cable_winch_monitor.messages import fields
    from cable_winch_monitor.replay.windows import WindowScheduler

    def item(stamp: float, log_time: float, lengths):
        header = SimpleNamespace(stamp=SimpleNamespace(sec=int(stamp), nanosec=int(round((stamp % 1) * 1e9))))
        message = SimpleNamespace(header=header, name=list(CABLE_NAMES), position=list(lengths), velocity=[], effort=[])
        return SimpleNamespace(topic="/winch/joint_states", msgtype=fields.JOINT_STATE, message=message,
                               log_time=int(log_time * 1e9))

    items = [item(T0 + 0.1 * k, T0 + 0.1 * k + 0.01, [20.0 + 0.01 * k] * 4) for k in range(300)]
    items[50] = item(2 ** 31 - 1, T0 + 5.01, [20.5] * 4)
    for batched in (True, False):
        scheduler = WindowScheduler(plant, batched=batched, window=64)
        results = [result for _, result in scheduler.run(items)]
        assert sum(r is not None and r.output.solution.ok for r in results) == 299
        assert dict(scheduler.monitor.stats.rejected) == {"/winch/joint_states: stamp ahead of the clock": 1}


@pytest.mark.parametrize("velocity", [50.0, 1e300, float("inf")])
def test_implausible_payout_speeds_are_refused(plant, velocity):
    pipeline = MonitorPipeline(plant)
    assert pipeline.on_joint_state(JointSample(1.0, list(CABLE_NAMES), [20.0] * 4, [velocity, 0, 0, 0])) is None
    assert "bad payout speed: cable_1" in pipeline.stats.last_rejection


@pytest.mark.parametrize("length", [1e9, 1e300, 3000.1])
def test_lengths_beyond_the_maximum_payout_are_refused(plant, length):
    pipeline = MonitorPipeline(plant)
    assert pipeline.on_joint_state(JointSample(1.0, list(CABLE_NAMES), [length, 20.0, 20.0, 20.0])) is None
    assert "beyond the maximum payout 3000 m" in pipeline.stats.last_rejection


@pytest.mark.parametrize("quaternion", [(1e300, 0.0, 0.0, 1.0), (0.0, 0.0, 0.0, 2.0), (np.nan, 0, 0, 1)])
def test_absurd_orientations_are_refused(plant, quaternion):
    pipeline = MonitorPipeline(plant)
    pipeline.on_joint_state(merged(1.0, [20.0] * 4, received=1.0))
    x, y, z, w = quaternion
    imu = SimpleNamespace(orientation=SimpleNamespace(x=x, y=y, z=z, w=w))
    assert pipeline.on_measurement("/platform/imu", 1.01, imu) is None
    assert "orientation is not a unit quaternion" in pipeline.stats.last_rejection


@pytest.mark.parametrize("xyz", [(1e300, 0.0, -30.0), (0.0, 0.0, -1e300), (float("inf"), 0.0, -30.0)])
def test_absurd_positions_are_refused(plant, xyz):
    pipeline = MonitorPipeline(plant)
    pipeline.on_joint_state(merged(1.0, [20.0] * 4, received=1.0))
    x, y, z = xyz
    assert pipeline.on_measurement("/platform/position", 1.01, SimpleNamespace(point=SimpleNamespace(x=x, y=y, z=z))) is None
    assert "bad measurement: position" in pipeline.stats.last_rejection


def test_limits_come_from_the_plant_file(plant):
    limited = plant.with_changes(max_payout=100.0, max_payout_speed=1.0)
    merger = CableLengthMerger(0.5, limits=InputLimits(limited.max_payout, limited.max_payout_speed))
    assert "beyond the maximum payout 100 m" in merger.add(JointSample(1.0, ["cable_1"], [101.0])).rejected
    assert "at most 1 m/s" in merger.add(JointSample(1.0, ["cable_1"], [99.0], [1.5])).rejected
    assert merger.add(JointSample(1.0, ["cable_1"], [99.0], [0.9])).accepted == [0]


def test_a_constant_clock_offset_is_judged_from_and_bad_stamps_are_still_refused(plant):
    """Stamps 30 s behind their arrival throughout: within a window shifted by that offset; a far-future
    stamp among them is refused all the same."""
    pipeline = MonitorPipeline(plant, stamp_window=StampWindow(offset=30.0))
    outputs = [pipeline.on_joint_state(merged(T0 + 0.1 * k, [20.0 + 0.01 * k] * 4, received=T0 + 30.0 + 0.1 * k))
               for k in range(100)]
    assert all(o is not None and o.solution.ok for o in outputs) and not pipeline.stats.rejected
    assert pipeline.on_joint_state(merged(T0 + 1e6, [21.0] * 4, received=T0 + 40.0)) is None
    assert pipeline.on_joint_state(merged(T0 + 10.0, [21.0] * 4, received=T0 + 52.0)) is None  # 12 s late
    assert set(pipeline.stats.rejected) == {"/winch/joint_states: stamp ahead of the clock",
                                            "/winch/joint_states: stamp behind the clock"}


def test_a_recording_whose_stamps_lie_30_s_behind_its_log_times_replays_with_a_note(tmp_path):
    """Every winch message was refused as "stamp behind the clock", and the replay exited 0 with nothing solved."""
    from simbags import assert_clean, run_cli

    from cable_winch_monitor.bagio.reader import BagReader
    from cable_winch_monitor.bagio.writer import BagWriter
    from cable_winch_monitor.paths import demo_bag

    late = tmp_path / "late"
    with BagWriter(late) as writer:
        for item in BagReader(demo_bag()):
            writer.write_raw(item.topic, item.msgtype, item.log_time + 30 * 10 ** 9, item.data)
    result = run_cli("replay", late, "--out", tmp_path / "out", "--quiet")
    assert_clean(result, 0)
    assert "note: the winches' header stamps lie 30.00" in result.stdout
    assert "s behind the log times throughout the first 100 winch messages" in result.stdout
    assert "samples: 2049 (solved 2049, solver failures 0)" in result.stdout and "stamp behind" not in result.stdout
