"""The energy-minimum solver: warm starts, general plants, the physics check.

The worked examples and bad input, shared with the traversal, are in test_seed002_examples.py.
"""
from __future__ import annotations

import numpy as np

from cable_winch_monitor.model.plantfile.plant import plant_from_mapping
from cable_winch_monitor.model.solvers.energy import solve_energy
from cable_winch_monitor.model.statics.result import check_physics


def test_warm_start_follows_a_lowering(plant):
    """Warm-started solves along a trajectory equal cold solves, mostly in two or three Newton steps."""
    rng = np.random.default_rng(3)
    previous, steps = None, []
    for depth in np.linspace(50.0, 60.0, 40):
        lengths = depth + np.array([0.0, 0.05, 0.1, 0.02]) + rng.normal(0.0, 0.01, 4)
        warm = solve_energy(plant, lengths, warm_start=previous)
        cold = solve_energy(plant, lengths)
        assert warm.taut_set == cold.taut_set
        np.testing.assert_allclose(warm.points_b, cold.points_b, atol=1e-6)
        np.testing.assert_allclose(warm.tensions, cold.tensions, atol=1e-3)
        if previous is not None:
            steps.append(warm.iterations)
        previous = warm
    assert np.median(steps) <= 3 and max(steps) <= 40


def test_plant_given_by_points(plant):
    """A plant that is not a rectangle: trapezoidal attachments, offset centre of gravity."""
    config = {"plant": {"mass": 8000.0, "g": 9.81, "geometry": {
        "anchors": [[2.2, 2.4, 0.0], [-1.8, 2.6, 0.1], [-2.1, -2.5, 0.0], [2.0, -2.3, -0.1]],
        "attachments": [[1.8, 2.0, 0.0], [-1.6, 2.2, 0.0], [-2.0, -2.1, 0.0], [1.9, -2.0, 0.0]],
        "centre_of_gravity": [0.3, -0.2, -8.0]}}}
    other = plant_from_mapping(config)
    for lengths in ([30.0, 30.2, 30.1, 30.05], [30.0] * 4, [30.0, 30.0, 30.3, 30.3]):
        solution = solve_energy(other, lengths)
        assert solution.ok, solution.message
        assert check_physics(other, solution).passes()


def test_physics_check_catches_what_it_must(plant):
    """The check fails on unbalanced tensions, a mirror image and an overstretched cable."""
    from dataclasses import replace

    good = solve_energy(plant, [20.3, 20.1, 20.5, 20.2])
    assert check_physics(plant, good).passes()
    unbalanced = replace(good, tensions=good.tensions * 1.01)
    assert not check_physics(plant, unbalanced).passes()
    mirror = np.diag([1.0, 1.0, -1.0])
    mirrored = replace(good, points_b=good.points_b @ mirror, point_c=good.point_c @ mirror)
    assert check_physics(plant, mirrored).mirrored
    stretched = replace(good, lengths=good.lengths - np.array([0.01, 0.0, 0.0, 0.0]))
    assert check_physics(plant, stretched).max_overstretch > 0.009
    assert not check_physics(plant, stretched).passes()
