"""Elastic ropes: Hooke's law on every taut rope, force and moment balance, the rigid limit."""
from __future__ import annotations

import numpy as np
import pytest

from cable_winch_monitor.model.solvers.elastic import solve_elastic
from cable_winch_monitor.model.solvers.energy import solve_energy
from cable_winch_monitor.model.statics.geometry import wrench_residual
from cable_winch_monitor.model.statics.result import SolveStatus

EA = 7.5e7  # [N] a 40 mm six-strand rope


@pytest.mark.parametrize("lengths", [[300.0] * 4, [300.0, 300.01, 300.02, 300.0], [300.3, 300.1, 300.5, 300.2]])
def test_hooke_law_and_balance(plant, lengths):
    solution = solve_elastic(plant, lengths, EA)
    assert solution.ok, solution.message
    stretch = solution.spans - solution.lengths
    np.testing.assert_allclose(solution.tensions, EA / solution.lengths * np.maximum(stretch, 0.0), rtol=1e-9)
    assert np.all(stretch[~solution.taut] <= 0.0)
    force, moment = wrench_residual(plant, solution.points_b, solution.point_c, solution.tensions)
    assert force < 1e-9 and moment < 1e-9
    assert solution.tensions.sum() == pytest.approx(plant.weight, rel=1e-3)


def test_elastic_ropes_share_the_load_that_rigid_ones_leave_open(plant):
    """Four equal elastic ropes: all taut, a determinate distribution (rigid: the min-Delta-T choice)."""
    solution = solve_elastic(plant, [300.0] * 4, EA)
    assert solution.taut.all()
    assert not np.allclose(solution.tensions / plant.weight, [0.3625, 0.2375, 0.1375, 0.2625], atol=1e-3)


def test_stiff_ropes_approach_the_rigid_solution(plant):
    lengths = [200.3, 200.1, 200.5, 200.2]
    rigid = solve_energy(plant, lengths)
    stiff = solve_elastic(plant, lengths, 1e13)
    assert stiff.taut_set == rigid.taut_set
    np.testing.assert_allclose(stiff.points_b, rigid.points_b, atol=1e-6)
    np.testing.assert_allclose(stiff.tensions, rigid.tensions, atol=5.0)


def test_bad_stiffness_and_single_rope(plant):
    assert solve_elastic(plant, [100.0] * 4, -1.0).status is SolveStatus.INVALID_INPUT
    assert solve_elastic(plant, [20, 21, 22, 21.5], EA).status is SolveStatus.SINGLE_CABLE_INDETERMINATE
