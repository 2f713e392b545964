"""The monitor publishes the fused estimate: lengths, load pins, inclinometer and depth, each with its noise.

Truth is computed without the package's solvers (`root_truth`: force and moment balance
solved by root finding): a rigid lowering at 20-60 m whose lag events slacken a rope and
move the load share, sensed as the plant's sensors sense it -- encoders 1 mm, load pins
150 N, inclinometer 0.01 deg stamped 30-40 ms after the winches, depth gauge 5 mm at 2 Hz.
Live (one message at a time) and replay (a window at a time, batched) give the same
outputs; a load pin that goes wrong is left out as soon as it contradicts the other sensors.
"""
from __future__ import annotations

import dataclasses
import os
from types import SimpleNamespace

import numpy as np
import pytest
from fusionbags import NOISE, header, lowering_truths, noisy, sensed
from root_truth import weak_mode_truth
from scipy.special import chdtri
from simbags import simulated

from cable_winch_monitor import channels
from cable_winch_monitor.bagio.reader import BagReader
from cable_winch_monitor.channels import BUILTIN_CHANNELS
from cable_winch_monitor.messages import fields
from cable_winch_monitor.model.estimator import DEFAULT_PROBABILITY, DEFAULT_THRESHOLDS, chi_square_threshold
from cable_winch_monitor.model.plantfile.plant import CABLE_NAMES
from cable_winch_monitor.model.statics.result import check_physics
from cable_winch_monitor.monitor import estimator
from cable_winch_monitor.monitor.judged import MonitorOutput
from cable_winch_monitor.monitor.pipeline import MonitorPipeline
from cable_winch_monitor.replay import second_process, worker
from cable_winch_monitor.replay.stages import Encoded
from cable_winch_monitor.replay.windows import WindowScheduler


def live(pipeline: MonitorPipeline, items, received: bool = False) -> list[MonitorOutput]:
    """What the node does with each message, the samples it publishes (`received`: each winch message
    arriving at its log time, as replay takes it)."""
    out = []
    for entry in items:
        msg = entry.message
        if entry.msgtype == channels.JOINT_STATE:
            arrival = entry.log_time * 1e-9 if received else float("nan")
            output = pipeline.on_joint_state(fields.joint_sample(msg, entry.topic, arrival))
            if output is not None:
                out.append(output)
        else:
            pipeline.on_measurement(entry.topic, fields.seconds(msg.header.stamp), msg)
    return out


def replayed(pipeline: WindowScheduler, items) -> list[MonitorOutput]:
    """What replay makes of the items in one process: each complete sample's outputs."""
    return [r.output for _, r in pipeline.run(items) if isinstance(r, Encoded)]


@pytest.fixture(scope="module")
def lowering(plant):
    truths = lowering_truths(plant, 800, seed=5)
    return truths, sensed(truths, seed=6)


def assert_same(got: list[MonitorOutput], want: list[MonitorOutput]) -> None:
    """The same state on every sample, to the estimator's convergence: taut set, tensions, points, sensors."""
    assert len(got) == len(want)
    for a, b in zip(got, want):
        assert a.stamp == b.stamp and a.solution.taut_set == b.solution.taut_set
        assert np.abs(a.solution.tensions - b.solution.tensions).max() < 1.0
        assert np.abs(a.solution.points_b - b.solution.points_b).max() < 1e-6
        assert set(a.estimate.used) == set(b.estimate.used) and a.alarm.level == b.alarm.level
        assert a.refused == b.refused


def test_replay_publishes_the_fused_tensions_and_equals_the_live_node(plant, lowering):
    truths, items = lowering
    fused = noisy(plant)
    outputs = replayed(WindowScheduler(fused, window=100), items)
    assert len(outputs) == len(truths)
    assert len({t.tensions.astype(bool).tobytes() for t in truths}) >= 3  # the lag events switch the taut set
    errors = np.array([np.abs(o.solution.tensions - t.tensions).max() for o, t in zip(outputs, truths)])
    assert np.mean(errors <= 3.0 * NOISE["tension"]) >= 0.995
    for output in outputs:
        assert output.solution.ok and output.estimate.fused
        assert check_physics(fused, output.solution).passes()  # balance, tensions >= 0, slack not overstretched
        assert not output.refused  # no sensor contradicts the others
    for output in outputs[1:]:  # the inclinometer's first reading comes after the first sample
        assert {*channels.TENSION_CHANNELS, "/platform/imu"} <= set(BUILTIN_CHANNELS.sensors_used(output.estimate.used))
    assert sum("/platform/position" in BUILTIN_CHANNELS.sensors_used(o.estimate.used) for o in outputs) > 0.15 * len(outputs)
    # once the model's error is learnt (its first update windows: a model error that grows with the payout
    # is learnt from a few metres of it), poses as good as the lengths taken as exact
    exact = replayed(WindowScheduler(plant.with_changes(noise={**NOISE, "length": float("nan")})), items)
    learnt = slice(500, None)
    pose_error = [np.abs(o.solution.position - t.position).max() for o, t in zip(outputs[learnt], truths[learnt])]
    exact_error = [np.abs(o.solution.position - t.position).max() for o, t in zip(exact[learnt], truths[learnt])]
    assert np.percentile(pose_error, 95) <= max(np.percentile(exact_error, 95), 2e-3)
    assert outputs[-1].model.length_sigma.max() < 1.5 * NOISE["length"]  # the plant file is right: nothing to add
    exact_tension = np.array([np.abs(o.solution.tensions - t.tensions).max() for o, t in zip(exact, truths)])
    assert np.mean(exact_tension > 3.0 * NOISE["tension"]) > 0.3  # the lengths alone miss the share
    assert_same(live(MonitorPipeline(fused), items), outputs)  # the node, one message at a time


