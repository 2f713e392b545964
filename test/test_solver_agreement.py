"""The energy solver and seed 002's traversal algorithm agree on random cable lengths.

Lengths span a realistic shaft (5 to 800 m of payout) with synchronisation errors up to
2 m, in families chosen so that every tension state occurs (see `random_lengths`).

One physical limit shapes the comparison: near-vertical ropes that are all four taut
share the load through a structure matrix whose smallest singular value is 1e-7..1e-5
of the largest. The load can shift along that direction, (-1, 1, -1, 1) for the
rectangle, with a change of one length below the 1e-13 m that double precision resolves
(a 2.8e-14 m change moves the exact tensions by about 5 N). Along that one direction
the rigid model does not determine the tensions, exactly as it does not for four equal
lengths (seed 002, 3.2); every other component must agree within 1 N.
"""
from __future__ import annotations

import numpy as np
import pytest

from cable_winch_monitor.model.geometry import structure_matrix
from cable_winch_monitor.model.result import SolveStatus, check_physics
from cable_winch_monitor.model.solve import solve

SAMPLES = 2000
CONDITION_LIMIT = 1e-5  # smallest/largest singular value below which one direction is unresolved


def random_lengths(count: int, seed: int = 2002, on_plane: bool = False) -> np.ndarray:
    """Payouts of 5-800 m plus per-cable offsets of up to 2 m.

    Four families of equal size: log-uniform spreads (millimetres to metres), uniform
    spreads, adjacent pairs of equal length (l1 = l2, l3 = l4 or l1 = l4, l2 = l3: seed
    002, 3.3, all four taut), and one cable 0.5-2 m shorter than the others (where the
    platform may hang from it alone). With on_plane, lengths on l1 + l3 = l2 + l4
    instead, near which all four cables can be taut without any symmetry.
    """
    rng = np.random.default_rng(seed)
    family = np.arange(count) % 4
    payout = rng.uniform(5.0, 800.0, count)
    spread = np.where(family == 1, rng.uniform(0.0, 2.0, count), 10.0 ** rng.uniform(-3.0, np.log10(2.0), count))
    lengths = payout[:, None] + rng.uniform(0.0, 1.0, (count, 4)) * spread[:, None]
    if on_plane:
        lengths[:, 3] = lengths[:, 0] + lengths[:, 2] - lengths[:, 1]
        return lengths
    pairs = np.flatnonzero(family == 2)
    swap = rng.integers(0, 2, pairs.size).astype(bool)
    lengths[pairs, 1] = np.where(swap, lengths[pairs, 2], lengths[pairs, 0])
    lengths[pairs, 3] = np.where(swap, lengths[pairs, 0], lengths[pairs, 2])
    short = np.flatnonzero(family == 3)
    lengths[short, rng.integers(0, 4, short.size)] -= rng.uniform(0.5, 2.0, short.size)
    return lengths


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
    assert sizes == {2, 3, 4}
    assert len(single) >= 20


def test_same_state_pose_and_tensions(plant, solved_pairs):
    disagreements = []
    for lengths, energy, traversal in solved_pairs:
        same_state = energy.status is traversal.status and energy.taut_set == traversal.taut_set
        if not same_state:
            disagreements.append((lengths.tolist(), energy.tension_state, traversal.tension_state))
            continue
        if energy.status is SolveStatus.SINGLE_CABLE_INDETERMINATE:
            np.testing.assert_allclose(energy.rotation_range, traversal.rotation_range, atol=1e-6)
            continue
        assert energy.ok, energy.message
        np.testing.assert_allclose(energy.points_b, traversal.points_b, atol=1e-3, err_msg=str(lengths))
        np.testing.assert_allclose(energy.point_c, traversal.point_c, atol=1e-3, err_msg=str(lengths))
        np.testing.assert_allclose(resolved_tensions(plant, energy), resolved_tensions(plant, traversal),
                                   atol=1.0, err_msg=str(lengths))
    assert not disagreements, disagreements[:10]


def test_unresolved_direction_only_with_four_taut(plant, solved_pairs):
    """The projection above touches only nearly singular four-taut states."""
    touched = [e for _, e, _ in solved_pairs if e.ok and not np.allclose(resolved_tensions(plant, e), e.tensions)]
    assert all(len(e.taut_set) == 4 for e in touched)


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
    for lengths in random_lengths(400, seed=4004, on_plane=True):
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
