"""Horizontal clearance between the platform outline and the shaft wall."""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..frozen import fast_init
from ..model.paper.plumb_hang import PlumbHang
from ..model.plantfile.plant import Plant
from ..model.solvers.batched import BatchSolution
from ..model.statics.result import Solution

SWING_SAMPLES_PER_RAD = 60


@fast_init
@dataclass(frozen=True)
class Clearance:
    """Smallest horizontal distance [m] from any outline point to the wall (negative: through it)."""

    value: float
    point_name: str
    point_platform: np.ndarray
    point_shaft: np.ndarray


def clearances_at_poses(plant: Plant, rotations: np.ndarray, positions: np.ndarray) -> list[Clearance]:
    """Clearance of the outline at each of N poses (rotations (N, 3, 3), positions (N, 3)), computed together."""
    if not plant.outline:
        raise ValueError("the plant file has no 'outline': clearance needs the platform's deck points")
    body = plant.outline_array
    world = body @ np.swapaxes(rotations, -1, -2)  # (N, points, 3): in place below, x and y apart (half the time)
    world += positions[:, None, :]
    centre_x, centre_y = plant.shaft_centre.tolist()
    gaps = plant.shaft_radius - np.hypot(world[..., 0] - centre_x, world[..., 1] - centre_y)
    nearest = np.argmin(gaps, axis=1).tolist()
    values = gaps[np.arange(len(nearest)), nearest].tolist()
    return [Clearance(value, plant.outline[k].name, body[k], world[i, k])
            for i, (k, value) in enumerate(zip(nearest, values))]


def clearance_at_pose(plant: Plant, rotation: np.ndarray, position: np.ndarray) -> Clearance:
    """Clearance of the outline at one platform pose."""
    return clearances_at_poses(plant, rotation[None], position[None])[0]


def swing_clearance(plant: Plant, solution: Solution) -> Clearance:
    """Worst clearance over every pose a single-cable platform can turn to (its range phi)."""
    assert solution.single_cable is not None  # a single-cable state names its cable
    hang = PlumbHang(plant, solution.single_cable, float(solution.lengths[solution.single_cable]))
    thetas = np.concatenate([np.linspace(lo, hi, max(2, int((hi - lo) * SWING_SAMPLES_PER_RAD) + 1))
                             for lo, hi in solution.rotation_range])
    rotations, positions = zip(*(hang.pose(theta) for theta in thetas))
    return min(clearances_at_poses(plant, np.array(rotations), np.array(positions)), key=lambda c: c.value)


def solution_clearances(plant: Plant, solutions: Sequence[Solution]) -> list[Clearance | None]:
    """`solution_clearance` of each solution, the solved poses computed together."""
    posed = [i for i, s in enumerate(solutions) if s.ok]
    out: list[Clearance | None] = [solution_clearance(plant, s) if not s.ok else None for s in solutions]
    if posed:
        batch = clearances_at_poses(plant, np.array([solutions[i].rotation for i in posed]),
                                    np.array([solutions[i].position for i in posed]))
        for i, clearance in zip(posed, batch):
            out[i] = clearance
    return out


def batch_clearances(plant: Plant, batch: BatchSolution) -> list[Clearance | None]:
    """`solution_clearances` of a batch's rows, from its arrays (no `Solution` made for a row the batch solved
    itself; the fallback's rows, a single cable's swing among them, from their own)."""
    out: list[Clearance | None] = [None] * len(batch)
    rows = [i for i in np.flatnonzero(batch.ok).tolist() if i not in batch.fallback]
    if rows:
        for i, clearance in zip(rows, clearances_at_poses(plant, batch.rotation[rows], batch.position[rows])):
            out[i] = clearance
    for i, solution in batch.fallback.items():
        out[i] = solution_clearance(plant, solution)
    return out


def solution_clearance(plant: Plant, solution: Solution) -> Clearance | None:
    """Clearance of a solved pose, or the worst over the swing of a single-cable state; None otherwise."""
    if solution.ok:
        assert solution.rotation is not None and solution.position is not None  # solved: a pose
        return clearance_at_pose(plant, solution.rotation, solution.position)
    if solution.single_cable is not None and solution.rotation_range:
        return swing_clearance(plant, solution)
    return None