@pytest.fixture(scope="module")
def winch_by_winch(tmp_path_factory: pytest.TempPathFactory) -> list:
    """20 s of every channel, each winch on its own topic, its messages logged as they come."""
    bag = simulated(tmp_path_factory.mktemp("winch_by_winch"), "all_channels", "duration=20")
    return list(BagReader(bag, fields.input_topics()))


def test_samples_made_winch_by_winch_are_estimated_as_the_node_estimates_them_to_the_bit(plant, winch_by_winch):
    """Every channel, each winch on its own topic, its messages logged as they come: a sample is made at each
    winch's message, so the samples are not quite in stamp order. The inclinometer, carried to each sample's
    stamp by the model's tilt rate, takes the predictions of the samples up to it (not those stamped before
    it, which would take a later sample's in replay's windows but not in the node), so the node, one
    message at a time, and replay, in windows that end anywhere, give every sample the same bits."""
    items = winch_by_winch
    node = live(MonitorPipeline(plant), items, received=True)
    stamps = np.array([o.stamp for o in node])
    assert len(node) > 700 and np.sum(np.diff(stamps) < 0) > 20  # samples out of stamp order
    assert all(o.estimate.fused and "/platform/imu" in BUILTIN_CHANNELS.sensors_used(o.estimate.used) for o in node[10:])
    for window in (97, 2000):
        replay = replayed(WindowScheduler(plant, window=window), items)
        assert [o.stamp for o in replay] == stamps.tolist()
        for a, b in zip(replay, node):
            assert a.solution.tensions.tobytes() == b.solution.tensions.tobytes()
            assert a.solution.points_b.tobytes() == b.solution.points_b.tobytes()


def test_a_sample_stamped_just_before_an_update_window_it_follows_stays_in_the_open_window(plant, winch_by_winch,
                                                                                          monkeypatch):
    """Each winch on its own topic: where a sample is stamped a little before the one before it, across the
    start of an update window, it is estimated in the window open already, not in the one closed before
    (which would close the open one after a sample and start the model error's update over); the node and
    replay alike, to the bit."""
    items = winch_by_winch
    stamps = [o.stamp for o in live(MonitorPipeline(plant), items, received=True)]
    k = next(k for k in range(200, len(stamps) - 1) if stamps[k + 1] < stamps[k])
    period = (stamps[k] + stamps[k + 1]) / 2.0 - stamps[0]  # a window starts between the two
    edged = plant.with_changes(model_error=dataclasses.replace(plant.model_error, period=period))
    closed = []
    close = estimator.MonitorEstimator._close
    monkeypatch.setattr(estimator.MonitorEstimator, "_close",
                        lambda self, index: closed.append((self.window.index, index)) or close(self, index))
    node = live(MonitorPipeline(edged), items, received=True)
    assert closed and all(after > before for before, after in closed)
    replay = replayed(WindowScheduler(edged, window=97), items)
    assert [o.stamp for o in replay] == stamps
    for a, b in zip(replay, node):
        assert a.solution.tensions.tobytes() == b.solution.tensions.tobytes()


