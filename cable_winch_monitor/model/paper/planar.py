"""Seed 002, 3.3: adjacent cables of equal length, solved as a planar mechanism.

With l1 = l2 and l3 = l4 (or l1 = l4 and l2 = l3) and all four cables taut, each equal pair
hangs parallel, the platform only tilts about the axis of the pair and J^T of eq. (8) is
nearly singular, which stalls the spatial solve. Projected on the plane across that axis
(yoz, or xoz for the second case) the pairs become two cables and the platform a triangle
B+ B- C: eqs. (13)-(14), eight equations in B+, B-, C and the pair tensions, solved with
MINPACK's trust-region dogleg (hybr). B_i and C follow from the projections, and
T = pinv(J^T) F from the spatial structure matrix. Only for the paper's rectangle.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..plantfile.plant import Plant
from ..statics.geometry import structure_matrix
from .equal_lengths import even_tensions, level_pose


class PlanarResult(NamedTuple):
    points_b: np.ndarray
    point_c: np.ndarray
    tensions: np.ndarray  # [N]
    evaluations: int


def adjacent_pairs(lengths: np.ndarray, tol: float) -> tuple[int, tuple[int, int], tuple[int, int]] | None:
    """(axis of the projection, cables on its + side, cables on its - side) or None.

    l1 = l2, l3 = l4, l1 != l3: project on yoz (axis y, cables 1, 2 at y = +b);
    l1 = l4, l2 = l3, l1 != l2: project on xoz (axis x, cables 1, 4 at x = +a).
    """
    l1, l2, l3, l4 = lengths
    if abs(l1 - l2) <= tol and abs(l3 - l4) <= tol and abs(l1 - l3) > tol:
        return 1, (0, 1), (2, 3)
    if abs(l1 - l4) <= tol and abs(l2 - l3) <= tol and abs(l1 - l2) > tol:
        return 0, (0, 3), (1, 2)
    return None


def solve_planar(plant: Plant, lengths: np.ndarray, tol: float, load: np.ndarray) -> PlanarResult | None:
    """Pose and tensions of the planar model, or None if the case does not apply or hybr fails."""
    pairs = adjacent_pairs(lengths, tol)
    if plant.rectangle is None or pairs is None:
        return None
    axis, plus, minus = pairs
    plane = [axis, 2]
    anchor_p, anchor_m = plant.anchors[plus[0], plane], plant.anchors[minus[0], plane]
    body_p, body_m, body_c = plant.attachments[plus[0], plane], plant.attachments[minus[0], plane], plant.cog[plane]
    width, r_p, r_m = (float(np.linalg.norm(body_p - body_m)), float(np.linalg.norm(body_c - body_p)),
                       float(np.linalg.norm(body_c - body_m)))
    l_p, l_m = float(np.mean(lengths[list(plus)])), float(np.mean(lengths[list(minus)]))
    scale = plant.moment_scale

    def cross(u: np.ndarray, v: np.ndarray) -> float:
        return float(u[0] * v[1] - u[1] * v[0])

    def equations(x: np.ndarray) -> np.ndarray:
        """Eq. (13) as (|PQ|^2 - d^2) / 2d and eq. (14) per mg, moments also per max |CB_i|."""
        p, m, c, (t_p, t_m) = x[0:2], x[2:4], x[4:6], x[6:8]
        u_p, u_m = (p - anchor_p) / l_p, (m - anchor_m) / l_m
        return np.array([
            (np.sum((p - anchor_p) ** 2) - l_p ** 2) / (2.0 * l_p),
            (np.sum((m - anchor_m) ** 2) - l_m ** 2) / (2.0 * l_m),
            (np.sum((p - m) ** 2) - width ** 2) / (2.0 * width),
            (np.sum((c - p) ** 2) - r_p ** 2) / (2.0 * r_p),
            (np.sum((c - m) ** 2) - r_m ** 2) / (2.0 * r_m),
            t_p * u_p[0] + t_m * u_m[0],
            t_p * u_p[1] + t_m * u_m[1] + 1.0,
            (t_p * cross(p - c, u_p) + t_m * cross(m - c, u_m)) / scale,
        ])

    rotation, position = level_pose(plant, float(np.mean(lengths)))
    guess_b = position + plant.attachments @ rotation.T
    guess_c = position + rotation @ plant.cog
    even = even_tensions(plant, guess_b, guess_c, load)
    assert even is not None  # the rectangle hangs plumb at its level pose, where eq. (12) gives the tensions
    weight = float(np.linalg.norm(load[:3]))
    start = np.concatenate([guess_b[plus[0], plane], guess_b[minus[0], plane], guess_c[plane],
                            [even[list(plus)].sum() / weight, even[list(minus)].sum() / weight]])
    from scipy.optimize import root  # imported on first use: scipy.optimize takes 0.4 s to load
    result = root(equations, start, method="hybr", options={"xtol": 1e-14})
    if not np.all(np.isfinite(result.x)):
        return None
    points_b, point_c = guess_b.copy(), guess_c.copy()
    for cables, point in ((plus, result.x[0:2]), (minus, result.x[2:4])):
        for k in cables:
            points_b[k, plane] = point
    point_c[plane] = result.x[4:6]
    tensions = np.linalg.pinv(structure_matrix(plant, points_b, point_c)) @ load
    return PlanarResult(points_b, point_c, tensions, int(result.nfev))
