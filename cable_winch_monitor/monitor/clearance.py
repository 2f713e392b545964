"""Horizontal clearance between the platform outline and the shaft wall."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..model.plant import Plant
from ..model.plumb_hang import PlumbHang
from ..model.result import Solution

SWING_SAMPLES_PER_RAD = 60


@dataclass(frozen=True)
class Clearance:
    """Smallest horizontal distance [m] from any outline point to the wall (negative: through it)."""

    value: float
    point_name: str
    point_platform: np.ndarray
    point_shaft: np.ndarray


def _outline(plant: Plant) -> tuple[np.ndarray, list[str]]:
    if not plant.outline:
        raise ValueError("the plant file has no 'outline': clearance needs the platform's deck points")
    return np.array([p.position for p in plant.outline]), [p.name for p in plant.outline]


def clearance_at_pose(plant: Plant, rotation: np.ndarray, position: np.ndarray) -> Clearance:
    """Clearance of the outline at one platform pose."""
    body, names = _outline(plant)
    world = position + body @ rotation.T
    gaps = plant.shaft_radius - np.linalg.norm(world[:, :2] - plant.shaft_centre, axis=1)
    k = int(np.argmin(gaps))
    return Clearance(float(gaps[k]), names[k], body[k], world[k])


def swing_clearance(plant: Plant, solution: Solution) -> Clearance:
    """Worst clearance over every pose a single-cable platform can turn to (its range phi)."""
    hang = PlumbHang(plant, solution.single_cable, float(solution.lengths[solution.single_cable]))
    worst: Clearance | None = None
    for lo, hi in solution.rotation_range:
        for theta in np.linspace(lo, hi, max(2, int((hi - lo) * SWING_SAMPLES_PER_RAD) + 1)):
            rotation, position = hang.pose(theta)
            candidate = clearance_at_pose(plant, rotation, position)
            if worst is None or candidate.value < worst.value:
                worst = candidate
    return worst


def solution_clearance(plant: Plant, solution: Solution) -> Clearance | None:
    """Clearance of a solved pose, or the worst over the swing of a single-cable state; None otherwise."""
    if solution.ok:
        return clearance_at_pose(plant, solution.rotation, solution.position)
    if solution.single_cable is not None and solution.rotation_range:
        return swing_clearance(plant, solution)
    return None
