"""Which plant parameters the monitor tracks live, and how it may use them: the plant file's `track` keys.

`plant.track` lists parameters of the plant's effects by name, `effect.param`
(`rope_elasticity.EA`, `encoder_offset.d_1`), or an effect's name alone for all its
fitted parameters. `plant.track_tolerance` maps a name to the change from the file's
value that raises a drift warning, `{relative: share}` or `{absolute: value}`. Three
shares of each parameter's tolerance say how the tracked values are used:

- `track_sigma` (0.2): a tracked value replaces the file's once its 1-sigma is below this
  share of its tolerance;
- `track_rate` (1.0): the value in use moves by at most this share of its tolerance per
  minute of sample time, so that a sensor fault cannot pull the model away in seconds;
- `track_drift` (0.2): how far the parameter may drift in an hour (1-sigma of a random walk),
  which bounds how much of the past its estimate rests on.

This module checks the form of these keys; the effect layer checks the names against the
effects and resolves tolerances against the file's values (effects.tracked).
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

KINDS = ("relative", "absolute")
SHARES = {"track_sigma": 0.2, "track_rate": 1.0, "track_drift": 0.2}


class TrackConfigError(ValueError):
    """A `plant.track*` key is wrong; the message names it."""


@dataclass(frozen=True)
class TrackSpec:
    """The plant file's tracking keys, as written (names not yet checked against the effects)."""

    names: tuple[str, ...] = ()                                   # `effect.param` or `effect`
    tolerance: Mapping[str, tuple[str, float]] = field(default_factory=dict)  # name -> (kind, value)
    sigma: float = SHARES["track_sigma"]    # share of the tolerance the 1-sigma must be below for use
    rate: float = SHARES["track_rate"]      # share of the tolerance per minute the value in use may move
    drift: float = SHARES["track_drift"]    # share of the tolerance the parameter may drift in an hour

    @property
    def enabled(self) -> bool:
        return bool(self.names)

    @classmethod
    def from_section(cls, section: Mapping[str, Any]) -> TrackSpec:
        """The spec of a plant file's `plant` mapping (every key optional)."""
        names = _names(section.get("track"))
        tolerance = _tolerances(section.get("track_tolerance"))
        shares = {key.removeprefix("track_"): _share(section, key, default) for key, default in SHARES.items()}
        return cls(names, tolerance, **shares)


def _names(value: Any) -> tuple[str, ...]:
    if value is None:
        return ()
    if isinstance(value, str):
        value = [value]
    if not isinstance(value, list) or not all(isinstance(v, str) and v.strip() for v in value):
        raise TrackConfigError("key 'plant.track' must be a list of parameter names 'effect.param' (or 'effect' for "
                               f"all its parameters), got {value!r}")
    names = [v.strip() for v in value]
    for name in names:
        if name.count(".") > 1 or name.startswith(".") or name.endswith("."):
            raise TrackConfigError(f"key 'plant.track': {name!r} is not a name 'effect.param' or 'effect'")
    repeated = sorted({n for n in names if names.count(n) > 1})
    if repeated:
        raise TrackConfigError(f"key 'plant.track': {repeated[0]!r} is listed twice")
    return tuple(names)


def _tolerances(section: Any) -> dict[str, tuple[str, float]]:
    if section is None:
        return {}
    if not isinstance(section, Mapping):
        raise TrackConfigError("key 'plant.track_tolerance' must map names 'effect.param' to {relative: share} or "
                               f"{{absolute: value}}, got {section!r}")
    out = {}
    for name, spec in section.items():
        where = f"plant.track_tolerance.{name}"
        if not isinstance(spec, Mapping) or len(spec) != 1 or next(iter(spec)) not in KINDS:
            raise TrackConfigError(f"key '{where}' must be {{relative: share}} or {{absolute: value}}, got {spec!r}")
        kind, value = next(iter(spec.items()))
        if not _positive(value):
            raise TrackConfigError(f"key '{where}.{kind}' must be a positive number, got {value!r}")
        out[str(name)] = (str(kind), float(value))
    return out


def _share(section: Mapping[str, Any], key: str, default: float) -> float:
    value = section.get(key, default)
    if not _positive(value):
        raise TrackConfigError(f"key 'plant.{key}' must be a positive number (a share of each parameter's "
                               f"tolerance), got {value!r}")
    return float(value)


def _positive(value: Any) -> bool:
    return not isinstance(value, bool) and isinstance(value, (int, float)) and math.isfinite(value) and value > 0.0
