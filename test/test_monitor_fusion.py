"""The monitor publishes the fused estimate: lengths, load pins, inclinometer and depth, each with its noise.

Truth is computed without the package's solvers (`root_truth`: force and moment balance
solved by root finding): a rigid lowering at 20-60 m whose lag events slacken a rope and
move the load share, sensed as the plant's sensors sense it -- encoders 1 mm, load pins
150 N, inclinometer 0.01 deg stamped 30-40 ms after the winches, depth gauge 5 mm at 2 Hz.
Live (one message at a time) and replay (a window at a time, batched) give the same
outputs; a load pin that goes wrong is left out after the gate's hold time.
"""
from __future__ import annotations

import os
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.special import chdtri

from cable_winch_monitor import ahead, channels
from cable_winch_monitor.bagio import fields, records
from cable_winch_monitor.lookahead import LookaheadPipeline
from cable_winch_monitor.model.gate import DEFAULT_PROBABILITY, DEFAULT_THRESHOLDS, chi_square_threshold
from cable_winch_monitor.model.plant import CABLE_NAMES
from cable_winch_monitor.model.result import check_physics
from cable_winch_monitor.monitor.pipeline import MonitorOutput, MonitorPipeline
from cable_winch_monitor.monitor.sensors import sensors_used
from fusionbags import NOISE, RATE, elastic_lowering_truths, header, lowering_truths, noisy, sensed
from root_truth import weak_mode_truth

def live(pipeline: MonitorPipeline, items) -> list[MonitorOutput]:
    """What the node does with each message, the samples it publishes."""
    out = []
    for entry in items:
        msg = entry.message
        if entry.msgtype == channels.JOINT_STATE:
            output = pipeline.on_joint_state(fields.joint_sample(msg, entry.topic))
            if output is not None:
                out.append(output)
        else:
            pipeline.on_measurement(entry.topic, fields.seconds(msg.header.stamp), msg)
    return out


def replayed(pipeline: LookaheadPipeline, items) -> list[MonitorOutput]:
    return [r for _, r in pipeline.run(items) if isinstance(r, MonitorOutput)]


@pytest.fixture(scope="module")
def lowering(plant):
    truths = lowering_truths(plant, 240, seed=5)
    return truths, sensed(truths, seed=6)


def test_replay_publishes_the_fused_tensions_and_equals_the_live_node(plant, lowering):
    truths, items = lowering
    fused = noisy(plant)
    outputs = replayed(LookaheadPipeline(fused, window=100), items)
    assert len(outputs) == len(truths)
    assert len({t.tensions.astype(bool).tobytes() for t in truths}) >= 3  # the lag events switch the taut set
    errors = np.array([np.abs(o.solution.tensions - t.tensions).max() for o, t in zip(outputs, truths)])
    assert np.mean(errors <= 3.0 * NOISE["tension"]) >= 0.995
    for output in outputs:
        assert output.solution.ok and output.estimate.fused
        assert check_physics(fused, output.solution).passes()  # balance, tensions >= 0, slack not overstretched
    for output in outputs[1:]:  # the inclinometer's first reading comes after the first sample
        assert {*channels.TENSION_CHANNELS, "/platform/imu"} <= set(sensors_used(output.estimate))
    assert sum("/platform/position" in sensors_used(o.estimate) for o in outputs) > 0.15 * len(outputs)
    assert max(np.abs(o.estimate.corrections_sigma).max() for o in outputs) < 6.0
    # poses no worse than the lengths taken as exact
    exact = replayed(LookaheadPipeline(plant.with_changes(noise={**NOISE, "length": float("nan")})), items)
    pose_error = [np.abs(o.solution.position - t.position).max() for o, t in zip(outputs, truths)]
    exact_error = [np.abs(o.solution.position - t.position).max() for o, t in zip(exact, truths)]
    assert np.percentile(pose_error, 95) <= np.percentile(exact_error, 95) + 1e-4
    exact_tension = np.array([np.abs(o.solution.tensions - t.tensions).max() for o, t in zip(exact, truths)])
    assert np.mean(exact_tension > 3.0 * NOISE["tension"]) > 0.3  # the lengths alone miss the share
    # the node, one message at a time, warm-started
    node = live(MonitorPipeline(fused), items)
    for got, want in zip(outputs, node):
        assert got.stamp == want.stamp and got.solution.taut_set == want.solution.taut_set
        assert np.abs(got.solution.tensions - want.solution.tensions).max() < 1.0
        assert np.abs(got.solution.points_b - want.solution.points_b).max() < 1e-6
        assert set(got.estimate.used) == set(want.estimate.used) and got.alarm.level == want.alarm.level


