"""The live pipeline under load: every complete sample is solved or counted as skipped; the newest wins."""
from __future__ import annotations

import threading

import numpy as np

from cable_winch_monitor.model.plant import CABLE_NAMES
from cable_winch_monitor.model.result import check_physics
from cable_winch_monitor.monitor.inputs import JointSample
from cable_winch_monitor.monitor.latest import LatestSamplePipeline


def sample(k: int) -> JointSample:
    payout = 20.0 + 1e-3 * k
    return JointSample(1.0 + 1e-3 * k, list(CABLE_NAMES), [payout + 0.3, payout + 0.1, payout + 0.5, payout + 0.2])


def test_a_sample_not_taken_before_the_next_is_skipped_and_the_newest_is_solved(plant):
    pipeline = LatestSamplePipeline(plant)
    for k in range(10):
        assert pipeline.offer(sample(k), tag=k)
    assert pipeline.complete == 10 and pipeline.skipped == 9 and pipeline.waiting == 1
    tag, newest = pipeline.take(timeout=0.0)
    assert tag == 9 and newest.stamp == sample(9).stamp
    output = pipeline.solve(newest)
    assert output.solution.ok and check_physics(plant, output.solution).passes()
    assert pipeline.take(timeout=0.0) is None and pipeline.waiting == 0


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
            if taken is not None:
                solved.append(pipeline.solve(taken[1]).stamp)

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
