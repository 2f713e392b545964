"""The batched elastic solver gives the per-sample elastic solver's answers.

Elastic ropes with their own weight (EA 7.5e7 N, 60 N/m, as a fitted plant file holds
them): same status and taut set, tensions within 1 N and poses within 1 mm, on a
lowering with drifting winches and on random lengths; and every solved state balances
the load with stretched ropes only.
"""
from __future__ import annotations

import numpy as np
import pytest
from batch_checks import assert_same, per_sample
from lengths import random_lengths

from cable_winch_monitor.bench.solvers import lowering_samples
from cable_winch_monitor.model.solvers.batched_elastic import solve_batch_elastic
from cable_winch_monitor.model.solvers.elastic import solve_elastic
from cable_winch_monitor.model.statics.result import SolveStatus

EA = 7.5e7      # [N]
WEIGHT = 60.0   # [N/m]


def unstretched(lengths: np.ndarray) -> np.ndarray:
    """The lengths the elastic solver takes: paid out plus the rope's stretch under its own weight."""
    return lengths + WEIGHT * lengths ** 2 / (2.0 * EA)


def elastic(load=None):
    """The per-sample elastic solver on EA, under `load`, as test_batched.per_sample calls a solver."""
    return lambda plant, row, warm_start: solve_elastic(plant, row, EA, warm_start=warm_start, load=load)


def hooke(plant, solution) -> bool:
    """Balanced, tensions >= 0, and each rope pulls by Hooke's law where stretched, not at all where slack."""
    stretch = np.maximum(solution.spans - solution.lengths, 0.0)
    return bool(solution.force_residual < 1e-6 and solution.moment_residual < 1e-6 and solution.tensions.min() >= 0.0
                and np.allclose(solution.tensions, EA / solution.lengths * stretch, rtol=1e-9, atol=1e-6)
                and np.allclose(solution.extras["stretch"], stretch, atol=1e-9))


def test_lowering_same_as_warm_started_solver(plant):
    lengths = unstretched(lowering_samples(1000))
    lengths[:, 1] += np.linspace(0.0, 0.6, len(lengths))  # a winch running ahead: its rope goes slack
    batch = solve_batch_elastic(plant, lengths, EA)
    solutions = per_sample(plant, lengths, True, elastic())
    assert len({s.taut_set for s in solutions}) >= 2  # four ropes pull, then three
    assert_same(plant, batch, solutions, hooke)
    assert len(batch.fallback) <= 3  # the batched path does the work


def test_random_lengths_same_as_warm_started_solver(plant):
    lengths = unstretched(random_lengths(60, seed=67))
    solutions = per_sample(plant, lengths, True, elastic())  # each from the last solved sample, as a monitor
    assert sum(s.ok for s in solutions) > 40
    assert_same(plant, solve_batch_elastic(plant, lengths, EA), solutions, hooke)


def test_bad_rows_loads_and_warm_start(plant):
    lengths = unstretched(lowering_samples(60))
    lengths[[3, 40]] = [[np.nan, 60, 60, 60], [-1.0, 70, 70, 70]]
    side_pull = plant.wrench + np.array([800.0, -300.0, 0.0, 0.0, 0.0, 0.0])
    warm = solve_elastic(plant, lengths[0], EA, load=side_pull)
    batch = solve_batch_elastic(plant, lengths[1:], EA, warm_start=warm, loads=side_pull)
    assert batch.status[2] == batch.status[39] == SolveStatus.INVALID_INPUT.value
    assert batch.ok.sum() == 57
    assert_same(plant, batch, [elastic(side_pull)(plant, row, warm) for row in lengths[1:]], hooke)
    assert np.abs(batch.solution(0).points_b[:, 0] - warm.points_b[:, 0]).max() < 0.5  # pulled sideways alike


@pytest.mark.parametrize("stiffness", [0.0, np.nan])
def test_bad_stiffness_is_the_per_sample_error(plant, stiffness):
    batch = solve_batch_elastic(plant, lowering_samples(5), stiffness)
    assert set(batch.status) == {SolveStatus.INVALID_INPUT.value}
    assert "EA" in batch.solution(0).message


def test_not_following_a_rows_answer_does_not_depend_on_the_rows_solved_with_it(plant):
    """Every row from the seed: its bits are the same solved alone as beside the others, one of which hangs on a
    single rope (left to the per-sample solver, which calls it indeterminate) and one of which is not a number;
    each solved row obeys Hooke's law in balance. (A row whose Newton meets a system with one rope pulling stops
    there: the random lengths above have such rows.)"""
    lengths = unstretched(lowering_samples(40, seed=21))
    lengths[7] = [303.4, 305.0, 305.0, 305.0]   # one rope 1.6 m shorter than the others: a plumb hang
    lengths[12] = np.nan
    seed = solve_elastic(plant, lengths[0], EA)
    together = solve_batch_elastic(plant, lengths, EA, seed, follow=False)
    assert together.status[7] == SolveStatus.SINGLE_CABLE_INDETERMINATE.value and 7 in together.fallback
    assert together.status[12] == SolveStatus.INVALID_INPUT.value
    good = [i for i in range(len(lengths)) if i not in (7, 12)]
    assert together.ok[good].all()
    for i in (1, 7, 20, 39):
        alone = solve_batch_elastic(plant, lengths[i:i + 1], EA, seed, follow=False)
        assert alone.status[0] == together.status[i]
        for name in ("tensions", "rotation", "position"):
            assert np.array_equal(getattr(alone, name)[0], getattr(together, name)[i], equal_nan=True)
    assert all(hooke(plant, together.solution(i)) for i in good)