def test_a_pin_that_goes_wrong_is_left_out_after_the_hold_time(plant, lowering):
    truths, _ = lowering
    truths = truths[:120]
    items = sensed(truths, seed=7, pin_fault=(1, 50, 5e3))
    hold = 0.5
    node = live(MonitorPipeline(noisy(plant), gate_hold=hold), items)
    refused_at = next(k for k, o in enumerate(node) if o.refused)
    assert node[refused_at].refused == ("tension_cable_2",)
    assert 50 + hold * RATE <= refused_at <= 50 + hold * RATE + 3
    for output, truth in zip(node[refused_at + 1:], truths[refused_at + 1:]):  # left out from the next sample
        assert "tension_cable_2" not in output.estimate.used and "tension_cable_1" in output.estimate.used
        assert np.abs(output.solution.tensions - truth.tensions).max() <= 4.0 * NOISE["tension"]
    replay = replayed(LookaheadPipeline(noisy(plant), window=64, gate_hold=hold), items)  # the gate closes mid-window
    assert [o.refused for o in replay] == [o.refused for o in node]
    for got, want in zip(replay, node):
        assert set(got.estimate.used) == set(want.estimate.used)
        assert np.abs(got.solution.tensions - want.solution.tensions).max() < 1.0


def test_a_second_process_estimating_ahead_gives_the_same_outputs(plant, lowering, monkeypatch, tmp_path):
    """Replay's second process estimates each window while the one before is published, under the gates
    of that moment; where a gate closes in between, the window is estimated again here. The outputs
    are those of one process, to the bit, and the files it handed its results over in are gone."""
    monkeypatch.setattr(ahead, "SPOOL", str(tmp_path))
    left_over = []
    close = ahead.AheadEstimator.close

    def closing(self):
        self.pool.shutdown(wait=True)  # every chunk handed over
        left_over.extend(os.listdir(self.spool))
        close(self)

    monkeypatch.setattr(ahead.AheadEstimator, "close", closing)
    truths, _ = lowering
    items = sensed(truths[:120], seed=7, pin_fault=(1, 50, 5e3))
    taken = []
    presolve = LookaheadPipeline._presolve

    def spy(self, samples, speculated=None):
        taken.append(speculated is not None)
        return presolve(self, samples, speculated)

    monkeypatch.setattr(LookaheadPipeline, "_presolve", spy)
    one = replayed(LookaheadPipeline(noisy(plant), window=64, gate_hold=0.5), items)
    assert not any(taken)
    taken.clear()
    pipeline = LookaheadPipeline(noisy(plant), window=64, gate_hold=0.5, second_process=True)
    run = list(pipeline.run_published(items))
    two = [r for _, r, _ in run if isinstance(r, MonitorOutput)]
    assert pipeline.ahead is None and not any(tmp_path.iterdir())  # stopped with the replay, its spool removed
    assert left_over == []  # the results of chunks not taken (the gate closed) were removed as they came
    encoded = [(fields.stamp_of(item.message), r, published) for item, r, published in run if published is not None]
    assert len(encoded) >= len(two) // 3  # the records of the windows the gate left alone come from there
    for stamp, output, published in encoded:
        assert published.solution == records.solution_records(stamp, output.solution, output.estimate)
        if published.alarm == (output.alarm.level, output.alarm.reason):
            assert published.alarm_record == records.alarm_record(stamp, output.alarm)
    assert sum(taken) >= 2 and not all(taken)  # the windows before the gate closed from there, those merged ahead of it not
    assert [o.refused for o in two] == [o.refused for o in one] and any(o.refused for o in one)
    for got, want in zip(two, one):
        assert got.stamp == want.stamp and got.estimate.used == want.estimate.used
        assert got.solution.tensions.tobytes() == want.solution.tensions.tobytes()
        assert got.solution.points_b.tobytes() == want.solution.points_b.tobytes()
        assert got.alarm.level == want.alarm.level and got.alarm.reason == want.alarm.reason
        assert got.clearance.value == want.clearance.value


def test_a_second_process_that_cannot_hand_over_its_results_leaves_them_to_the_replay(plant, lowering, monkeypatch,
                                                                                      tmp_path):
    """Where the worker cannot write a chunk's results (its spool is not a directory: a full or missing
    /dev/shm), the replaying process estimates the chunk itself: the same outputs, none from there."""
    spooled = ahead.AheadEstimator.__init__

    def unwritable(self, *args):
        spooled(self, *args)
        os.rmdir(self.spool)
        self.spool = str(tmp_path / "not-a-directory")
        open(self.spool, "w").close()

    monkeypatch.setattr(ahead.AheadEstimator, "__init__", unwritable)
    items = sensed(lowering[0][:60], seed=11)
    one = replayed(LookaheadPipeline(noisy(plant), window=64), items)
    run = list(LookaheadPipeline(noisy(plant), window=64, second_process=True).run_published(items))
    two = [r for _, r, _ in run if isinstance(r, MonitorOutput)]
    assert all(published is None for _, _, published in run)
    assert len(two) == len(one) > 0
    for got, want in zip(two, one):
        assert got.solution.tensions.tobytes() == want.solution.tensions.tobytes()
        assert got.solution.points_b.tobytes() == want.solution.points_b.tobytes()


