"""The batched solver held to the per-sample one: the same states, sample by sample."""
from __future__ import annotations

import numpy as np

from cable_winch_monitor.model.solvers.energy import solve_energy
from cable_winch_monitor.model.statics.result import check_physics


def per_sample(plant, lengths, warm: bool, solver=solve_energy):
    """`solver(plant, lengths, warm_start=...)` on each row, warm-started from the last solved row or cold."""
    solutions, previous = [], None
    for row in lengths:
        solution = solver(plant, row, warm_start=previous if warm else None)
        solutions.append(solution)
        previous = solution if solution.ok else previous
    return solutions


def rigid_physics(plant, solution) -> bool:
    return check_physics(plant, solution).passes()


def assert_same(plant, batch, solutions, physics=rigid_physics):
    """Status, taut set, tensions within 1 N, poses within 1 mm; every solved state passes `physics`."""
    for i, want in enumerate(solutions):
        got = batch.solution(i)
        assert got.status is want.status, i
        assert got.taut_set == want.taut_set, i
        if want.tensions is not None:
            assert np.abs(got.tensions - want.tensions).max() < 1.0, i
        if want.ok:
            assert np.abs(got.position - want.position).max() < 1e-3, i
            assert np.abs(got.points_b - want.points_b).max() < 1e-3, i
            assert physics(plant, got), i
