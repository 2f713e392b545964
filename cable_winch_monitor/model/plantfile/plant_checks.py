"""Geometry a four-cable plant cannot have: what makes its equilibrium meaningless, in words."""
from __future__ import annotations

import numpy as np

COINCIDENT = 1e-3  # [m] two points closer than this are one point
COLLINEAR = 1e-6  # second singular value / first below this: the points lie on one line


def degenerate_points(points: np.ndarray) -> str:
    """Why four anchor or attachment points (4, 3) cannot carry a platform ('' if they can).

    Two points in one place make two cables one; four points on one line leave the
    platform free to turn about that line.
    """
    for i in range(len(points)):
        for j in range(i + 1, len(points)):
            if np.linalg.norm(points[i] - points[j]) < COINCIDENT:
                return f"points {i + 1} and {j + 1} are identical (closer than {COINCIDENT * 1e3:g} mm)"
    singular = np.linalg.svd(points - points.mean(axis=0), compute_uv=False)
    if singular[1] <= COLLINEAR * singular[0]:
        return "all points lie on one line: the platform could turn about it"
    return ""