def test_sensor_messages_logged_late_are_fused_as_if_logged_in_order(plant, lowering):
    """A recorder logs each message when it came: inclinometer and depth messages logged up to 85 ms late, after
    winch messages stamped after them (the inclinometer is stamped 30-40 ms after the winches). Replay waits
    for them as the node does, past the end of its window where it must, and gives every sample the state of
    the recording logged in order."""
    _, items = lowering
    rng = np.random.default_rng(11)
    late = [SimpleNamespace(**{**vars(entry), "log_time": entry.log_time + (
        0 if entry.msgtype == channels.JOINT_STATE else int(rng.uniform(0.0, 0.085) * 1e9))}) for entry in items]
    late.sort(key=lambda entry: entry.log_time)
    overtaken = sum(a.msgtype != channels.JOINT_STATE and b.msgtype == channels.JOINT_STATE
                    and fields.seconds(b.message.header.stamp) >= fields.seconds(a.message.header.stamp)
                    for k, a in enumerate(late) for b in late[max(k - 4, 0):k])  # logged before a, stamped after
    fused = noisy(plant)
    assert overtaken > 50
    # windows of 25 messages: at many of their ends a sample waits, and the window goes on past it
    assert_same(replayed(WindowScheduler(fused, window=25), late), replayed(WindowScheduler(fused, window=25), items))


def test_a_pin_that_goes_wrong_is_left_out_from_its_first_wrong_reading(plant, lowering):
    """A load pin 5 kN off from sample 50 contradicts the other sensors: rejected at each sample from its
    first wrong reading (the others then agree), left out of the update windows after, and named; the
    tensions stay within 4 sigma of the truth. Replay, a window at a time, gives the node's states."""
    truths, _ = lowering
    truths = truths[:300]
    items = sensed(truths, seed=7, pin_fault=(1, 50, 5e3))
    node = live(MonitorPipeline(noisy(plant)), items)
    assert not any(o.refused for o in node[:50])
    for output, truth in zip(node[50:], truths[50:]):
        assert output.refused == ("tension_cable_2",)
        assert "tension_cable_2" not in output.estimate.used and "tension_cable_1" in output.estimate.used
        assert output.model.faults["tension_cable_2"] == "contradicts the other sensors"
        assert np.abs(output.solution.tensions - truth.tensions).max() <= 4.0 * NOISE["tension"]
    assert any(o.model.left_out == ("tension_cable_2",) for o in node)  # left out of a later window
    assert_same(replayed(WindowScheduler(noisy(plant), window=64), items), node)


def test_the_sensor_rejected_at_the_sample_before_is_tried_alone_first_with_the_same_outputs(plant, lowering,
                                                                                          monkeypatch):
    """A suspect sample is estimated again without the sensor rejected at the sample before, alone, first: where
    the others then agree that sensor is the one rejected whatever leaving out each of the others would give,
    so the outputs are those of leaving out every sensor in turn, to the bit, for a fourth of the estimates."""
    truths, _ = lowering
    items = sensed(truths[:300], seed=7, pin_fault=(1, 50, 5e3))
    trials = estimator.MonitorEstimator._trials
    tried: list[int] = []

    def counted(self, suspects, *args):
        trial = trials(self, suspects, *args)
        tried.append(len(trial.pairs))
        return trial

    monkeypatch.setattr(estimator.MonitorEstimator, "_trials", counted)
    first = replayed(WindowScheduler(noisy(plant), window=64), items)
    shortened = sum(tried)

    def every_sensor(self, suspects, lengths, measured, samples, loads, prior, forward, sensors, with_lengths=True):
        if sensors is not None:  # the sensor rejected before: never tried alone
            return estimator.Trial(sensors, with_lengths, [], [], None, np.zeros(0, bool))
        return counted(self, suspects, lengths, measured, samples, loads, prior, forward, None, with_lengths)

    monkeypatch.setattr(estimator.MonitorEstimator, "_trials", every_sensor)
    tried.clear()
    every = replayed(WindowScheduler(noisy(plant), window=64), items)
    assert sum(o.refused == ("tension_cable_2",) for o in every) == 250
    assert shortened * 4 < sum(tried)
    assert len(first) == len(every) == 300
    for a, b in zip(first, every):
        assert a.solution.tensions.tobytes() == b.solution.tensions.tobytes()
        assert a.solution.points_b.tobytes() == b.solution.points_b.tobytes()
        assert a.estimate.residuals == b.estimate.residuals and a.refused == b.refused
        assert (a.alarm.level, a.alarm.reason) == (b.alarm.level, b.alarm.reason)