def test_pins_left_out_are_taken_back_once_they_agree_again(plant):
    """Stiff elastic ropes at 20 m (EA 7.5e7 N: a millimetre of an encoder is 3.75 kN of tension), all
    four pins 5 kN high for 1.5 s (a shared amplifier fault), then right again. Left out, each pin is
    judged by what taking it back in costs the estimate, not by its reading against the tensions
    the encoders alone predict (tens of sigma off), against which it would never be taken back."""
    ea, weight = 7.5e7, 60.0
    truths = elastic_lowering_truths(plant, 160, seed=9, start=20.0, speed=0.2, ea=ea, weight=weight)

    def pins(truth):  # the pins at the head sheaves feel the rope below them too
        drop = plant.anchors[:, 2] - (truth.position + plant.attachments @ truth.rotation.T)[:, 2]
        return truth.tensions + weight * drop

    items = sensed(truths, seed=8, pins=pins, pin_fault=([0, 1, 2, 3], 30, 5e3), fault_until=60)
    elastic = noisy(plant).with_changes(effects={"rope_elasticity": {"EA": ea}, "rope_weight": {"w": weight}})
    hold = 0.5
    node = live(MonitorPipeline(elastic, gate_hold=hold), items)
    pins_ = set(channels.TENSION_CHANNELS)
    refused_at = next(k for k, o in enumerate(node) if o.refused)
    assert set(node[refused_at].refused) == pins_ and refused_at <= 30 + hold * RATE + 3
    back_at = next(k for k, o in enumerate(node) if k > refused_at and not o.refused)
    # each of the four is tried once per hold time (TRIALS_PER_HOLD = 4, in turn) and must pass for a hold time
    assert 60 + hold * RATE <= back_at <= 60 + 2 * hold * RATE + 3
    for output, truth in zip(node[back_at + 1:], truths[back_at + 1:]):
        assert pins_ <= set(output.estimate.used) and not output.refused
        assert np.abs(output.solution.tensions - truth.tensions).max() <= 4.0 * NOISE["tension"]
    replay = replayed(LookaheadPipeline(elastic, window=64, gate_hold=hold), items)
    assert [o.refused for o in replay] == [o.refused for o in node]


def test_equal_lengths_with_pins_give_tensions_independent_of_history(plant):
    truth = weak_mode_truth(plant, 300.0, np.zeros(3), 12e3)
    np.testing.assert_allclose(truth.lengths, 300.0, atol=1e-9)
    tensions = []
    for history in ([300.02, 300.0, 300.01, 300.0], [300.0, 300.02, 300.0, 300.01], [299.0, 299.0, 299.0, 299.0]):
        pipeline = MonitorPipeline(noisy(plant))
        for k in range(3):
            t = 10.0 + 0.1 * k
            pipeline.on_joint_state(fields.joint_sample(SimpleNamespace(
                header=header(t), name=list(CABLE_NAMES), position=history, velocity=[0.0] * 4,
                effort=[float("nan")] * 4), "/winch/joint_states"))
        output = pipeline.on_joint_state(fields.joint_sample(SimpleNamespace(
            header=header(11.0), name=list(CABLE_NAMES), position=truth.lengths.tolist(), velocity=[0.0] * 4,
            effort=(truth.tensions + np.array([120.0, -80.0, 40.0, -150.0])).tolist()), "/winch/joint_states"))
        assert output.solution.taut_set == (1, 2, 3, 4) and check_physics(plant, output.solution).passes()
        tensions.append(output.solution.tensions)
    tensions = np.array(tensions)
    assert np.ptp(tensions, axis=0).max() < 1.0
    assert np.abs(tensions[0] - truth.tensions).max() <= 3.0 * NOISE["tension"]


def test_tension_message_says_what_the_estimate_used(plant, lowering):
    truths, items = lowering
    output = live(MonitorPipeline(noisy(plant)), items[:40])[-1]
    values = fields.tension_distribution((100, 0), output.solution, output.estimate)
    assert values["sensors_used"][:4] == list(channels.TENSION_CHANNELS)
    assert "/platform/imu" in values["sensors_used"]
    np.testing.assert_allclose(values["length_corrections_sigma"], output.estimate.corrections / NOISE["length"])
    exact = live(MonitorPipeline(plant.with_changes(noise={**NOISE, "length": float("nan")})), items[:40])[-1]
    values = fields.tension_distribution((100, 0), exact.solution, exact.estimate)
    assert values["sensors_used"] == [] and values["length_corrections_sigma"] == []


def test_default_gate_thresholds_are_scipys_chi_square_quantiles():
    """The gate's thresholds at the default probability are kept as numbers (no scipy import in a replay):
    they must be scipy's quantiles to the bit, and other probabilities still come from scipy."""
    for dof, threshold in enumerate(DEFAULT_THRESHOLDS, 1):
        assert threshold == float(chdtri(dof, 1.0 - DEFAULT_PROBABILITY))
    assert chi_square_threshold(9) == float(chdtri(9, 1.0 - DEFAULT_PROBABILITY))
    assert chi_square_threshold(2, 0.99) == pytest.approx(-2.0 * np.log(0.01))  # two channels: exponential
