"""The batched elastic solver gives the per-sample elastic solver's answers.

Elastic ropes with their own weight (EA 7.5e7 N, 60 N/m, as a fitted plant file holds
them): same status and taut set, tensions within 1 N and poses within 1 mm, on a
lowering with drifting winches and on random lengths; and every solved state balances
the load with stretched ropes only.
"""
from __future__ import annotations

import numpy as np
import pytest

from cable_winch_monitor.bench.solvers import lowering_samples
from cable_winch_monitor.model.batched_elastic import solve_batch_elastic
from cable_winch_monitor.model.elastic import solve_elastic
from cable_winch_monitor.model.result import SolveStatus
from test_solver_agreement import random_lengths

EA = 7.5e7      # [N]
WEIGHT = 60.0   # [N/m]


def unstretched(lengths: np.ndarray) -> np.ndarray:
    """The lengths the elastic solver takes: paid out plus the rope's stretch under its own weight."""
    return lengths + WEIGHT * lengths ** 2 / (2.0 * EA)


def per_sample(plant, lengths, warm: bool, load=None):
    solutions, previous = [], None
    for row in lengths:
        solution = solve_elastic(plant, row, EA, warm_start=previous if warm else None, load=load)
        solutions.append(solution)
        previous = solution if solution.ok else previous
    return solutions


def assert_same(plant, batch, solutions):
    for i, want in enumerate(solutions):
        got = batch.solution(i)
        assert got.status is want.status, i
        assert got.taut_set == want.taut_set, i
        if not want.ok:
            continue
        assert np.abs(got.tensions - want.tensions).max() < 1.0, i
        assert np.abs(got.position - want.position).max() < 1e-3, i
        assert np.abs(got.points_b - want.points_b).max() < 1e-3, i
        # physics: tensions >= 0, the load balanced, a rope pulls only where stretched (Hooke)
        assert np.all(got.tensions >= 0.0), i
        assert got.force_residual < 1e-6 and got.moment_residual < 1e-6, i
        stretch = got.spans - got.lengths
        np.testing.assert_allclose(got.tensions, EA / got.lengths * np.maximum(stretch, 0.0), rtol=1e-9, atol=1e-6)
        np.testing.assert_allclose(got.extras["stretch"], want.extras["stretch"], atol=1e-6)


def test_lowering_same_as_warm_started_solver(plant):
    lengths = unstretched(lowering_samples(1000))
    lengths[:, 1] += np.linspace(0.0, 0.6, len(lengths))  # a winch running ahead: its rope goes slack
    batch = solve_batch_elastic(plant, lengths, EA)
    solutions = per_sample(plant, lengths, warm=True)
    assert len({s.taut_set for s in solutions}) >= 2  # four ropes pull, then three
    assert_same(plant, batch, solutions)
    assert len(batch.fallback) <= 3  # the batched path does the work


def test_random_lengths_same_as_warm_started_solver(plant):
    lengths = unstretched(random_lengths(60, seed=67))
    solutions = per_sample(plant, lengths, warm=True)  # each from the last solved sample, as a monitor
    assert sum(s.ok for s in solutions) > 40
    assert_same(plant, solve_batch_elastic(plant, lengths, EA), solutions)


def test_bad_rows_loads_and_warm_start(plant):
    lengths = unstretched(lowering_samples(60))
    lengths[[3, 40]] = [[np.nan, 60, 60, 60], [-1.0, 70, 70, 70]]
    side_pull = plant.wrench + np.array([800.0, -300.0, 0.0, 0.0, 0.0, 0.0])
    warm = solve_elastic(plant, lengths[0], EA, load=side_pull)
    batch = solve_batch_elastic(plant, lengths[1:], EA, warm_start=warm, loads=side_pull)
    assert batch.status[2] == batch.status[39] == SolveStatus.INVALID_INPUT.value
    assert batch.ok.sum() == 57
    assert_same(plant, batch, [solve_elastic(plant, row, EA, warm_start=warm, load=side_pull) for row in lengths[1:]])
    assert np.abs(batch.solution(0).points_b[:, 0] - warm.points_b[:, 0]).max() < 0.5  # pulled sideways alike


@pytest.mark.parametrize("stiffness", [0.0, np.nan])
def test_bad_stiffness_is_the_per_sample_error(plant, stiffness):
    batch = solve_batch_elastic(plant, lowering_samples(5), stiffness)
    assert set(batch.status) == {SolveStatus.INVALID_INPUT.value}
    assert "EA" in batch.solution(0).message
