"""The live scheduler under load: every complete sample is solved or counted as skipped; samples waiting are
solved together in order, and only those more than the backlog behind the newest are skipped."""
from __future__ import annotations

import os
import signal
import threading
from collections.abc import Callable
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from fusionbags import lowering_truths, noisy, sensed
from simbags import simulated

from cable_winch_monitor import channels
from cable_winch_monitor.bagio.reader import BagReader
from cable_winch_monitor.bench.plants import tracking_plant_file
from cable_winch_monitor.effects import PlantModel
from cable_winch_monitor.live.scheduler import UPDATES_LOST, LiveScheduler
from cable_winch_monitor.messages import fields
from cable_winch_monitor.messages.outputs import ALARM, OUTPUT_TYPES, POSE, TENSION
from cable_winch_monitor.model.plantfile.plant import CABLE_NAMES, load_plant
from cable_winch_monitor.model.statics.result import check_physics
from cable_winch_monitor.monitor.inputs import JointSample
from cable_winch_monitor.monitor.pipeline import MonitorPipeline
from cable_winch_monitor.monitor.sensors import READING_LAG
from cable_winch_monitor.monitor.updates import PendingUpdate
from cable_winch_monitor.replay.run import replay


def sample(k: int, period: float = 1e-3) -> JointSample:
    payout = 20.0 + 1e-3 * k
    return JointSample(1.0 + period * k, list(CABLE_NAMES), [payout + 0.3, payout + 0.1, payout + 0.5, payout + 0.2])


def test_samples_waiting_are_solved_together_and_those_beyond_the_backlog_skipped(plant):
    scheduler = LiveScheduler(plant, backlog=0.3)
    for k in range(10):  # 10 Hz: the first six are more than 0.3 s behind the newest
        assert scheduler.offer(sample(k, 0.1), tag=k)
    assert scheduler.complete == 10 and scheduler.skipped == 6 and scheduler.waiting == 4
    taken = scheduler.take(timeout=0.0)
    assert [tag for tag, _ in taken] == [6, 7, 8, 9] and scheduler.waiting == 0
    outputs = scheduler.solve_all([s for _, s in taken])
    assert [o.stamp for o in outputs] == [sample(k, 0.1).stamp for k in (6, 7, 8, 9)]
    assert all(o.solution.ok and check_physics(plant, o.solution).passes() for o in outputs)
    one_by_one = MonitorPipeline(plant)  # together, each sample's answer is the one it has alone, in order
    for k in (6, 7, 8, 9):
        alone = one_by_one.on_joint_state(sample(k, 0.1))
        np.testing.assert_allclose(alone.solution.tensions, outputs[k - 6].solution.tensions, atol=1e-6)
    assert scheduler.take(timeout=0.0) == [] and scheduler.waiting == 0


def test_a_refused_message_makes_no_sample_and_skips_none(plant):
    scheduler = LiveScheduler(plant)
    assert scheduler.offer(sample(0))
    assert not scheduler.offer(JointSample(2.0, ["cable_1"], [float("nan")]))
    assert scheduler.monitor.stats.winch == 2 and scheduler.complete == 1 and scheduler.skipped == 0


def test_a_worker_solving_while_samples_pour_in_accounts_for_every_one(plant):
    scheduler = LiveScheduler(plant)
    solved: list[float] = []
    done = threading.Event()

    def work() -> None:
        while not done.is_set() or scheduler.waiting:
            taken = scheduler.take(timeout=0.01)
            solved.extend(output.stamp for output in scheduler.solve_all([s for _, s in taken]))

    worker = threading.Thread(target=work)
    worker.start()
    for k in range(2000):
        scheduler.offer(sample(k))
    done.set()
    worker.join(timeout=30)
    assert not worker.is_alive()
    assert len(solved) + scheduler.skipped == scheduler.complete == 2000
    assert solved == sorted(solved) and solved[-1] == sample(1999).stamp  # in order, and the last one solved
    assert np.all(np.diff(solved) > 0)


def delivered(items: list, rng: np.random.Generator, late: float) -> list[tuple[float, object]]:
    """The items as DDS may hand them over: each sensor message up to `late` [s] after its log time (each topic
    still in order), the winch messages on time, overtaking them."""
    arrivals, last = [], {}
    for k, entry in enumerate(items):
        at = entry.log_time * 1e-9 + (0.0 if entry.msgtype == channels.JOINT_STATE else rng.uniform(0.0, late))
        last[entry.topic] = at = max(at, last.get(entry.topic, at))
        arrivals.append((at, k))
    return [(at, items[k]) for at, k in sorted(arrivals)]


