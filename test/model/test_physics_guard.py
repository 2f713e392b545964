"""No result leaves a solver as solved unless its physics check passes; absurd lengths are refused."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from cable_winch_monitor.model.paper.traversal import solve_traversal
from cable_winch_monitor.model.solvers.batched import solve_batch
from cable_winch_monitor.model.solvers.energy import solve_energy
from cable_winch_monitor.model.statics.result import SolveStatus, check_physics, guarded_solve, physics_guard

ABSURD = [[1e300, 20.1, 20.5, 20.2], [1e9, 1e9 + 0.2, 1e9 + 0.1, 1e9], [3000.5, 3000.0, 3000.2, 3000.1]]


@pytest.mark.parametrize("lengths", ABSURD)
def test_lengths_beyond_the_maximum_payout_are_invalid_input(plant, lengths):
    warm = solve_energy(plant, [20.3, 20.1, 20.5, 20.2])
    for solution in (solve_energy(plant, lengths), solve_energy(plant, lengths, warm_start=warm),
                     solve_traversal(plant, lengths), solve_batch(plant, np.array([lengths]), warm).solution(0)):
        assert solution.status is SolveStatus.INVALID_INPUT, solution.message
        assert "beyond the maximum payout 3000 m" in solution.message


def test_a_batch_refuses_the_absurd_rows_and_solves_the_others(plant):
    lengths = np.array([[20.3, 20.1, 20.5, 20.2]] * 6 + ABSURD + [[20.3, 20.1, 20.5, 20.2]] * 3)
    batch = solve_batch(plant, lengths)
    assert batch.ok.tolist() == [True] * 6 + [False] * 3 + [True] * 3
    for solution in batch.solutions():
        assert not solution.ok or check_physics(plant, solution).passes()


def test_the_guard_turns_a_solution_that_does_not_balance_into_a_failure(plant):
    good = solve_energy(plant, [20.3, 20.1, 20.5, 20.2])
    unbalanced = replace(good, tensions=good.tensions * 1.01)
    guarded = guarded_solve("energy", good.lengths, lambda _: unbalanced, plant=plant)
    assert guarded.status is SolveStatus.SOLVER_FAILED
    assert "fails the physics check (force residual 0.01 mg" in guarded.message
    assert physics_guard(plant, good) is good


def test_the_guard_names_every_failed_condition(plant):
    good = solve_energy(plant, [20.3, 20.1, 20.5, 20.2])
    mirror = np.diag([1.0, 1.0, -1.0])
    mirrored = replace(good, points_b=good.points_b @ mirror, point_c=good.point_c @ mirror)
    failure = check_physics(plant, mirrored).failure()
    assert "mirror image" in failure and "force residual 2 mg" in failure


@pytest.mark.parametrize("payout", [2000.0, 2999.0])
def test_long_but_possible_payouts_solve_and_balance(plant, payout):
    lengths = payout + np.array([0.3, 0.1, 0.5, 0.2])
    for solution in (solve_energy(plant, lengths), solve_batch(plant, lengths[None]).solution(0)):
        assert solution.ok, solution.message
        assert check_physics(plant, solution).passes()
