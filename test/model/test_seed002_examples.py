"""Seed 002's worked examples and bad input, for both solvers: Table 2, the single-cable
range of example 1, the most even distribution at equal lengths, a status for any input."""
from __future__ import annotations

import numpy as np
import pytest

from cable_winch_monitor import seed002
from cable_winch_monitor.demo import table2_values
from cable_winch_monitor.model.solvers.solve import METHODS, solve
from cable_winch_monitor.model.statics.result import SolveStatus, check_physics


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("example", [2, 3, 4])
def test_table2_reproduced(plant, method, example):
    solution = solve(plant, seed002.TABLE_1[example], method)
    assert solution.ok, solution.message
    assert solution.taut_set == seed002.TAUT_SETS[example]
    assert check_physics(plant, solution).passes()
    np.testing.assert_allclose(table2_values(solution), seed002.physical_table2(example),
                               rtol=0.0, atol=seed002.TABLE_2_TOLERANCE)


@pytest.mark.parametrize("method", METHODS)
def test_example3_tau2_is_a_misprint(plant, method):
    """Cables 1, 2 plumb: tau1 + tau2 = mg and tau1 (1 - k1) a = tau2 (1 + k1) a about the CoG line."""
    solution = solve(plant, seed002.TABLE_1[3], method)
    tau1, tau2 = solution.tensions[:2]
    np.testing.assert_allclose(solution.points_b[:2, :2], plant.anchors[:2, :2], atol=1e-9)
    assert tau1 + tau2 == pytest.approx(plant.weight, rel=1e-9)
    assert tau1 * (1.0 - 0.25) == pytest.approx(tau2 * (1.0 + 0.25), rel=1e-9)
    assert tau1 / 1e3 == pytest.approx(61.250, abs=1e-6) and tau2 / 1e3 == pytest.approx(36.750, abs=1e-6)
    assert seed002.TABLE_2[3][seed002.TABLE_2_ROWS.index("tau2_kN")] == 38.750  # as printed


@pytest.mark.parametrize("method", METHODS)
def test_example1_single_cable(plant, method):
    solution = solve(plant, seed002.TABLE_1[1], method)
    assert solution.status is SolveStatus.SINGLE_CABLE_INDETERMINATE
    assert solution.single_cable == 0 and solution.points_b is None
    assert solution.taut_set == (1,)
    np.testing.assert_allclose(solution.tensions, [plant.weight, 0.0, 0.0, 0.0])  # a plumb line carries mg
    assert "cable_1" in solution.message and "alone" in solution.message
    (lo1, hi1), (lo2, hi2) = solution.rotation_range
    (_, paper_hi1), (paper_lo2, _) = seed002.EXAMPLE_1_RANGE
    assert lo1 == 0.0 and hi2 == pytest.approx(2.0 * np.pi)
    assert abs(hi1 - paper_hi1) < 0.02 and abs(lo2 - paper_lo2) < 0.02


@pytest.mark.parametrize("method", METHODS)
def test_equal_lengths_most_even_distribution(plant, method):
    solution = solve(plant, [37.0] * 4, method)
    np.testing.assert_allclose(solution.tensions / plant.weight, [0.3625, 0.2375, 0.1375, 0.2625], atol=1e-9)
    np.testing.assert_allclose(solution.points_b, plant.anchors - [0.0, 0.0, 37.0], atol=1e-9)
    assert check_physics(plant, solution).passes()


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("lengths, words", [
    ([np.nan, 20, 20, 20], "finite"), ([20, np.inf, 20, 20], "finite"), ([-1, 20, 20, 20], "positive"),
    ([0, 20, 20, 20], "positive"), ([20, 20, 20], "exactly 4"), ([20] * 5, "exactly 4"),
    (["a", "b", "c", "d"], "numbers"), (["20", "20", "20", "20"], "numbers"), ("20 20 20 20", "numbers"),
    (None, "got None"), ({"l1": 20}, "numbers"),
])
def test_bad_lengths_get_a_status_and_a_reason(plant, method, lengths, words):
    solution = solve(plant, lengths, method)
    assert solution.status is SolveStatus.INVALID_INPUT
    assert words in solution.message


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("lengths", [[1e300, 1e300, 1e300, 2e300], [1e-300, 1.0, 1.0, 1.0],
                                     [4125.7, 0.0085, 0.011, 83.6]])
def test_extreme_lengths_end_with_a_status(plant, method, lengths):
    """Far outside any shaft: a status and a message, never an exception."""
    solution = solve(plant, lengths, method)
    assert solution.status in tuple(SolveStatus) and solution.message
    if solution.ok:
        assert solution.tensions.min() >= 0.0
