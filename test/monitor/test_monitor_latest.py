"""The live pipeline under load: every complete sample is solved or counted as skipped; samples waiting are
solved together in order, and only those more than the backlog behind the newest are skipped."""
from __future__ import annotations

import threading

import numpy as np

from cable_winch_monitor.model.plant import CABLE_NAMES
from cable_winch_monitor.model.result import check_physics
from cable_winch_monitor.monitor.inputs import JointSample
from cable_winch_monitor.monitor.latest import LatestSamplePipeline
from cable_winch_monitor.monitor.pipeline import MonitorPipeline


def sample(k: int, period: float = 1e-3) -> JointSample:
    payout = 20.0 + 1e-3 * k
    return JointSample(1.0 + period * k, list(CABLE_NAMES), [payout + 0.3, payout + 0.1, payout + 0.5, payout + 0.2])


def test_samples_waiting_are_solved_together_and_those_beyond_the_backlog_skipped(plant):
    pipeline = LatestSamplePipeline(plant, backlog=0.3)
    for k in range(10):  # 10 Hz: the first six are more than 0.3 s behind the newest
        assert pipeline.offer(sample(k, 0.1), tag=k)
    assert pipeline.complete == 10 and pipeline.skipped == 6 and pipeline.waiting == 4
    taken = pipeline.take(timeout=0.0)
    assert [tag for tag, _ in taken] == [6, 7, 8, 9] and pipeline.waiting == 0
    outputs = pipeline.solve_all([s for _, s in taken])
    assert [o.stamp for o in outputs] == [sample(k, 0.1).stamp for k in (6, 7, 8, 9)]
    assert all(o.solution.ok and check_physics(plant, o.solution).passes() for o in outputs)
    one_by_one = MonitorPipeline(plant)  # together, each sample's answer is the one it has alone, in order
    for k in (6, 7, 8, 9):
        alone = one_by_one.on_joint_state(sample(k, 0.1))
        np.testing.assert_allclose(alone.solution.tensions, outputs[k - 6].solution.tensions, atol=1e-6)
    assert pipeline.take(timeout=0.0) == [] and pipeline.waiting == 0


def test_a_refused_message_makes_no_sample_and_skips_none(plant):
    pipeline = LatestSamplePipeline(plant)
    assert pipeline.offer(sample(0))
    assert not pipeline.offer(JointSample(2.0, ["cable_1"], [float("nan")]))
    assert pipeline.stats.winch == 2 and pipeline.complete == 1 and pipeline.skipped == 0


def test_a_worker_solving_while_samples_pour_in_accounts_for_every_one(plant):
    pipeline = LatestSamplePipeline(plant)
    solved: list[float] = []
    done = threading.Event()

    def work() -> None:
        while not done.is_set() or pipeline.waiting:
            taken = pipeline.take(timeout=0.01)
            solved.extend(output.stamp for output in pipeline.solve_all([s for _, s in taken]))

    worker = threading.Thread(target=work)
    worker.start()
    for k in range(2000):
        pipeline.offer(sample(k))
    done.set()
    worker.join(timeout=30)
    assert not worker.is_alive()
    assert len(solved) + pipeline.skipped == pipeline.complete == 2000
    assert solved == sorted(solved) and solved[-1] == sample(1999).stamp  # in order, and the last one solved
    assert np.all(np.diff(solved) > 0)
