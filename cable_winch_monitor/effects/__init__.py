"""Physical effects as composable terms: rope law, geometry and measurement model (see base.py)."""
from .base import Conditions, Effect, EffectError, Parameter, RopeLaw
from .model import PlantModel, effects_from_mapping
from .registry import available, effect_class, load_module, register

__all__ = ["Conditions", "Effect", "EffectError", "Parameter", "PlantModel", "RopeLaw", "available",
           "effect_class", "effects_from_mapping", "load_module", "register"]
