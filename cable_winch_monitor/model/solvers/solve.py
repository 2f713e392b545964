"""One entry point to both solvers."""
from __future__ import annotations

import numpy as np

from ..plantfile.plant import Plant
from ..statics.result import Solution, SolveStatus, failed
from .energy import solve_energy

METHODS = ("energy", "traversal")


def solve(plant: Plant, lengths: object, method: str = "energy", warm_start: Solution | None = None,
          load: np.ndarray | None = None) -> Solution:
    """Equilibrium for four cable lengths under `load` (model.load; None: gravity) with the chosen solver.

    `energy` (the monitor's solver) may be warm-started with the previous sample's
    solution; `traversal` is seed 002's algorithm as published and always starts cold.
    """
    if method == "energy":
        return solve_energy(plant, lengths, warm_start=warm_start, load=load)
    if method == "traversal":
        from ..paper.traversal import solve_traversal

        return solve_traversal(plant, lengths, load=load)
    return failed(SolveStatus.INVALID_INPUT, f"unknown solver {method!r}; use one of {', '.join(METHODS)}", method,
                  [float("nan")] * 4)
