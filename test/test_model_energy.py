"""The energy-minimum solver: seed 002's examples, physics of every solution, warm starts, bad input."""
from __future__ import annotations

import numpy as np
import pytest

from cable_winch_monitor import seed002
from cable_winch_monitor.demo import table2_values
from cable_winch_monitor.model.energy import solve_energy
from cable_winch_monitor.model.plant import plant_from_mapping
from cable_winch_monitor.model.result import SolveStatus, check_physics


@pytest.mark.parametrize("example", [2, 3, 4])
def test_table2_reproduced(plant, example):
    solution = solve_energy(plant, seed002.TABLE_1[example])
    assert solution.ok, solution.message
    assert solution.taut_set == seed002.TAUT_SETS[example]
    assert check_physics(plant, solution).passes()
    expected = np.array(seed002.TABLE_2[example])
    for (ex, row), value in seed002.MISPRINTS.items():
        if ex == example:
            expected[seed002.TABLE_2_ROWS.index(row)] = value
    np.testing.assert_allclose(table2_values(solution), expected, atol=seed002.TABLE_2_TOLERANCE)


def test_example3_tau2_is_a_misprint(plant):
    """Two vertical taut cables: tau1 + tau2 = mg and tau1 (1 - k1) a = tau2 (1 + k1) a."""
    solution = solve_energy(plant, seed002.TABLE_1[3])
    tau1, tau2 = solution.tensions[:2]
    assert tau1 + tau2 == pytest.approx(plant.weight, rel=1e-9)
    assert tau1 * 0.75 == pytest.approx(tau2 * 1.25, rel=1e-9)
    assert tau2 / 1e3 == pytest.approx(36.750, abs=1e-3)
    assert seed002.TABLE_2[3][13] == 38.750


def test_example1_single_cable(plant):
    solution = solve_energy(plant, seed002.TABLE_1[1])
    assert solution.status is SolveStatus.SINGLE_CABLE_INDETERMINATE
    assert solution.single_cable == 0 and solution.points_b is None
    (lo1, hi1), (lo2, hi2) = solution.rotation_range
    (plo1, phi1), (plo2, phi2) = seed002.EXAMPLE_1_RANGE
    assert lo1 == 0.0 and hi2 == pytest.approx(2 * np.pi)
    assert abs(hi1 - phi1) < 0.02 and abs(lo2 - plo2) < 0.02


def test_equal_lengths_most_even_distribution(plant):
    solution = solve_energy(plant, [37.0] * 4)
    np.testing.assert_allclose(solution.tensions / plant.weight, [0.3625, 0.2375, 0.1375, 0.2625], atol=1e-9)
    np.testing.assert_allclose(solution.points_b[:, 2], -37.0, atol=1e-12)
    assert check_physics(plant, solution).passes()


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


@pytest.mark.parametrize("lengths, words", [
    ([np.nan, 20, 20, 20], "finite"), ([np.inf, 20, 20, 20], "finite"), ([-1, 20, 20, 20], "positive"),
    ([0, 20, 20, 20], "positive"), ([20, 20, 20], "exactly 4"), ([20] * 5, "exactly 4"), (["a", 1, 2, 3], "numbers"),
    (None, "exactly 4"), ("20 20 20 20", "numbers"),
])
def test_bad_lengths_get_a_status_and_a_reason(plant, lengths, words):
    solution = solve_energy(plant, lengths)
    assert solution.status is SolveStatus.INVALID_INPUT
    assert words in solution.message


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