def fed(plant, arrivals: list[tuple[float, object]], wait: float, in_process: bool = True,
        on_arrival: Callable[[float, LiveScheduler], None] | None = None,
        lag: float = READING_LAG) -> tuple[list, list, LiveScheduler]:
    """The complete samples a live scheduler hands the worker, and their outputs, fed the items as they arrive
    (its clock their arrival), its window updates worked out in their process (`in_process`) or at once as
    replay does; `on_arrival(time, scheduler)` is called before each item is fed."""
    clock = [0.0]
    scheduler = LiveScheduler(plant, backlog=1e9, wait=wait, clock=lambda: clock[0], lag=lag)
    if not in_process:
        scheduler.monitor.estimator.background = None
    inputs = {spec.topic: spec for spec in scheduler.monitor.model.inputs}  # what the plant's effects read
    samples, outputs = [], []
    for at, entry in arrivals:
        clock[0] = at
        if on_arrival is not None:
            on_arrival(at, scheduler)
        msg = entry.message
        if entry.topic in inputs:
            scheduler.monitor.on_input(inputs[entry.topic], fields.seconds(msg.header.stamp), msg)
        elif entry.msgtype == channels.JOINT_STATE:
            scheduler.offer(fields.joint_sample(msg, entry.topic, at))
        else:
            scheduler.on_measurement(entry.topic, fields.seconds(msg.header.stamp), msg)
        taken = [sample for _, sample in scheduler.take(timeout=0.0)]
        samples += taken
        outputs += scheduler.solve_all(taken)
    clock[0] += 1.0
    taken = [sample for _, sample in scheduler.take(timeout=0.0)]
    outputs += scheduler.solve_all(taken)
    scheduler.close()
    return samples + taken, outputs, scheduler


def test_a_sample_waits_for_the_readings_stamped_before_it_that_its_winch_message_overtook(plant):
    """Sensor messages delivered up to 85 ms late, overtaken by the winch messages stamped after them (the
    inclinometer is stamped 30-40 ms after the winches): held for them, every complete sample fuses the
    readings it fuses in log order, and comes to the same state; not held, samples fuse older readings."""
    fused = noisy(plant)
    items = sensed(lowering_truths(fused, 60, seed=3), seed=4)
    in_order, want, _ = fed(fused, [(entry.log_time * 1e-9, entry) for entry in items], wait=1.0)
    late = delivered(items, np.random.default_rng(5), 0.085)
    held, got, scheduler = fed(fused, late, wait=1.0)
    unheld, _, _ = fed(fused, late, wait=0.0)
    known = [k for k, sample in enumerate(in_order) if sample.stamp > 100.6]  # the depth gauge's interval known
    assert len(held) == len(in_order) == len(got) == 60 and scheduler.counters()["held for a sensor reading"] > 0
    for k in known:
        assert held[k].taken == in_order[k].taken and held[k].sensors == in_order[k].sensors
        assert held[k].faults == in_order[k].faults
        np.testing.assert_allclose(got[k].solution.tensions, want[k].solution.tensions, atol=1e-6)
        assert check_physics(fused, got[k].solution).passes()
    assert sum(unheld[k].taken != in_order[k].taken for k in known) >= 10


def test_a_node_seconds_behind_its_inputs_fuses_the_readings_replay_fuses(plant):
    """A node that falls 3 s behind (its start, a stall) finds 3 s of sensor readings queued before the winch
    messages stamped among them, and keeps them all before it merges those: every sample still fuses the
    readings it fuses in log order, and comes to the same state to the last bit. With 16 readings kept a
    channel, the inclinometer's 30 newer ones pushed out those its samples needed."""
    fused = noisy(plant)
    items = sensed(lowering_truths(fused, 60, seed=3), seed=4)
    in_order, want, _ = fed(fused, [(entry.log_time * 1e-9, entry) for entry in items], wait=1.0)
    behind = sorted(((entry.log_time * 1e-9 + (3.0 if entry.msgtype == channels.JOINT_STATE else 0.0), k)
                     for k, entry in enumerate(items)))
    lagging, got, _ = fed(fused, [(at, items[k]) for at, k in behind], wait=1.0)
    assert len(lagging) == len(in_order) == len(got) == len(want) == 60
    for k in range(60):
        assert lagging[k].taken == in_order[k].taken and lagging[k].sensors == in_order[k].sensors, k
        assert np.array_equal(got[k].solution.tensions, want[k].solution.tensions)


