"""Seed 002, 3.1: critical lengths, and whether one cable can carry the platform alone.

Hanging from cable i alone, B_i lies plumb below A_i at depth l_i and C plumb below B_i,
so the pose is fixed up to a turn theta about the vertical through A_i. In the initial
pose (theta = 0) the next cable's attachment B_j, j = i + 1, lies in the vertical plane
through A_i and A_j on A_j's side: its span is then the minimal critical length. Turning
by theta moves every B_j on a horizontal circle (eq. 11), and with rho, psi the horizontal
distance and direction from A_i to A_j and z the height of A_j above B_j

    l_j(theta)^2 = rho^2 + d_j^2 + z^2 - 2 d_j rho cos(theta + theta_j - psi).

phi_j = {theta: l_j(theta) <= l_j} and phi = the intersection over j != i; the platform
hangs from cable i alone when phi is not empty. The paper solves l_j(theta) = l_j by
interval analysis; the cosine form above gives both roots in closed form, exactly, and the
paper's midpoint rule then picks the sub-intervals of [0, 2 pi].
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..plantfile.plant import CABLE_NAMES, Plant
from ..statics.geometry import rotation_about_z, rotation_aligning

TWO_PI = 2.0 * np.pi
Intervals = tuple[tuple[float, float], ...]
DOWN = np.array([0.0, 0.0, -1.0])


def initial_pose(plant: Plant, cable: int, length: float) -> tuple[np.ndarray, np.ndarray]:
    """Rotation and position of the initial pose of Fig. 5 for `cable` (0-based) hanging alone.

    The body is tilted so that C - B_i points straight down, then turned about the vertical
    so that the next cable's attachment faces the next anchor.
    """
    tilt = rotation_aligning(plant.cog - plant.attachments[cable], DOWN)
    nxt = (cable + 1) % 4
    offset = tilt @ (plant.attachments[nxt] - plant.attachments[cable])
    towards = plant.anchors[nxt] - plant.anchors[cable]
    rotation = rotation_about_z(np.arctan2(towards[1], towards[0]) - np.arctan2(offset[1], offset[0])) @ tilt
    position = plant.anchors[cable] + length * DOWN - rotation @ plant.attachments[cable]
    return rotation, position


@dataclass(frozen=True)
class CriticalLengths:
    """The circles of eq. (11) for every cable j while cable `cable` carries the platform.

    Entries of the (4,) arrays for j == cable are zero (d, rho) or meaningless.
    """

    cable: int
    points_b: np.ndarray  # B_1..B_4 in the initial pose, shape (4, 3)
    point_c: np.ndarray
    d: np.ndarray  # radius of B_j's circle about the vertical through A_i
    theta: np.ndarray  # direction of d_j from the x axis
    z: np.ndarray  # height of B_j
    rho: np.ndarray  # horizontal distance A_i -> A_j
    psi: np.ndarray  # horizontal direction A_i -> A_j
    height: np.ndarray  # A_j,z - z_j
    l_min: np.ndarray
    l_max: np.ndarray

    def span(self, j: int, theta: float | np.ndarray) -> np.ndarray:
        """l_j(theta) = |A_j B_j| after turning by theta."""
        square = (self.rho[j] ** 2 + self.d[j] ** 2 + self.height[j] ** 2
                  - 2.0 * self.d[j] * self.rho[j] * np.cos(np.asarray(theta) + self.theta[j] - self.psi[j]))
        return np.sqrt(np.maximum(square, 0.0))

    def range_of(self, j: int, length: float) -> Intervals:
        """phi_j: the turns theta in [0, 2 pi] with l_j(theta) <= length."""
        if length <= self.l_min[j]:
            return ()
        if length >= self.l_max[j]:
            return ((0.0, TWO_PI),)
        cosine = (self.rho[j] ** 2 + self.d[j] ** 2 + self.height[j] ** 2 - length ** 2) / (2.0 * self.d[j] * self.rho[j])
        centre, half = self.psi[j] - self.theta[j], float(np.arccos(cosine))
        roots = sorted(float(np.mod(centre + s * half, TWO_PI)) for s in (-1.0, 1.0))
        edges = [0.0, *roots, TWO_PI]
        return tuple((lo, hi) for lo, hi in zip(edges[:-1], edges[1:])
                     if hi > lo and self.span(j, 0.5 * (lo + hi)) <= length)


def critical_lengths(plant: Plant, cable: int, length: float) -> CriticalLengths:
    """d_j, theta_j, z_j and l_jmin, l_jmax for `cable` (0-based) hanging alone at `length`."""
    rotation, position = initial_pose(plant, cable, length)
    points_b = position + plant.attachments @ rotation.T
    radial = points_b[:, :2] - plant.anchors[cable, :2]
    reach = plant.anchors[:, :2] - plant.anchors[cable, :2]
    d, rho = np.linalg.norm(radial, axis=1), np.linalg.norm(reach, axis=1)
    height = plant.anchors[:, 2] - points_b[:, 2]
    return CriticalLengths(
        cable=cable, points_b=points_b, point_c=position + rotation @ plant.cog, d=d,
        theta=np.arctan2(radial[:, 1], radial[:, 0]), z=points_b[:, 2], rho=rho,
        psi=np.arctan2(reach[:, 1], reach[:, 0]), height=height,
        l_min=np.hypot(rho - d, height), l_max=np.hypot(rho + d, height),
    )


def intersect(a: Intervals, b: Intervals) -> Intervals:
    """The intersection of two unions of closed intervals."""
    pieces = ((max(lo1, lo2), min(hi1, hi2)) for lo1, hi1 in a for lo2, hi2 in b)
    return tuple(sorted((lo, hi) for lo, hi in pieces if hi > lo))


def rotation_range(plant: Plant, lengths: np.ndarray, cable: int) -> tuple[Intervals, CriticalLengths]:
    """phi = intersection of phi_j over j != cable, and the critical lengths behind it."""
    critical = critical_lengths(plant, cable, float(lengths[cable]))
    phi: Intervals = ((0.0, TWO_PI),)
    for j in range(4):
        if j != cable:
            phi = intersect(phi, critical.range_of(j, float(lengths[j])))
    return phi, critical


def describe(critical: CriticalLengths, lengths: np.ndarray) -> dict[str, Any]:
    """JSON-ready l_jmin, l_jmax and phi_j of the cables other than the hanging one."""
    return {CABLE_NAMES[j]: {"l_min": float(critical.l_min[j]), "l_max": float(critical.l_max[j]),
                             "phi": [list(i) for i in critical.range_of(j, float(lengths[j]))]}
            for j in range(4) if j != critical.cable}
