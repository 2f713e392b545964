"""A platform hanging from one cable: the poses it can take and the range it can turn through.

With one taut cable the only equilibria have A_i, B_i and C on one plumb line; the
platform is then free to turn about that line wherever the other three cables stay
slack (seed 002, 3.1). This module finds that range numerically, by sampling the spans
of the other cables over a full turn and refining each crossing with Brent's method, so
it serves as an independent check of the paper's closed-form critical lengths.
"""
from __future__ import annotations

import numpy as np

from ..plantfile.plant import Plant
from ..statics.geometry import rotation_about_z, rotation_aligning

TWO_PI = 2.0 * np.pi
SAMPLES = 720


def lowest_hang_cable(plant: Plant, lengths: np.ndarray) -> int:
    """The only cable that can carry the platform alone: the one that lets C hang lowest.

    At any admissible pose z_C >= z_Ai - l_i - r_i for every cable i, so hanging from
    cable j (z_C = z_Aj - l_j - r_j) is admissible only where that depth is the lowest.
    """
    return int(np.argmin(lengths + plant.cog_distances - plant.anchors[:, 2]))


class PlumbHang:
    """The one-parameter family of poses of a platform hanging from cable `cable` alone."""

    def __init__(self, plant: Plant, cable: int, length: float):
        self.plant, self.cable = plant, cable
        self.tilt = rotation_aligning(plant.cog - plant.attachments[cable], np.array([0.0, 0.0, -1.0]))
        self.top = plant.anchors[cable] - np.array([0.0, 0.0, length])
        self.offsets = (plant.attachments - plant.attachments[cable]) @ self.tilt.T
        neighbour = (cable + 1) % 4
        towards = plant.anchors[neighbour] - plant.anchors[cable]
        self.reference = float(np.arctan2(towards[1], towards[0])
                               - np.arctan2(self.offsets[neighbour, 1], self.offsets[neighbour, 0]))

    def shortest_spans(self) -> np.ndarray:
        """The smallest |A_k B_k| over a full turn (the minimal critical lengths of 3.1.1)."""
        radius = np.linalg.norm(self.offsets[:, :2], axis=1)
        reach = np.linalg.norm(self.plant.anchors[:, :2] - self.top[:2], axis=1)
        height = self.top[2] + self.offsets[:, 2] - self.plant.anchors[:, 2]
        return np.hypot(reach - radius, height)

    def pose(self, theta: float) -> tuple[np.ndarray, np.ndarray]:
        """Rotation and position of the platform turned by theta from the reference pose.

        The reference (theta = 0) is the pose in which the next cable's span is shortest,
        the initial pose of seed 002, Fig. 5.
        """
        rotation = rotation_about_z(theta + self.reference) @ self.tilt
        position = self.top - rotation @ self.plant.attachments[self.cable]
        return rotation, position

    def spans(self, theta: float) -> np.ndarray:
        """|A_k B_k| for every cable k at angle theta."""
        rotation, position = self.pose(theta)
        return np.linalg.norm(position + self.plant.attachments @ rotation.T - self.plant.anchors, axis=1)

    def rotation_range(self, lengths: np.ndarray) -> tuple[tuple[float, float], ...]:
        """Intervals of theta in [0, 2 pi] where every other cable satisfies |A_k B_k| <= l_k."""
        others = [k for k in range(4) if k != self.cable]

        def margin(theta: float) -> float:
            spans = self.spans(theta)
            return float(max(spans[k] - lengths[k] for k in others))

        from scipy.optimize import brentq  # imported on first use: scipy.optimize takes 0.4 s to load

        grid = np.linspace(0.0, TWO_PI, SAMPLES + 1)
        values = np.array([margin(t) for t in grid])
        edges = [0.0]
        for k in range(SAMPLES):
            if (values[k] <= 0.0) != (values[k + 1] <= 0.0):
                edges.append(brentq(margin, grid[k], grid[k + 1], xtol=1e-13))
        edges.append(TWO_PI)
        intervals = [(lo, hi) for lo, hi in zip(edges[:-1], edges[1:]) if hi > lo and margin(0.5 * (lo + hi)) <= 0.0]
        return tuple((float(lo), float(hi)) for lo, hi in intervals)