def test_a_sensor_as_fast_as_the_winches_holds_no_sample_behind_the_lag(tmp_path):
    """Site recording (a) with winches and inclinometer at 50 Hz, the inclinometer stamped 30-40 ms after the
    winches (5 ms between some of its readings). Fusing the readings stamped at or before a sample, a good part
    of the samples wait for its next reading; fusing those stamped READING_LAG before it, none waits, and each
    takes the same readings whether the inclinometer's messages came in log order or up to 20 ms late."""
    bag = simulated(tmp_path, "site_elastic", "duration=8.0", "sensors.joint_states.rate=50")
    plant = load_plant()  # the bundled rigid plant file, which fuses every sensor
    items = list(BagReader(bag, fields.input_topics(PlantModel.from_plant(plant))))
    in_order = [(entry.log_time * 1e-9, entry) for entry in items]
    _, _, unlagged = fed(plant, in_order, wait=1.0, lag=0.0)
    lagged, outputs, scheduler = fed(plant, in_order, wait=1.0)
    late, _, _ = fed(plant, delivered(items, np.random.default_rng(6), 0.02), wait=1.0)
    assert len(lagged) == len(late) == scheduler.complete > 350
    assert unlagged.counters()["held for a sensor reading"] > 0.2 * unlagged.complete
    assert scheduler.counters()["held for a sensor reading"] == 0
    for sample, at_random in zip(lagged, late):
        assert at_random.taken == sample.taken and at_random.sensors == sample.sensors
        roll = sample.taken.get("roll")
        assert roll is None or roll <= sample.stamp - READING_LAG
    first = min(fields.seconds(entry.message.header.stamp) for entry in items if entry.topic == "/platform/imu")
    assert all("roll" in sample.taken for sample in lagged if sample.stamp >= first + READING_LAG)
    assert all(check_physics(plant, output.solution).passes() for output in outputs)


def test_a_sample_whose_reading_never_comes_goes_on_when_its_wait_is_over(plant):
    """The inclinometer falls silent: the sample at which its next reading was due waits `wait` seconds of the
    node's clock, then fuses what is in (the last reading, within the staleness limit), counted as released
    without it; a sensor more than three intervals late is not waited for."""
    fused = noisy(plant)
    items = sensed(lowering_truths(fused, 20, seed=3, lags=False), seed=4)
    silent = [entry for entry in items if entry.msgtype == channels.JOINT_STATE or entry.log_time * 1e-9 < 100.5]
    clock = [0.0]
    scheduler = LiveScheduler(fused, backlog=1e9, wait=0.05, clock=lambda: clock[0])
    taken = []
    for entry in silent:
        clock[0] = entry.log_time * 1e-9
        if entry.msgtype == channels.JOINT_STATE:
            scheduler.offer(fields.joint_sample(entry.message, entry.topic, clock[0]))
        else:
            scheduler.on_measurement(entry.topic, fields.seconds(entry.message.header.stamp), entry.message)
        taken += [sample for _, sample in scheduler.take(timeout=0.0)]
    clock[0] += 0.05
    taken += [sample for _, sample in scheduler.take(timeout=0.0)]
    assert len(taken) == 20 and scheduler.waiting == 0
    assert [s.stamp for s in taken] == sorted(s.stamp for s in taken)
    last, period = scheduler.monitor.readings.values["roll"][-1][0], scheduler.monitor.readings.periods["roll"]
    waited = [s.stamp for s in taken if last + period <= s.stamp < last + 3.0 * period]
    counts = scheduler.counters()
    assert len(waited) >= 1 and counts["of those, released without it"] == counts["held for a sensor reading"] == len(waited)
    assert all(s.taken["roll"] == last for s in taken if s.stamp >= last + period - 1e-9 and s.stamp - last <= 0.5)


def test_diagnostics_time_what_each_solved_sample_queued_and_took(plant):
    now = [0.0]
    scheduler = LiveScheduler(plant, backlog=0.3, clock=lambda: now[0])
    for k in range(10):  # 10 Hz, merged 1 ms apart on the clock: the first six are skipped (beyond the backlog)
        now[0] = 1e-3 * k
        scheduler.offer(sample(k, 0.1), tag=k)
    solve = scheduler.monitor.solve_samples

    def solving(*args):  # the solve takes 7 ms of the clock
        now[0] += 7e-3
        return solve(*args)
    scheduler.monitor.solve_samples = solving
    now[0] = 0.020
    scheduler.solve_all([s for _, s in scheduler.take(timeout=0.0)])
    merged = 1e-3 * np.arange(6, 10)  # only the four solved samples are timed
    np.testing.assert_allclose(scheduler.queued, 0.020 - merged)
    np.testing.assert_allclose(scheduler.processed, 0.027 - merged)
    counters = scheduler.counters()
    assert counters["queued before the solve [ms], latest 4 samples"] == "p50 12.5, p99 14.0, max 14.0"
    assert counters["merged to outputs [ms], latest 4 samples"] == "p50 19.5, p99 21.0, max 21.0"


