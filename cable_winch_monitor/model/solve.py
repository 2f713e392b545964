"""One entry point to both solvers."""
from __future__ import annotations

from .energy import solve_energy
from .plant import Plant
from .result import Solution, SolveStatus, failed

METHODS = ("energy", "traversal")


def solve(plant: Plant, lengths: object, method: str = "energy", warm_start: Solution | None = None) -> Solution:
    """Equilibrium for four cable lengths with the chosen solver.

    `energy` (the monitor's solver) may be warm-started with the previous sample's
    solution; `traversal` is seed 002's algorithm as published and always starts cold.
    """
    if method == "energy":
        return solve_energy(plant, lengths, warm_start=warm_start)
    if method == "traversal":
        from .traversal import solve_traversal

        return solve_traversal(plant, lengths)
    return failed(SolveStatus.INVALID_INPUT, f"unknown solver {method!r}; use one of {', '.join(METHODS)}", method,
                  [float("nan")] * 4)
