"""The live scheduler under load: every complete sample is solved or counted as skipped; samples waiting are
solved together in order, and only those more than the backlog behind the newest are skipped."""
from __future__ import annotations

import threading

import numpy as np

from cable_winch_monitor.live.scheduler import LiveScheduler
from cable_winch_monitor.model.plantfile.plant import CABLE_NAMES
from cable_winch_monitor.model.statics.result import check_physics
from cable_winch_monitor.monitor.inputs import JointSample
from cable_winch_monitor.monitor.pipeline import MonitorPipeline


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
