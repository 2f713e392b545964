"""The plant parameters tracked live (`plant.track`), resolved against the effects.

A name in `plant.track` is `effect.param`, or an effect alone for all its fitted
parameters; the effect need not be switched on in the plant file (its file value, or its
default, is where tracking starts). Each tracked parameter gets the tolerance its drift
warning uses: `plant.track_tolerance`'s (by parameter, else by effect), else 5 % of the
file's value, or twice the parameter's fit step where that value is zero. `PlantModel.with_tracked` gives the
plant model with tracked parameters at other values; an effect off in the file is switched on in the model
the monitor uses only where one of its values has left its start, so that tracking alone
costs that model nothing.
"""
from __future__ import annotations

from dataclasses import dataclass

from ..model.plantfile.plant import Plant
from .base import Effect, EffectError
from .registry import BUILTIN_REGISTRY, Registry

DEFAULT_RELATIVE = 0.05  # tolerance: this share of the file's value where that is not zero
DEFAULT_STEPS = 2.0      # else this many of the parameter's fit steps


@dataclass(frozen=True)
class TrackedParameter:
    """One tracked parameter: where it lives, where it starts, how far it may go before a drift warning."""

    effect: str
    name: str
    unit: str
    acts: str                      # where the effect acts (effects.base.ACTS)
    start: float                   # the file's value, or the parameter's default where the effect is off
    enabled: bool                  # the effect is switched on in the plant file
    tolerance: float               # [unit] the change from `start` that raises a drift warning
    bounds: tuple[float, float]    # the parameter's bounds for this plant
    step: float                    # its fit step: the size of a numerical derivative's step is set by it

    @property
    def key(self) -> str:
        return f"{self.effect}.{self.name}"


def tracked_parameters(plant: Plant, registry: Registry = BUILTIN_REGISTRY) -> tuple[TrackedParameter, ...]:
    """The parameters `plant.track` names (effects of `registry`), in its order; EffectError names a wrong key
    (unknown effect or parameter, a setting that is not fitted, a relative tolerance of a zero value)."""
    spec = plant.track
    out: list[TrackedParameter] = []
    for name in spec.names:
        effect_name, _, param = name.partition(".")
        try:
            cls = registry.effect_class(effect_name)
        except EffectError as error:
            raise EffectError(f"key 'plant.track': {error}") from None
        effect = file_effect(cls, plant)
        fitted = [p.name for p in effect.fitted()]
        if param and param not in {p.name for p in effect.specs}:
            raise EffectError(f"key 'plant.track': effect '{effect_name}' has no parameter '{param}' "
                              f"(known: {', '.join(fitted) or 'none'})")
        if param and param not in fitted:
            raise EffectError(f"key 'plant.track': '{name}' is a setting of the effect, not a parameter it fits "
                              f"(tracked: {', '.join(fitted) or 'none'})")
        if not fitted:
            raise EffectError(f"key 'plant.track': effect '{effect_name}' has no parameter to track")
        for p in effect.specs:
            if p.name in ([param] if param else fitted):
                key = f"{effect_name}.{p.name}"
                if any(t.key == key for t in out):
                    raise EffectError(f"key 'plant.track': '{key}' is named twice")
                start = effect[p.name]
                out.append(TrackedParameter(effect_name, p.name, p.unit, cls.acts, start, effect_name in _enabled(plant),
                                            _tolerance(plant, key, effect_name, start, p.scale), p.bounds, p.scale))
    unknown = sorted(set(spec.tolerance) - {t.key for t in out} - {t.effect for t in out})
    if unknown:
        raise EffectError(f"key 'plant.track_tolerance.{unknown[0]}': not a tracked parameter "
                          f"(tracked: {', '.join(t.key for t in out) or 'none'})")
    return tuple(out)


def _enabled(plant: Plant) -> set[str]:
    return {name for name, spec in plant.effects.items() if spec.get("enabled", True) is True}


def file_effect(cls: type[Effect], plant: Plant) -> Effect:
    """The effect as the plant file gives it (its values whether it is switched on or not)."""
    values = {k: v for k, v in plant.effects.get(cls.name, {}).items() if k != "enabled"}
    try:
        return cls(values, plant)
    except EffectError as error:
        raise EffectError(f"key 'plant.effects.{cls.name}': {error}") from None


def _tolerance(plant: Plant, key: str, effect: str, start: float, step: float) -> float:
    given = plant.track.tolerance.get(key) or plant.track.tolerance.get(effect)
    if given is None:
        return DEFAULT_RELATIVE * abs(start) if start != 0.0 else DEFAULT_STEPS * step
    kind, value = given
    if kind == "absolute":
        return value
    if start == 0.0:
        raise EffectError(f"key 'plant.track_tolerance.{key}': relative to a file value of 0; give it as "
                          "{absolute: value}")
    return value * abs(start)
