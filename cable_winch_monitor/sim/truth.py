"""The plant's true state: the equilibrium for the winches' lengths under the true plant and its effects.

The truth is a PlantModel: the plant file's effects, `ropes.model: elastic` as the
rope_elasticity effect, and the scenario's `effects:` section on top, so any effect
(built-in or user) can be hidden in simulated data. Each solve is warm-started from the
previous one, as the platform moves little between samples; the winches' direction of
motion is tracked for effects that depend on it (sheave friction).
"""
from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from ..effects import (
    Conditions,
    EffectError,
    PlantModel,
    effect_class,
    effects_from_mapping,
)
from ..model.conditions import motion_direction
from ..model.plant import Plant
from ..model.result import Solution
from .scenario import ScenarioError


def truth_model(plant: Plant, config: Mapping[str, Any]) -> PlantModel:
    """The true plant of a checked scenario."""
    model = PlantModel.from_plant(plant)
    extra = []
    if config["ropes"]["model"] == "elastic":
        extra.append(effect_class("rope_elasticity")({"EA": config["ropes"]["EA"]}))
    try:
        extra += effects_from_mapping(config.get("effects"), "effects")
    except EffectError as error:
        raise ScenarioError(f"scenario: {error}") from None
    return model.with_effects(extra)


class TruthModel:
    def __init__(self, model: PlantModel):
        self.model = model
        self.previous: Solution | None = None
        self.direction = np.zeros(4)

    def __call__(self, lengths: np.ndarray, speeds: np.ndarray) -> tuple[Solution, dict[str, float]]:
        """The true equilibrium for the lengths the winches report, and what the sensors see of it."""
        solution = self.model.solve(lengths, self.previous)
        self.previous = solution if solution.ok else None
        self.direction = motion_direction(speeds, self.direction)
        channels = self.model.predict(solution, Conditions(speeds=np.asarray(speeds, dtype=float),
                                                           direction=self.direction)) \
            if solution.ok else {}
        return solution, channels
