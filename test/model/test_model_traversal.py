"""Seed 002's Traversal Solving Algorithm: the special cases of section 3 and its limits.

The worked examples and bad input, shared with the energy solver, are in test_seed002_examples.py.
"""
from __future__ import annotations

import numpy as np
import pytest

from cable_winch_monitor import seed002
from cable_winch_monitor.model.paper.critical_lengths import critical_lengths, initial_pose, rotation_range
from cable_winch_monitor.model.paper.equal_lengths import level_pose, rectangle_tensions, tau4_interval, tau4_star
from cable_winch_monitor.model.paper.planar import solve_planar
from cable_winch_monitor.model.paper.traversal import EQUAL_LENGTH_TOL, solve_traversal
from cable_winch_monitor.model.plantfile.plant import plant_from_mapping
from cable_winch_monitor.model.statics.geometry import rotation_about_z, structure_matrix
from cable_winch_monitor.model.statics.result import SolveStatus, check_physics
from cable_winch_monitor.model.statics.tensions import least_norm_tensions


def rectangle_plant(k1: float = 0.25, k2: float = 0.2, h: float = 10.0):
    return plant_from_mapping({"plant": {"geometry": {"a": 2.0, "b": 2.5, "h": h, "k1": k1, "k2": k2},
                                         "mass": 1e4, "g": 9.8}})


def test_example2_is_the_planar_case(plant):
    """l1 = l2, l3 = l4, all taut: each pair hangs parallel, so pair tensions split as (1 +- k1) / 2."""
    solution = solve_traversal(plant, seed002.TABLE_1[2])
    assert solution.extras["step"] == "vi"
    tau = solution.tensions
    assert tau[0] / tau[1] == pytest.approx(1.25 / 0.75, rel=1e-6)
    assert tau[3] / tau[2] == pytest.approx(1.25 / 0.75, rel=1e-6)
    sigma = np.linalg.svd(structure_matrix(plant, solution.points_b, solution.point_c), compute_uv=False)
    assert sigma[-1] / sigma[0] < 1e-4  # the near-singular J^T that defeats the spatial solve


def test_single_cable_is_the_lowest_hanging_not_the_shortest():
    """Anchor 3 raised 3 m: cable 1 is the shortest, but only cable 3 (least l + r - A_z) can hang alone."""
    corners = [[2.0, 2.5, 0.0], [-2.0, 2.5, 0.0], [-2.0, -2.5, 0.0], [2.0, -2.5, 0.0]]
    anchors = [list(c) for c in corners]
    anchors[2][2] = 3.0
    plant = plant_from_mapping({"plant": {"geometry": {"anchors": anchors, "attachments": corners,
                                                       "centre_of_gravity": [0.0, 0.0, -10.0]}, "mass": 1e4, "g": 9.8}})
    lengths = np.array([21.5, 22.5, 22.0, 22.5])
    assert rotation_range(plant, lengths, 0)[0] == ()
    solution = solve_traversal(plant, lengths)
    assert solution.status is SolveStatus.SINGLE_CABLE_INDETERMINATE and solution.single_cable == 2


def test_critical_lengths_match_the_closed_forms(plant):
    """The general construction of the initial pose reproduces eq. (10), x3, y3 and z2, z3, z4."""
    a, b = plant.rectangle
    r1, r2, r3, _ = plant.cog_distances
    l1 = 20.0
    q = (r2 ** 2 - 4 * a ** 2 - r1 ** 2) / (2 * r1)
    x21, x22, z21 = a - np.sqrt(4 * a ** 2 - q ** 2), a + np.sqrt(4 * a ** 2 - q ** 2), q - l1
    z3 = (r3 ** 2 - 4 * a ** 2 - 4 * b ** 2 - r1 ** 2) / (2 * r1) - l1
    z4 = (r3 ** 2 - r2 ** 2 - 4 * b ** 2) / (2 * r1) - l1
    x3 = (3 * a ** 2 + x21 ** 2 + (z3 - z21) ** 2 - (z3 + l1) ** 2) / (2 * (x21 - a))
    y3 = b - np.sqrt(4 * a ** 2 + 4 * b ** 2 - (z3 + l1) ** 2 - (x3 - a) ** 2)
    critical = critical_lengths(plant, 0, l1)
    np.testing.assert_allclose(critical.points_b[0], [a, b, -l1], atol=1e-12)
    np.testing.assert_allclose(critical.point_c, [a, b, -l1 - r1], atol=1e-12)
    np.testing.assert_allclose(critical.points_b[1], [x21, b, z21], atol=1e-12)
    np.testing.assert_allclose(critical.points_b[2], [x3, y3, z3], atol=1e-12)
    np.testing.assert_allclose(critical.z[1:], [z21, z3, z4], atol=1e-12)
    assert critical.l_min[1] == pytest.approx(np.linalg.norm(plant.anchors[1] - [x21, b, z21]), abs=1e-12)
    assert critical.l_max[1] == pytest.approx(np.linalg.norm(plant.anchors[1] - [x22, b, z21]), abs=1e-12)


