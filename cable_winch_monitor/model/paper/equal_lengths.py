"""Seed 002, 3.2: four equal cable lengths, and the most even tension distribution.

With equal lengths the platform hangs level, every cable plumb, and J^T tau = F has rank 3
in four tensions: eq. (12) is the family tau(tau4), tau >= 0 bounds tau4 to one of four
intervals set by k1, k2, and the paper picks the member with the least tension difference
Delta T (tau4*, clipped to the interval). Since sum(tau) = mg is fixed,
Delta T^2 = 4 |tau|^2 - (sum tau)^2, so least Delta T is the least-norm non-negative
solution of J^T tau = F; that form serves plants that are not the paper's rectangle.
"""
from __future__ import annotations

import numpy as np

from ..plantfile.plant import Plant
from ..statics.geometry import structure_matrix
from ..statics.result import Solution, solved
from ..statics.tensions import least_norm_tensions

PLUMB_TOL = 1e-9  # [m] attachments must repeat the anchors' layout for a level, plumb hang


def plumb_when_level(plant: Plant) -> bool:
    """True when the attachments are a translate of the anchors, so equal lengths hang plumb."""
    shift = plant.anchors - plant.attachments
    return bool(np.all(np.abs(shift - shift.mean(axis=0)) <= PLUMB_TOL))


def level_pose(plant: Plant, length: float) -> tuple[np.ndarray, np.ndarray]:
    """Unrotated platform with its attachments on average `length` below their anchors.

    For a plant with plumb_when_level() this is the exact equal-length pose of 3.2
    (B_i = A_i - length e_z); otherwise it is only the guess of 4.1.
    """
    shift = (plant.anchors - plant.attachments).mean(axis=0)
    return np.eye(3), shift - np.array([0.0, 0.0, length])


def tau4_interval(k1: float, k2: float) -> tuple[int, float, float]:
    """The case (1-4) of 3.2 that (k1, k2) falls in, and [tau4L, tau4R] in units of mg."""
    if k2 >= 0.0 and abs(k1) <= abs(k2):
        return 1, 0.0, (1.0 - k2) / 2.0
    if k1 < 0.0 and abs(k1) >= abs(k2):
        return 2, 0.0, (1.0 + k1) / 2.0
    if k2 < 0.0 and abs(k1) <= abs(k2):
        return 3, (k1 - k2) / 2.0, (1.0 + k1) / 2.0
    return 4, (k1 - k2) / 2.0, (1.0 - k2) / 2.0


def tau4_star(k1: float, k2: float) -> float:
    """The unconstrained minimiser of Delta T over eq. (12), in units of mg."""
    return (1.0 + k1 - k2) / 4.0


def rectangle_tensions(k1: float, k2: float) -> np.ndarray:
    """Eq. (12) at the tau4 of least Delta T (tau4* clipped to [tau4L, tau4R]), units of mg."""
    _, low, high = tau4_interval(k1, k2)
    tau4 = min(max(tau4_star(k1, k2), low), high)  # the three rules: tau4L, tau4* or tau4R
    return np.array([(1.0 + k1) / 2.0, (k2 - k1) / 2.0, (1.0 - k2) / 2.0, 0.0]) + tau4 * np.array([-1.0, 1.0, -1.0, 1.0])


def even_tensions(plant: Plant, points_b: np.ndarray, point_c: np.ndarray, load: np.ndarray) -> np.ndarray | None:
    """Least-Delta-T tensions [N] for the platform at (points_b, point_c) under a vertical `load`.

    For the paper's rectangle in its level pose this is eq. (12) with the tau4 rules;
    otherwise the least-norm non-negative balance (None where no tau >= 0 balances).
    """
    if plant.rectangle is not None and np.allclose(points_b[:, :2], plant.anchors[:, :2], rtol=0.0, atol=PLUMB_TOL):
        a, b = plant.rectangle
        return rectangle_tensions(plant.cog[0] / a, plant.cog[1] / b) * float(np.linalg.norm(load[:3]))
    return least_norm_tensions(structure_matrix(plant, points_b, point_c), load)


def solve_equal_lengths(plant: Plant, lengths: np.ndarray, method: str, load: np.ndarray) -> Solution | None:
    """Step (ii): the level pose and least-Delta-T tensions, or None if equal lengths are not special here.

    None when the plant does not hang plumb at equal lengths or no tau >= 0 balances the
    level pose (centre of gravity outside the attachments' support); the traversal goes on.
    """
    if not plumb_when_level(plant):
        return None
    rotation, position = level_pose(plant, float(np.mean(lengths)))
    points_b = position + plant.attachments @ rotation.T
    tensions = even_tensions(plant, points_b, position + rotation @ plant.cog, load)
    if tensions is None:
        return None
    return solved(plant, method, lengths, rotation, position, tensions, tensions > 0.0, iterations=0,
                  message="four equal lengths: level pose, least tension difference (seed 002, 3.2)", load=load,
                  step="ii")
