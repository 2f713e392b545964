"""A plant with its enabled physical effects: the equilibrium for reported lengths, and what sensors read.

`PlantModel.solve` turns encoder lengths into true lengths (geometry effects), builds the
rope law (rope-law effects) and solves with the matching solver -- the rigid energy
solver, or the elastic one with EA and the rope's own-weight stretch -- then refines
pose-dependent geometry (sheave tangent points) by fixed-point iteration.
`PlantModel.predict` gives the sensor readings for a solved state (measurement effects).
A model without effects is exactly the monitor's rigid model.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any, Iterable, Mapping

import numpy as np

from ..model.elastic import solve_elastic
from ..model.plant import Plant, PlantConfigError
from ..model.result import Solution
from ..model.solve import solve
from ..monitor.residuals import predicted_channels
from .base import Conditions, Effect, EffectError, RopeLaw
from .registry import effect_class, load_module

REFINE_STEPS = 6
REFINE_TOL = 1e-7  # [m] pose change at which the pose-dependent geometry has settled


def _overrides(cls: type[Effect], hook: str) -> bool:
    return getattr(cls, hook) is not getattr(Effect, hook)


def effects_from_mapping(section: Any, where: str) -> list[Effect]:
    """The enabled effects of an `effects:` mapping {name: {enabled: bool, parameter: value, ...}}."""
    if section is None:
        return []
    if not isinstance(section, Mapping):
        raise EffectError(f"key '{where}' must be a mapping of effect names to their parameters")
    effects = []
    for name, spec in section.items():
        spec = dict(spec or {})
        enabled = spec.pop("enabled", True)
        if not isinstance(enabled, bool):
            raise EffectError(f"key '{where}.{name}.enabled' must be true or false, got {enabled!r}")
        try:
            effect = effect_class(str(name))(spec)
        except EffectError as error:
            raise EffectError(f"key '{where}.{name}': {error}") from None
        if enabled:
            effects.append(effect)
    return effects


@dataclass(frozen=True)
class PlantModel:
    """The nominal plant and its enabled effects (at most one of each name)."""

    plant: Plant
    effects: tuple[Effect, ...] = field(default=())

    @classmethod
    def from_plant(cls, plant: Plant) -> "PlantModel":
        """The effects the plant file switches on (`plant.effects`, user modules in `plant.effect_modules`)."""
        section = plant.raw.get("plant", {}) if isinstance(plant.raw, Mapping) else {}
        try:
            for path in section.get("effect_modules", []) or []:
                load_module(path)
            return cls(plant, tuple(effects_from_mapping(section.get("effects"), "plant.effects")))
        except EffectError as error:
            raise PlantConfigError(f"plant file: {error}") from None

    def names(self) -> list[str]:
        return [e.name for e in self.effects]

    def get(self, name: str) -> Effect | None:
        return next((e for e in self.effects if e.name == name), None)

    def with_effects(self, effects: Iterable[Effect]) -> "PlantModel":
        """Add or replace effects by name."""
        replaced = {e.name: e for e in effects}
        kept = [replaced.pop(e.name, e) for e in self.effects]
        return PlantModel(self.plant, tuple(kept + list(replaced.values())))

    @cached_property
    def physical(self) -> Plant:
        """The plant as the geometry effects make it (centre of gravity, mass, ...)."""
        plant = self.plant
        for effect in self.effects:
            plant = effect.plant(plant)
        return plant

    @cached_property
    def rope_law(self) -> RopeLaw:
        law = RopeLaw()
        for effect in self.effects:
            law = effect.rope(law)
        return law

    @cached_property
    def _refiners(self) -> tuple[Effect, ...]:
        return tuple(e for e in self.effects if _overrides(type(e), "refine"))

    @cached_property
    def _measurers(self) -> tuple[Effect, ...]:
        return tuple(sorted((e for e in self.effects if _overrides(type(e), "measure")), key=lambda e: e.order))

    def solve_key(self) -> tuple:
        """Everything a solve depends on: two models with equal keys have the same equilibria."""
        law = self.rope_law
        geometry = tuple((e.name, tuple(e.values.items())) for e in self.effects
                         if any(_overrides(type(e), hook) for hook in ("plant", "lengths", "refine")))
        return law.EA, law.weight if law.EA is not None else 0.0, geometry

    def true_lengths(self, reported: np.ndarray) -> np.ndarray:
        lengths = np.asarray(reported, dtype=float)
        for effect in self.effects:
            lengths = effect.lengths(lengths)
        return lengths

    def _solve_once(self, plant: Plant, lengths: np.ndarray, warm_start: Solution | None) -> Solution:
        law = self.rope_law
        if law.EA is None:
            return solve(plant, lengths, "energy", warm_start=warm_start)
        own_weight_stretch = law.weight * lengths ** 2 / (2.0 * law.EA)
        return solve_elastic(plant, lengths + own_weight_stretch, law.EA, warm_start=warm_start)

    def solve(self, reported: object, warm_start: Solution | None = None) -> Solution:
        """Equilibrium for the lengths the winches report; never raises (see model.result)."""
        try:
            lengths = self.true_lengths(np.asarray(reported, dtype=float))
        except (TypeError, ValueError):
            lengths = reported  # the solver's input check reports what is wrong
        solution = self._solve_once(self.physical, lengths, warm_start)
        for _ in range(REFINE_STEPS if self._refiners else 0):
            if not solution.ok:
                break
            plant, refined = self.physical, lengths
            for effect in self._refiners:
                plant, refined = effect.refine(plant, refined, solution)
            previous, solution = solution, self._solve_once(plant, refined, solution)
            if solution.ok and np.abs(solution.points_b - previous.points_b).max() < REFINE_TOL:
                break
        return solution

    def predict(self, solution: Solution, conditions: Conditions | None = None) -> dict[str, float]:
        """What each sensor reads for a solved state: the rigid-model channels, then measurement effects."""
        channels = predicted_channels(solution)
        conditions = conditions or Conditions()
        for effect in self._measurers:
            effect.measure(channels, solution, self.physical, conditions)
        return channels

    def effects_config(self) -> dict[str, dict[str, Any]]:
        """The `effects:` section of a plant file with these effects on."""
        return {e.name: {"enabled": True, **{k: float(v) for k, v in e.values.items()}} for e in self.effects}

    def user_modules(self) -> list[str]:
        """Files of the user modules defining effects of this model (for `effect_modules:`)."""
        import inspect

        files = []
        for effect in self.effects:
            module = inspect.getmodule(type(effect))
            if module is not None and module.__name__.startswith("cable_winch_monitor_user_effects."):
                files.append(str(Path(module.__file__).resolve()))
        return sorted(set(files))
