"""The plant's true state: the equilibrium for the true cable lengths, rigid or elastic ropes.

Each solve is warm-started from the previous one, as the platform moves little between
samples. Elastic ropes (unilateral Hooke springs of stiffness EA) share the load among
all four ropes where rigid ones leave one slack, which the monitor (rigid model) then sees.
"""
from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from ..model.elastic import solve_elastic
from ..model.plant import Plant
from ..model.result import Solution
from ..model.solve import solve


class TruthModel:
    def __init__(self, plant: Plant, ropes: Mapping[str, Any]):
        self.plant = plant
        self.elastic = ropes["model"] == "elastic"
        self.stiffness = float(ropes["EA"])
        self.previous: Solution | None = None

    def _solve(self, lengths: np.ndarray, warm_start: Solution | None) -> Solution:
        if self.elastic:
            return solve_elastic(self.plant, lengths, self.stiffness, warm_start=warm_start)
        return solve(self.plant, lengths, "energy", warm_start=warm_start)

    def __call__(self, lengths: np.ndarray) -> Solution:
        """The true equilibrium for these unstretched cable lengths."""
        solution = self._solve(lengths, self.previous)
        self.previous = solution if solution.ok else None
        return solution