def test_the_node_estimates_under_the_model_loosely_held_in_the_same_batch_with_the_same_bits(plant, lowering,
                                                                                             monkeypatch):
    """After a sample that fails its gates, the node estimates its next samples under the model as it is and
    under the model loosely held in one batch (estimator.SPECULATED), instead of estimating the failing ones
    again alone: every output is the same to the bit, what the alarm is based on included. Winch 1's encoder
    slips 5 cm at sample 100: from there the model's lengths disagree with the sensors, which the state
    follows, until the model's error has learnt the slip."""
    truths, _ = lowering
    slipped = [0]

    def reported(lengths: np.ndarray) -> np.ndarray:
        slipped[0] += 1
        return lengths + (np.array([0.05, 0.0, 0.0, 0.0]) if slipped[0] > 100 else 0.0)

    items = sensed(truths[:300], seed=6, reported=reported)
    calls = []
    batches = estimator.MonitorEstimator._batches
    monkeypatch.setattr(estimator.MonitorEstimator, "_batches",
                        lambda self, *args: calls.append(len(args[0])) or batches(self, *args))
    speculated = live(MonitorPipeline(noisy(plant)), items)
    assert len(calls) >= 50 and set(calls) == {1}  # one sample at a time, each with its loose twin
    followed = [o for o in speculated if "the model disagrees" in o.basis.text]
    assert len(followed) >= 50  # the state followed the sensors
    monkeypatch.setattr(estimator, "SPECULATED", 0)
    before = len(calls)
    alone = live(MonitorPipeline(noisy(plant)), items)
    assert len(calls) == before  # nothing speculated the second time
    assert len(speculated) == len(alone) == 300
    for a, b in zip(speculated, alone):
        assert a.solution.tensions.tobytes() == b.solution.tensions.tobytes()
        assert a.solution.points_b.tobytes() == b.solution.points_b.tobytes()
        assert a.estimate.residuals == b.estimate.residuals and a.estimate.used == b.estimate.used
        assert a.refused == b.refused and a.basis.text == b.basis.text
        assert (a.alarm.level, a.alarm.reason, a.alarm.clearance.value) == \
            (b.alarm.level, b.alarm.reason, b.alarm.clearance.value)


def test_a_second_process_publishing_ahead_gives_the_same_outputs(plant, lowering, monkeypatch, tmp_path):
    """Replay's second process estimates, judges and encodes each window while the next ones are merged:
    every record is the one-process replay's, to the bit, and the files it handed its results over in
    are gone when it stops."""
    monkeypatch.setattr(worker, "SPOOL", str(tmp_path))
    truths, _ = lowering
    items = sensed(truths[:160], seed=7, pin_fault=(1, 50, 5e3))
    one = [r for _, r in WindowScheduler(noisy(plant), window=64).run(items)]
    two = [r for _, r in WindowScheduler(noisy(plant), window=64, second_process=True).run(items)]
    assert not any(tmp_path.iterdir())  # the worker stopped with the replay, its spool removed
    published = [(a, b) for a, b in zip(one, two) if isinstance(a, Encoded)]
    assert len(published) == len(truths[:160]) and all(b.output is None for _, b in published)  # from there
    for a, b in published:
        assert a.records == b.records and a.outcome == b.outcome and a.view == b.view
    assert [a for a in one if not isinstance(a, Encoded)] == [b for b in two if not isinstance(b, Encoded)]


def test_a_second_process_that_is_lost_leaves_the_rest_to_the_replay(plant, lowering, monkeypatch, tmp_path):
    """Where the worker cannot hand a window's results over (its spool is not a directory: a full or
    missing /dev/shm), or is killed, the replay publishes the rest itself from the worker's last state:
    the same records."""
    items = sensed(lowering[0][:200], seed=11)
    one = [r for _, r in WindowScheduler(noisy(plant), window=64).run(items)]
    spooled = worker.ForkedWorker.__init__

    def unwritable(self, *args):
        spooled(self, *args)
        os.rmdir(self.spool)
        self.spool = str(tmp_path / "not-a-directory")
        open(self.spool, "w").close()

    with monkeypatch.context() as patch:
        patch.setattr(worker.ForkedWorker, "__init__", unwritable)
        two = [r for _, r in WindowScheduler(noisy(plant), window=64, second_process=True).run(items)]
    taken = second_process.SecondProcess.take
    killed = []

    def kill_after_two(self):
        if len(killed) == 2 and self.worker is not None:
            self.worker.process.kill()
            self.worker.process.join()
        killed.append(True)
        return taken(self)

    monkeypatch.setattr(second_process.SecondProcess, "take", kill_after_two)
    three = [r for _, r in WindowScheduler(noisy(plant), window=64, second_process=True).run(items)]
    for other in (two, three):
        pairs = [(a, b) for a, b in zip(one, other) if isinstance(a, Encoded)]
        assert len(pairs) == 200 and all(a.records == b.records and a.outcome == b.outcome for a, b in pairs)
    assert any(r.output is None for r in three if isinstance(r, Encoded))  # the first windows from there


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
    assert chi_square_threshold(17) == float(chdtri(17, 1.0 - DEFAULT_PROBABILITY))
    assert chi_square_threshold(1, 0.9973) == pytest.approx(9.0, rel=1e-3)  # 3 sigma of one channel
    assert chi_square_threshold(2, 0.99) == pytest.approx(-2.0 * np.log(0.01))  # two channels: exponential
