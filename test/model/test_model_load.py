"""The external load is an input of every solver: the balance holds for the load given, not for m g."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cable_winch_monitor.model.paper.traversal import solve_traversal
from cable_winch_monitor.model.plantfile.plant import load_plant
from cable_winch_monitor.model.solvers.batched import solve_batch
from cable_winch_monitor.model.solvers.elastic import solve_elastic
from cable_winch_monitor.model.solvers.energy import solve_energy
from cable_winch_monitor.model.statics import load
from cable_winch_monitor.model.statics.result import SolveStatus, check_physics

PLANT = load_plant()
LENGTHS = np.array([120.3, 120.1, 120.5, 120.2])


def braking(acceleration: float) -> np.ndarray:
    """The platform accelerating downward at `acceleration` [m/s^2]: the ropes carry m (g - a)."""
    return np.array([0.0, 0.0, -PLANT.mass * (PLANT.g - acceleration), 0.0, 0.0, 0.0])


@pytest.mark.parametrize("solver", [
    lambda lengths, load: solve_energy(PLANT, lengths, load=load),
    lambda lengths, load: solve_traversal(PLANT, lengths, load=load),
    lambda lengths, load: solve_batch(PLANT, lengths[None], loads=load).solution(0),
], ids=["energy", "traversal", "batched"])
def test_vertical_load_scales_the_tensions_and_keeps_the_rigid_pose(solver):
    gravity, lighter = solver(LENGTHS, None), solver(LENGTHS, braking(0.5))
    assert gravity.ok and lighter.ok
    assert lighter.taut_set == gravity.taut_set
    np.testing.assert_allclose(lighter.position, gravity.position, atol=1e-9)
    np.testing.assert_allclose(lighter.tensions, gravity.tensions * (PLANT.g - 0.5) / PLANT.g, rtol=1e-9, atol=1e-6)
    assert abs(lighter.tensions.sum() - PLANT.mass * (PLANT.g - 0.5)) < 1e-3 * PLANT.weight  # near-vertical ropes
    assert check_physics(PLANT, lighter).passes()


def test_general_wrench_is_balanced_by_energy_batched_and_elastic_solvers():
    load = np.array([800.0, -500.0, -PLANT.weight, 0.0, 0.0, 2000.0])  # a side pull and a torque about C
    rigid = solve_energy(PLANT, LENGTHS, load=load)
    batched = solve_batch(PLANT, np.vstack([LENGTHS, LENGTHS + 0.01]), loads=load).solution(0)
    elastic = solve_elastic(PLANT, LENGTHS, 7.5e7, load=load)
    for solution in (rigid, batched, elastic):
        assert solution.ok, solution.message
        np.testing.assert_array_equal(solution.load, load)
        structure_force = (solution.points_b - PLANT.anchors) / solution.spans[:, None]
        np.testing.assert_allclose(structure_force.T @ solution.tensions, load[:3], atol=1e-6 * PLANT.weight)
        assert solution.tensions.min() >= 0.0
    assert check_physics(PLANT, rigid).passes() and check_physics(PLANT, batched).passes()
    gravity = solve_energy(PLANT, LENGTHS)
    assert np.linalg.norm(rigid.position[:2] - gravity.position[:2]) > 1e-3  # the side pull moves the platform
    np.testing.assert_allclose(batched.position, rigid.position, atol=1e-6)


@pytest.mark.parametrize("load", [np.array([0.0, 0.0, 5.0e4, 0, 0, 0]), np.array([np.nan, 0, -1e5, 0, 0, 0])])
def test_a_load_ropes_cannot_carry_is_refused(load):
    for solution in (solve_energy(PLANT, LENGTHS, load=load), solve_elastic(PLANT, LENGTHS, 7.5e7, load=load),
                     solve_traversal(PLANT, LENGTHS, load=load)):
        assert solution.status is SolveStatus.INVALID_INPUT and "load" in solution.message


def test_traversal_refuses_a_side_pull_and_names_the_energy_solver():
    solution = solve_traversal(PLANT, LENGTHS, load=np.array([500.0, 0.0, -PLANT.weight, 0.0, 0.0, 0.0]))
    assert solution.status is SolveStatus.INVALID_INPUT and "energy solver" in solution.message


LOAD_VALUES = st.one_of(st.floats(-2e5, 2e5), st.sampled_from([0.0, -0.0, np.nan, np.inf, -np.inf]))


@settings(max_examples=300, deadline=None)
@given(st.lists(st.lists(LOAD_VALUES, min_size=6, max_size=6), max_size=6))
def test_a_batch_of_loads_is_refused_for_its_first_that_ropes_cannot_carry(rows):
    """The rows checked together name the first load that hanging ropes cannot carry (not finite, or not pulling
    down), as checking them one by one does; a batch that they can all carry passes."""
    loads = np.array(rows, dtype=float).reshape(-1, 6)
    first = next((reason for reason in map(load.check, loads) if reason), "")
    assert load.check_rows(loads) == first
    carried = np.isfinite(loads).all(axis=1) & (loads[:, 2] < 0.0)
    assert (first == "") == bool(carried.all())
