"""The external load on the platform: one wrench in `shaft`, the input of every solver.

A load is a 6-vector (f_x, f_y, f_z, M_x, M_y, M_z): the resultant force [N] and its
moment about the centre of gravity C [N m], the right-hand side F of seed 002's
J^T tau = F (eq. 7). Gravity alone, (0, 0, -m g, 0, 0, 0), is the default
(`Plant.wrench`); physical effects change it (a platform braking carries m (g - a)).
Solvers normalise by the force's magnitude, so that their tolerances mean the same
for a 10 t platform and a 13 kg laboratory robot.
"""
from __future__ import annotations

import numpy as np

from ..plantfile.plant import Plant

VERTICAL_TOL = 1e-12  # relative horizontal force or moment below which a load counts as a plain vertical pull


def resolve(plant: Plant, load: np.ndarray | None) -> np.ndarray:
    """The load a solver works with: `load` as a float array, or gravity where it is None."""
    return plant.wrench if load is None else np.asarray(load, dtype=float).reshape(6)


def check(load: np.ndarray) -> str:
    """Why a load cannot be carried by hanging ropes ('' when it can): finite, with a downward force."""
    if not np.all(np.isfinite(load)):
        return f"load must be finite, got {load.tolist()}"
    if load[2] >= 0.0:
        return f"load must pull the platform down (f_z < 0), got f_z = {load[2]:g} N"
    return ""


def check_rows(loads: np.ndarray) -> str:
    """`check` of the first of many loads (n, 6) that cannot be carried ('' when all can), the rows tested
    together (one row at a time, 2 us each, for every row of every batch the estimator solves)."""
    bad = ~(np.isfinite(loads).all(axis=1) & (loads[:, 2] < 0.0))
    return check(loads[int(np.argmax(bad))]) if bad.any() else ""


def magnitude(load: np.ndarray) -> float:
    """|f| [N]: the scale of tensions (m g under gravity)."""
    return float(np.linalg.norm(load[:3]))


def is_vertical(load: np.ndarray) -> bool:
    """A downward force along z with no moment about C, as gravity: the paper's closed forms hold for it."""
    scale = magnitude(load)
    return bool(np.all(np.abs(load[[0, 1]]) <= VERTICAL_TOL * scale)
                and np.all(np.abs(load[3:]) <= VERTICAL_TOL * scale))  # moment per metre of lever


def loads_for(plant: Plant, loads: np.ndarray | None, count: int) -> np.ndarray:
    """(count, 6) loads for a batch: one per row, one for all rows, or gravity where None."""
    if loads is None:
        return np.broadcast_to(plant.wrench, (count, 6))
    return np.broadcast_to(np.asarray(loads, dtype=float), (count, 6))
