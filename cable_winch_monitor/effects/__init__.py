"""Physical effects as composable terms: rope law, geometry and measurement model (see base.py)."""
from .base import Conditions, Effect, EffectError, Parameter, RopeLaw
from .model import PlantModel, effects_from_mapping
from .registry import BUILTIN_REGISTRY, Registry, available, effect_class

__all__ = ["BUILTIN_REGISTRY", "Conditions", "Effect", "EffectError", "Parameter", "PlantModel", "Registry", "RopeLaw",
           "available", "effect_class", "effects_from_mapping"]
