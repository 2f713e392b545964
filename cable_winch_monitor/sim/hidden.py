"""Which effects a simulated plant hides: the `effects:` sections of the plant file and the scenario.

Names of the simulator's own truth physics (`sim.physics`) take their parameters, checked
here; any other name must be a measurement effect of a user's module (`--effect-module`),
applied to the truth's channels. Errors name the key.
"""
from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from ..effects import Effect, EffectError, Registry
from ..model.plantfile.plant import Plant
from . import physics
from .keys import ScenarioError

Hidden = tuple[dict[str, dict[str, float]], dict[str, Effect]]


def effects_section(section: Any, where: str, registry: Registry, hidden: Hidden | None = None) -> Hidden:
    """The enabled truth effects {name: parameters} and user measurement effects {name: effect}, named in
    `registry`, of one `effects:` section, over (and replacing by name) those of `hidden`."""
    truth, users = ({}, {}) if hidden is None else (dict(hidden[0]), dict(hidden[1]))
    if section is None:
        return truth, users
    if not isinstance(section, Mapping):
        raise ScenarioError(f"key '{where}' must be a mapping of effect names to their parameters, got {section!r}")
    for name, spec in section.items():
        key = f"{where}.{name}"
        if spec is not None and not isinstance(spec, Mapping):
            raise ScenarioError(f"key '{key}' must be a mapping of parameters, got {spec!r}")
        spec = dict(spec or {})
        enabled = spec.pop("enabled", True)
        if not isinstance(enabled, bool):
            raise ScenarioError(f"key '{key}.enabled' must be true or false, got {enabled!r}")
        if name in physics.PARAMETERS:
            try:
                values = physics.check_parameters(str(name), spec, key)
            except ValueError as error:
                raise ScenarioError(str(error)) from None
            truth.pop(name, None)
            if enabled:
                truth[str(name)] = values
        else:
            effect = _user_effect(registry, str(name), spec, key)
            users.pop(effect.name, None)
            if enabled:
                users[effect.name] = effect
    return truth, users


def _user_effect(registry: Registry, name: str, spec: Mapping[str, Any], key: str) -> Effect:
    cls = registry.available().get(name)
    if cls is None:
        raise ScenarioError(f"key '{key}': unknown effect '{name}' (the truth's effects: "
                            f"{', '.join(physics.PARAMETERS)}; a user's measurement effect needs its module in "
                            "effect_modules or --effect-module)")
    try:
        effect = cls(spec)
    except EffectError as error:
        raise ScenarioError(f"key '{key}': {error}") from None
    if cls.acts != "measurement":
        raise ScenarioError(f"key '{key}': only measurement effects of a user's module can be hidden in the "
                            f"simulator's truth; '{name}' acts on the {cls.acts.replace('_', ' ')} "
                            f"(the truth's own effects: {', '.join(physics.PARAMETERS)})")
    return effect


def hidden_effects(plant: Plant, config: Mapping[str, Any]) -> tuple[dict[str, dict[str, float]], list[Effect]]:
    """The truth effects of a simulated run: `ropes.model: elastic` as rope_elasticity, the plant file's
    effects, then the scenario's; user measurement effects in their order."""
    section = plant.raw.get("plant", {}) if isinstance(plant.raw, Mapping) else {}
    try:
        registry = Registry(config.get("effect_modules", ())).with_modules(plant.effect_modules)
    except EffectError as error:
        raise ScenarioError(f"plant file: {error}") from None
    ropes = {"rope_elasticity": {"EA": config["ropes"]["EA"]}} if config["ropes"]["model"] == "elastic" else {}
    hidden = effects_section(ropes, "ropes", registry)
    hidden = effects_section(section.get("effects"), "plant.effects", registry, hidden)
    truth, users = effects_section(config.get("effects"), "effects", registry, hidden)
    return truth, sorted(users.values(), key=lambda e: e.order)
