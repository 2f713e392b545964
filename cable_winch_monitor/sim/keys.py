"""A scenario's keys checked: the error naming the key, and a mapping checked against the types of its keys."""
from __future__ import annotations

from collections.abc import Collection, Mapping
from typing import Any


class ScenarioError(ValueError):
    """A scenario file or override is wrong; the message names the key."""


def _kind_ok(value: Any, kind: type) -> bool:
    if kind is float:
        return isinstance(value, (int, float)) and not isinstance(value, bool)
    if kind is int:
        return isinstance(value, int) and not isinstance(value, bool)
    return isinstance(value, kind)


def check_value(value: Any, kind: type, where: str) -> Any:
    """`value` (at key `where`) of type `kind`, a number given as a string read as one (ScenarioError if not)."""
    if kind is float and isinstance(value, str):  # YAML 1.1 reads 7.5e7 (no dot) as a string
        try:
            value = float(value)
        except ValueError:
            pass
    if not _kind_ok(value, kind):
        name = "a number" if kind is float else kind.__name__
        raise ScenarioError(f"key '{where}' must be {name}, got {value!r}")
    return float(value) if kind is float else value


def check_item(item: Any, spec: Mapping[str, type], where: str, optional: Collection[str] = frozenset()) -> dict:
    """`item` (at key `where`) as a mapping of exactly the keys of `spec` (but those `optional`), each value of its
    type (a number given as a string read as one); ScenarioError names the first key that is wrong."""
    if not isinstance(item, Mapping):
        raise ScenarioError(f"key '{where}' must be a mapping with keys {', '.join(spec)}, got {item!r}")
    unknown = [k for k in item if k not in spec]
    if unknown:
        raise ScenarioError(f"unknown key '{where}.{unknown[0]}' (known: {', '.join(spec)})")
    missing = [k for k in spec if k not in item and k not in optional]
    if missing:
        raise ScenarioError(f"key '{where}' needs '{missing[0]}'")
    return {k: check_value(v, spec[k], f"{where}.{k}") for k, v in item.items()}