def test_eq11_spans_follow_the_turned_body(plant):
    """l_j(theta) in closed form equals |A_j B_j| of the body turned about the vertical through A_1."""
    rotation, position = initial_pose(plant, 0, 20.0)
    critical = critical_lengths(plant, 0, 20.0)
    pivot = plant.anchors[0]
    for theta in np.linspace(0.0, 2.0 * np.pi, 13):
        turned = (position + plant.attachments @ rotation.T - pivot) @ rotation_about_z(theta).T + pivot
        spans = np.linalg.norm(turned - plant.anchors, axis=1)
        np.testing.assert_allclose([critical.span(j, theta) for j in range(4)], spans, atol=1e-12)


def test_rotation_range_ends_are_exact_roots(plant):
    lengths = np.array(seed002.TABLE_1[1])
    critical = critical_lengths(plant, 0, lengths[0])
    for j in (1, 2, 3):
        for lo, hi in critical.range_of(j, lengths[j]):
            for end in (lo, hi):
                if 0.0 < end < 2.0 * np.pi:
                    assert critical.span(j, end) == pytest.approx(lengths[j], abs=1e-12)
            assert critical.span(j, 0.5 * (lo + hi)) <= lengths[j]


@pytest.mark.parametrize("k1, k2, case, clipped", [
    (0.1, 0.5, 1, None),    # case 1, tau4* inside
    (-0.6, 0.2, 2, None),   # case 2, tau4* inside
    (0.5, -0.9, 3, "L"),    # case 3, tau4* = 0.6 below tau4L = 0.7
    (0.9, 0.8, 4, "R"),     # case 4, tau4* = 0.275 above tau4R = 0.1
    (0.25, 0.2, 4, None),   # the seed plant
    (-0.9, 0.9, 1, "L"),    # case 1, tau4* = -0.2 below tau4L = 0
])
def test_tau4_rules(k1, k2, case, clipped):
    """Interval, clipping rule and eq. (12) agree with tau >= 0, the balance and min Delta T."""
    found, low, high = tau4_interval(k1, k2)
    assert found == case
    assert low == pytest.approx(max(0.0, (k1 - k2) / 2)) and high == pytest.approx(min((1 + k1) / 2, (1 - k2) / 2))
    star = tau4_star(k1, k2)
    assert {None: low <= star <= high, "L": star < low, "R": star > high}[clipped]
    tau = rectangle_tensions(k1, k2)
    assert tau.min() >= 0.0 and tau.sum() == pytest.approx(1.0)
    plant = rectangle_plant(k1, k2)
    rotation, position = level_pose(plant, 30.0)
    points_b, point_c = position + plant.attachments @ rotation.T, position + rotation @ plant.cog
    jt = structure_matrix(plant, points_b, point_c)
    np.testing.assert_allclose(jt @ (tau * plant.weight), plant.wrench, atol=1e-9 * plant.weight)
    np.testing.assert_allclose(least_norm_tensions(jt, plant.wrench) / plant.weight, tau, atol=1e-12)
    grid = np.linspace(low, high, 20001)  # brute force over the admissible tau4
    family = np.array([(1 + k1) / 2, (k2 - k1) / 2, (1 - k2) / 2, 0.0]) + grid[:, None] * np.array([-1, 1, -1, 1])
    spread = np.sum((family[:, :, None] - family[:, None, :]) ** 2, axis=(1, 2))
    assert tau[3] == pytest.approx(grid[np.argmin(spread)], abs=1e-4)
    solution = solve_traversal(plant, [30.0] * 4)
    np.testing.assert_allclose(solution.tensions / plant.weight, tau, atol=1e-12)
    assert check_physics(plant, solution).passes()


def test_general_plant_uses_the_affine_b4():
    """A plant that is not a rectangle: solved through the spatial states, never the planar shortcut."""
    plant = plant_from_mapping({"plant": {"geometry": {
        "anchors": [[2.2, 2.6, 0.0], [-1.8, 2.4, 0.1], [-2.1, -2.5, 0.0], [1.9, -2.7, -0.05]],
        "attachments": [[2.0, 2.5, 0.3], [-2.0, 2.3, 0.0], [-2.2, -2.4, 0.0], [2.1, -2.6, -0.2]],
        "centre_of_gravity": [0.3, 0.4, -9.0]}, "mass": 8000.0, "g": 9.81}})
    assert solve_planar(plant, np.array([40.0, 40.0, 41.0, 41.0]), EQUAL_LENGTH_TOL, plant.wrench) is None
    for lengths in ([40.0, 40.3, 40.9, 40.1], [40.0, 40.0, 41.0, 41.0], [40.0] * 4):
        solution = solve_traversal(plant, lengths)
        assert solution.ok, solution.message
        assert check_physics(plant, solution).passes()


def test_random_lengths_never_raise(plant):
    """The cross-check regime (5-800 m, differences up to 2 m): a status always, physics when solved."""
    rng = np.random.default_rng(2)
    for _ in range(60):
        lengths = rng.uniform(5.0, 800.0) + rng.uniform(0.0, 2.0, 4)
        solution = solve_traversal(plant, lengths)
        assert solution.status in (SolveStatus.SOLVED, SolveStatus.SINGLE_CABLE_INDETERMINATE), solution.message
        if solution.ok:
            assert check_physics(plant, solution).passes()
            assert solution.iterations > 0
