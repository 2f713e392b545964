"""Replay's read-ahead feed: every message comes out once, in order, with what the per-message pipeline makes of it."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cable_winch_monitor import channels
from cable_winch_monitor.bench.plants import realistic
from cable_winch_monitor.messages import fields, records
from cable_winch_monitor.model.plantfile.plant import CABLE_NAMES
from cable_winch_monitor.monitor.judged import MonitorOutput
from cable_winch_monitor.monitor.pipeline import MonitorPipeline
from cable_winch_monitor.replay.stages import Encoded, Measured
from cable_winch_monitor.replay.windows import FIRST_WINDOW, Failed, WindowScheduler, window_sizes


def header(t: float) -> SimpleNamespace:
    sec = int(t)
    return SimpleNamespace(stamp=SimpleNamespace(sec=sec, nanosec=int(round((t - sec) * 1e9))), frame_id="shaft")


def stream(count: int) -> list[SimpleNamespace]:
    """A lowering reported winch by winch (so samples need merging), with an inclinometer, a depth
    gauge, a stamp that goes backwards and a message the pipeline cannot read (no `name`)."""
    items = []
    for k in range(count):
        t = 1.0 + 0.1 * k
        lengths = 30.0 + 0.05 * k + np.array([0.3, 0.1, 0.5, 0.2]) * np.sin(0.01 * k)
        for i, name in enumerate(CABLE_NAMES):
            msg = SimpleNamespace(header=header(t + 0.01 * i), name=[name], position=[lengths[i]], velocity=[0.5],
                                  effort=[float("nan")])
            items.append(SimpleNamespace(topic=f"/winch_{i + 1}/joint_states", msgtype=channels.JOINT_STATE, message=msg))
        if k % 3 == 0:
            q = SimpleNamespace(x=0.001, y=-0.002, z=0.0, w=1.0)
            items.append(SimpleNamespace(topic="/platform/imu", msgtype=channels.IMU,
                                         message=SimpleNamespace(header=header(t + 0.05), orientation=q)))
        if k % 7 == 0:
            point = SimpleNamespace(x=float("nan"), y=float("nan"), z=-30.0 - 0.05 * k)
            items.append(SimpleNamespace(topic="/platform/position", msgtype=channels.POINT,
                                         message=SimpleNamespace(header=header(t + 0.06), point=point)))
    broken = SimpleNamespace(header=header(5.0), position=[1.0])  # no `name`: reading it raises
    items.insert(40, SimpleNamespace(topic="/winch/joint_states", msgtype=channels.JOINT_STATE, message=broken))
    backwards = SimpleNamespace(header=header(1.0), name=["cable_1"], position=[30.0], velocity=[], effort=[])
    items.insert(90, SimpleNamespace(topic="/winch_1/joint_states", msgtype=channels.JOINT_STATE, message=backwards))
    for item in items:  # recorded 5 ms after its stamp, as a bag's messages are
        stamp = item.message.header.stamp
        item.log_time = stamp.sec * 1_000_000_000 + stamp.nanosec + 5_000_000
    return items


def one_at_a_time(pipeline: MonitorPipeline, item: SimpleNamespace):
    """What the live node does with each message."""
    msg = item.message
    if item.msgtype == channels.JOINT_STATE:
        return pipeline.on_joint_state(fields.joint_sample(msg, item.topic)._replace(received=item.log_time * 1e-9))
    return pipeline.on_measurement(item.topic, fields.seconds(msg.header.stamp), msg)


@pytest.mark.parametrize("batched", [True, False])
@pytest.mark.parametrize("kind", ["rigid", "realistic"])
def test_every_message_once_in_order_with_the_node_pipelines_result(plant, batched, kind):
    """On the rigid plant and on elastic ropes with their weight and sheave friction (batched too)."""
    plant = realistic(plant) if kind == "realistic" else plant
    # the lengths taken as exact: this stream's inclinometer does not agree with its lengths (the fused
    # paths are compared in test_monitor_fusion, on sensors that read a root-found truth)
    plant = plant.with_changes(noise={k: v for k, v in plant.noise.items() if k != "length"})
    items = stream(300)
    reference = MonitorPipeline(plant)
    expected = []
    for item in items:
        try:
            expected.append(one_at_a_time(reference, item))
        except Exception as error:
            expected.append(error)
    scheduler = WindowScheduler(plant, batched=batched, window=64)  # windows end between a sample's messages
    assert scheduler.batched == batched
    ran = list(scheduler.run(items))
    for item, got in ran:  # a sensor message's residuals: encoded with the window's others, as the node one at a time
        if isinstance(got, Measured):
            assert got.records == records.residual_records(fields.message_stamp(item.message, item.log_time),
                                                           got.residuals)
    results = [(item, got.output if isinstance(got, Encoded) else got.residuals if isinstance(got, Measured) else got)
               for item, got in ran]
    assert [item for item, _ in results] == items
    solved = 0
    for (_, got), want in zip(results, expected):
        if isinstance(want, Exception):  # what the node counts as a callback error
            assert got == Failed(f"{type(want).__name__}: {want}")
            continue
        assert type(got) is type(want)
        if isinstance(want, MonitorOutput):
            solved += 1
            assert got.stamp == want.stamp and got.solution.taut_set == want.solution.taut_set
            np.testing.assert_allclose(got.solution.points_b, want.solution.points_b, atol=1e-9)
            np.testing.assert_allclose(got.solution.tensions, want.solution.tensions, atol=1e-3)
            assert got.alarm.level == want.alarm.level and got.alarm.reason == want.alarm.reason
        elif want is not None:  # residuals of an inclinometer or depth reading
            assert got.channels == want.channels
            np.testing.assert_allclose(got.values, want.values, atol=1e-9)
    assert solved > 250 and sum(isinstance(w, AttributeError) for w in expected) == 1  # the unreadable message
    stats = scheduler.monitor.stats
    assert stats.messages == reference.stats.messages and stats.used == reference.stats.used
    assert stats.rejected == reference.stats.rejected and stats.states == reference.stats.states
    assert sum(stats.rejected.values()) >= 1  # the stamp that went backwards


@settings(max_examples=200, deadline=None)
@given(full=st.integers(1, 5000), expected=st.integers(0, 50_000))
def test_windows_grow_from_the_first_to_the_full_size_and_shrink_towards_the_end(full, expected):
    """With a second process: the first window small (the second process starts sooner), the full size in
    between, and the last ones small again (the replay waits less for them); never above the full size nor
    below the first."""
    least = min(FIRST_WINDOW, full)
    sizes, taken = [], 0
    generator = window_sizes(full, expected)
    while taken < max(expected, 10 * full):
        sizes.append(next(generator))
        taken += sizes[-1]
    assert sizes[0] == least and all(least <= size <= full for size in sizes)
    if expected >= 16 * full:  # long enough to reach the full size
        assert full in sizes
    covering = next(k for k in range(len(sizes)) if sum(sizes[:k + 1]) >= expected) if expected else None
    if covering is not None and expected >= 4 * full:
        assert sizes[covering] <= max(full // 2, least)  # the bag's last window is at most half the full one
