"""The energy solver and seed 002's traversal algorithm agree on random cable lengths.

2,000 random length vectors over a realistic shaft (5 to 800 m of payout, differences
up to 2 m, every state from one to three taut cables) must give the same state, poses
within 1 mm and tensions within 1 N.

Four taut ropes are a thin sliver of length space (l1 + l3 = l2 + l4 to the micrometre),
reached here only by construction, in two families tested apart: adjacent equal pairs
(seed 002, 3.3) and unsymmetric lengths on that plane. There the structure matrix is
nearly singular (smallest singular value 1e-7..1e-5 of the largest) and the load can
shift along one direction, (-1, 1, -1, 1) for the rectangle, with changes of a length
below the 1e-13 m double precision resolves (a 2.8e-14 m change moves the exact
tensions by about 5 N). Along that one direction the rigid model does not determine the
tensions, as at four equal lengths (3.2); every other component must agree within 1 N.
"""
from __future__ import annotations

import numpy as np
import pytest
from lengths import random_lengths

from cable_winch_monitor.model.solvers.solve import solve
from cable_winch_monitor.model.statics.geometry import structure_matrix
from cable_winch_monitor.model.statics.result import SolveStatus, check_physics

SAMPLES = 2000
CONDITION_LIMIT = 1e-5  # smallest/largest singular value below which one direction is unresolved


def resolved_tensions(plant, solution) -> np.ndarray:
    """Tensions with the component along an unresolved direction of the taut cables removed."""
    taut = solution.taut
    structure = structure_matrix(plant, solution.points_b, solution.point_c)[:, taut]
    _, sigma, vt = np.linalg.svd(structure)
    tensions = solution.tensions.copy()
    if sigma[-1] < CONDITION_LIMIT * sigma[0]:
        direction = np.zeros(4)
        direction[taut] = vt[-1]
        tensions -= (tensions @ direction) * direction
    return tensions


@pytest.fixture(scope="module")
def solved_pairs(plant):
    return [(lengths, solve(plant, lengths, "energy"), solve(plant, lengths, "traversal"))
            for lengths in random_lengths(SAMPLES)]


def test_every_state_occurs(solved_pairs):
    sizes = {len(energy.taut_set) for _, energy, _ in solved_pairs if energy.ok}
    single = [e for _, e, _ in solved_pairs if e.status is SolveStatus.SINGLE_CABLE_INDETERMINATE]
    assert sizes == {2, 3}
    assert len(single) >= 20


def test_same_state_pose_and_tensions(solved_pairs):
    disagreements = []
    for lengths, energy, traversal in solved_pairs:
        if energy.status is not traversal.status or energy.taut_set != traversal.taut_set:
            disagreements.append((lengths.tolist(), energy.tension_state, traversal.tension_state))
            continue
        if energy.status is SolveStatus.SINGLE_CABLE_INDETERMINATE:
            np.testing.assert_allclose(energy.rotation_range, traversal.rotation_range, atol=1e-6)
            continue
        assert energy.ok, energy.message
        np.testing.assert_allclose(energy.points_b, traversal.points_b, atol=1e-3, err_msg=str(lengths))
        np.testing.assert_allclose(energy.point_c, traversal.point_c, atol=1e-3, err_msg=str(lengths))
        np.testing.assert_allclose(energy.tensions, traversal.tensions, atol=1.0, err_msg=str(lengths))
    assert not disagreements, disagreements[:10]


def test_adjacent_equal_lengths_agree_but_along_the_open_direction(plant):
    """Seed 002's 3.3 case, all four taut: same state and pose; the tensions agree within
    1 N once the component along the unresolved direction is set aside."""
    for lengths in random_lengths(300, seed=3003, family="adjacent_equal"):
        energy, traversal = solve(plant, lengths, "energy"), solve(plant, lengths, "traversal")
        assert energy.status is traversal.status and energy.taut_set == traversal.taut_set, lengths
        if not energy.ok:
            continue
        for solution in (energy, traversal):
            assert check_physics(plant, solution).passes(), (solution.method, lengths)
        np.testing.assert_allclose(energy.points_b, traversal.points_b, atol=1e-3)
        np.testing.assert_allclose(resolved_tensions(plant, energy), resolved_tensions(plant, traversal), atol=1.0)


def test_every_solution_passes_the_physics(plant, solved_pairs):
    for _, energy, traversal in solved_pairs:
        for solution in (energy, traversal):
            if solution.ok:
                check = check_physics(plant, solution)
                assert check.passes(), (solution.method, solution.lengths, check)


def test_on_the_plane_the_rigid_model_leaves_the_load_split_open(plant):
    """Lengths with l1 + l3 = l2 + l4 and no symmetry: the energy solver always finds the
    equilibrium; the published traversal, whose dogleg starts from the level pose, does
    not always converge on the nearly singular four-cable system (the failure seed 002,
    3.3, cures only for symmetric lengths). Where both solve, the pose agrees and the
    tensions differ only along the unresolved direction or in cables that touch their
    length within rounding in both solutions (taut with zero tension, or slack by 0 m)."""
    failures = 0
    for lengths in random_lengths(400, seed=4004, family="plane"):
        energy, traversal = solve(plant, lengths, "energy"), solve(plant, lengths, "traversal")
        if energy.status is SolveStatus.SINGLE_CABLE_INDETERMINATE:
            assert traversal.single_cable == energy.single_cable
            continue
        assert energy.ok and check_physics(plant, energy).passes(), energy.message
        if traversal.status is SolveStatus.NO_EQUILIBRIUM:
            failures += 1
            continue
        assert traversal.ok and check_physics(plant, traversal).passes()
        np.testing.assert_allclose(energy.points_b, traversal.points_b, atol=1e-3)
        touching = np.abs(energy.lengths - energy.spans) < 1e-9
        differing = energy.taut != traversal.taut
        assert np.all(touching[differing] & (np.abs(traversal.lengths - traversal.spans) < 1e-9)[differing])
        if not differing.any():
            np.testing.assert_allclose(resolved_tensions(plant, energy), resolved_tensions(plant, traversal), atol=1.0)
    print(f"traversal found no equilibrium for {failures} of 400 lengths on the plane")
    assert failures < 0.2 * 400, failures