def tracked_values(plant, bag, in_process: bool, on_arrival: Callable[[float, LiveScheduler], None] | None = None) \
        -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Each sample's tensions and tracked parameters (values, sigmas) from a live scheduler fed the recording in
    log order (`fed`)."""
    topics = fields.input_topics(PlantModel.from_plant(plant))
    arrivals = [(item.log_time * 1e-9, item) for item in BagReader(bag, topics)]
    _, outputs, _ = fed(plant, arrivals, wait=0.0, in_process=in_process, on_arrival=on_arrival)
    return [(output.solution.tensions, output.model.parameters.values, output.model.parameters.sigmas)
            for output in outputs]


def test_window_updates_in_their_process_are_those_worked_out_at_once(tmp_path):
    """The node works its window updates out in a process of its own (monitor.updates); they are the updates
    replay works out at once, bit for bit, on every sample of a recording whose tracked values move."""
    bag = simulated(tmp_path / "bag", "site_tracking", "duration=45.0")
    plant = load_plant(tracking_plant_file(tmp_path / "stiff.yaml", 6.8e7 / 0.9))
    apart, together = tracked_values(plant, bag, True), tracked_values(plant, bag, False)
    assert len(apart) == len(together) > 400
    for (tensions, values, sigmas), (tensions_at_once, values_at_once, sigmas_at_once) in zip(apart, together):
        assert np.array_equal(tensions, tensions_at_once)
        assert np.array_equal(values, values_at_once) and np.array_equal(sigmas, sigmas_at_once)
    first, last = apart[0], apart[-1]
    assert not np.array_equal(first[2], last[2]), "the windows' updates moved the tracked parameters' sigmas"


def test_a_lost_update_process_costs_no_update_and_is_replaced(tmp_path):
    """The update process killed twice (as the kernel kills a process for memory), once while it works an update
    out and once while it waits for one: the node goes on, works the unanswered update out itself and starts a
    new process, and every sample's tensions and tracked values are still those worked out at once, bit for
    bit; /diagnostics counts the losses."""
    bag = simulated(tmp_path / "bag", "site_tracking", "duration=45.0")
    plant = load_plant(tracking_plant_file(tmp_path / "stiff.yaml", 6.8e7 / 0.9))
    kills: list[int] = []
    unanswered: list[PendingUpdate] = []
    counters: list[dict[str, object]] = []
    start: list[float] = []

    def kill(at: float, scheduler: LiveScheduler) -> None:
        pending, ids = scheduler.monitor.estimator.pending, scheduler.updates.process_ids()
        start[:] = start or [at]
        due = [t for t in (12.0, 31.0) if t <= at - start[0]]  # seconds into the recording; windows of 10 s
        if len(due) > len(kills) and ids and isinstance(pending, PendingUpdate):
            if not kills and not pending.future.done():  # lost while it works an update out
                unanswered.append(pending)
            elif kills:  # lost while it waits for one
                pending.future.result()
            else:
                return
            os.kill(ids[0], signal.SIGKILL)
            kills.append(ids[0])
        counters.append(scheduler.counters())

    lost = tracked_values(plant, bag, True, kill)
    together = tracked_values(plant, bag, False)
    assert len(kills) == 2 and kills[0] != kills[1], "a new process replaced the first one lost"
    assert isinstance(unanswered[0].future.exception(), BrokenProcessPool), "its update was worked out in the node"
    assert len(lost) == len(together) > 400
    for (tensions, values, sigmas), (tensions_at_once, values_at_once, sigmas_at_once) in zip(lost, together):
        assert np.array_equal(tensions, tensions_at_once)
        assert np.array_equal(values, values_at_once) and np.array_equal(sigmas, sigmas_at_once)
    assert counters[-1][UPDATES_LOST] == 2
    assert "terminated abruptly" in str(counters[-1][f"{UPDATES_LOST}, the last"])


def test_a_users_effect_is_tracked_in_the_update_process_as_at_once(tmp_path):
    """The update process loads a user's effect (examples/rope_temperature.py, reading /shaft/temperature) from
    the plant file as the node does, and tracks its parameter as replay would, bit for bit."""
    bag = simulated(tmp_path / "bag", "sinking_run", "duration=35.0", "shaft_air.amplitude=8.0",
                    "shaft_air.period=60.0")
    config = yaml.safe_load(tracking_plant_file(tmp_path / "elastic.yaml", 6.8e7, track=False).read_text())
    config["plant"]["effect_modules"] = [str(Path(__file__).parents[2] / "examples" / "rope_temperature.py")]
    config["plant"]["effects"]["rope_temperature"] = {"alpha": 0.0}
    config["plant"]["track"] = ["rope_temperature.alpha"]
    (tmp_path / "plant.yaml").write_text(yaml.safe_dump(config))
    plant = load_plant(tmp_path / "plant.yaml")
    apart, together = tracked_values(plant, bag, True), tracked_values(plant, bag, False)
    assert len(apart) == len(together) > 300
    for (tensions, values, sigmas), (tensions_at_once, values_at_once, sigmas_at_once) in zip(apart, together):
        assert np.array_equal(tensions, tensions_at_once)
        assert np.array_equal(values, values_at_once) and np.array_equal(sigmas, sigmas_at_once)
    # the windows' updates were taken: 35 s of lowering do not excite alpha enough, so it is held and its sigma
    # grows by the drift the plant file allows
    assert apart[-1][2][0] > apart[0][2][0]


def batched_outputs(plant, bag: Path, sizes: np.random.Generator) -> dict[int, tuple[np.ndarray, np.ndarray, int]]:
    """Stamp [ns] -> tensions, position and alarm level of each sample, from a live scheduler fed the recording in
    log order and solving its waiting samples whenever a random number of them (1 to 7) waits, as a node does
    under a load it cannot foresee."""
    clock = [0.0]
    scheduler = LiveScheduler(plant, backlog=1e9, wait=1.0, clock=lambda: clock[0])
    inputs = {spec.topic: spec for spec in scheduler.monitor.model.inputs}
    out: dict[int, tuple[np.ndarray, np.ndarray, int]] = {}

    def solve() -> None:
        for output in scheduler.solve_all([sample for _, sample in scheduler.take(timeout=0.0)]):
            out[round(output.stamp * 1e9)] = (output.solution.tensions, output.solution.position, output.alarm.level)

    due = int(sizes.integers(1, 8))
    for item in BagReader(bag, fields.input_topics(scheduler.monitor.model)):
        clock[0] = item.log_time * 1e-9
        stamp = fields.message_seconds(item.message, item.log_time)
        if item.topic in inputs:
            scheduler.monitor.on_input(inputs[item.topic], stamp, item.message)
        elif item.msgtype == channels.JOINT_STATE:
            scheduler.offer(fields.joint_sample(item.message, item.topic, clock[0]))
        else:
            scheduler.on_measurement(item.topic, stamp, item.message)
        if scheduler.waiting >= due:
            solve()
            due = int(sizes.integers(1, 8))
    clock[0] += 10.0
    solve()
    scheduler.close()
    return out


def replayed_outputs(plant, bag: Path, out: Path) -> dict[int, tuple[np.ndarray, np.ndarray, int]]:
    """The same from `replay` (windows of samples solved at once, its output bag read back)."""
    replay(bag, out, plant, progress=False)

    def stamped(topic: str) -> dict[int, Any]:
        return {round(fields.seconds(m.message.header.stamp) * 1e9): m.message
                for m in BagReader(out, {topic: OUTPUT_TYPES[topic]})}
    poses, levels = stamped(POSE), stamped(ALARM)
    return {stamp: (np.array([c.tension for c in message.cables]),
                    np.array([getattr(poses[stamp].pose.position, axis) for axis in "xyz"]), levels[stamp].level)
            for stamp, message in stamped(TENSION).items()}


def test_the_node_gives_replays_state_bit_for_bit_however_it_batches_its_samples(tmp_path):
    """On elastic ropes replayed with the bundled rigid plant file (case (a): the model's taut set changes from
    sample to sample) and with an elastic plant file that tracks EA, a live scheduler solving its samples in
    batches of any size gives every sample the replay's tensions and pose to the last bit, and its alarm level:
    every forward solve starts from a state that depends on the sample's own update window only, and every
    fit over recent samples sums that window's own rows."""
    bag = simulated(tmp_path / "bag", "site_elastic", "duration=40.0")
    rigid = load_plant(None)
    elastic = load_plant(tracking_plant_file(tmp_path / "elastic.yaml", 6.8e7 / 0.9))
    for name, plant in (("rigid", rigid), ("elastic", elastic)):
        live = batched_outputs(plant, bag, np.random.default_rng(7))
        replayed = replayed_outputs(plant, bag, tmp_path / f"replayed_{name}")
        assert len(live) == len(replayed) == 400, name
        for stamp, (tensions, position, level) in replayed.items():
            got = live[stamp]
            assert np.array_equal(got[0], tensions) and np.array_equal(got[1], position), (name, stamp)
            assert got[2] == level
