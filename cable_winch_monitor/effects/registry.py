"""What a plant model can name: effect classes and measured channels, in a `Registry` each model holds.

A registry knows the built-in effects and channels, the effects installed packages declare
as entry points, and what the user modules it is made with define: a user module is any
Python file defining Effect subclasses with a `name` and declaring its sensors' channels
(`channels.declare`), named by a plant file's `effect_modules:` or the CLI's
--effect-module. Loading a module for one model changes no other. An installed package adds
effects without a path by declaring an entry point:

    [project.entry-points."cable_winch_monitor.effects"]
    my_effect = "my_package.effects:MyEffect"
"""
from __future__ import annotations

import importlib.util
import inspect
import sys
from collections.abc import Iterable
from functools import cache
from pathlib import Path
from types import ModuleType
from typing import NamedTuple

from ..channels import Channel, ChannelRegistry, declared_by_import
from .base import ACTS, Effect, EffectError
from .body import CogOffset, PayloadMass
from .calibration import InclinometerOffset, LoadPinCalibration
from .encoder import EncoderOffset, EncoderScale
from .pulley import PulleyGeometry
from .rope import RopeElasticity, RopeWeight
from .sensor import TensionSensorBending
from .sheave import SheaveFriction, SheaveGeometry

GROUP = "cable_winch_monitor.effects"
USER_MODULES = "cable_winch_monitor_user_effects."  # the package user modules are imported into
BUILTINS: tuple[type[Effect], ...] = (RopeElasticity, RopeWeight, EncoderScale, EncoderOffset, SheaveFriction,
                                      CogOffset, PayloadMass, SheaveGeometry, TensionSensorBending, InclinometerOffset,
                                      LoadPinCalibration, PulleyGeometry)


class UserModule(NamedTuple):
    """What a user's module defines: its effect classes and the channels it declares."""

    effects: tuple[type[Effect], ...]
    channels: tuple[Channel, ...]


class Registry:
    """The effect classes and channels a plant model knows, by name: the built-ins, the user modules it is made
    with (`modules`, absolute paths, in order), then the installed packages' entry points (read only when a
    name is not known otherwise, or for a listing: reading every installed package's metadata costs 13 ms of
    each start). Made whole, never changed; it pickles as its modules' paths."""

    def __init__(self, modules: Iterable[str | Path] = (), group: str = GROUP):
        self.modules = tuple(dict.fromkeys(str(Path(path).resolve()) for path in modules))
        self.group = group
        self.loaded = {path: import_user_module(path) for path in self.modules}
        self.classes: dict[str, type[Effect]] = {cls.name: cls for cls in BUILTINS}
        for module in self.loaded.values():
            for cls in module.effects:
                _add(self.classes, cls)
        self.channels = ChannelRegistry(channel for module in self.loaded.values() for channel in module.channels)

    def __reduce__(self) -> tuple:
        return Registry, (self.modules, self.group)

    def with_modules(self, modules: Iterable[str | Path]) -> Registry:
        """This registry with more user modules after its own (the same object where they add none)."""
        more = tuple(str(Path(path).resolve()) for path in modules)
        if set(more) <= set(self.modules):
            return self
        return Registry((*self.modules, *more), self.group)

    def available(self) -> dict[str, type[Effect]]:
        """Every known effect by name: built-ins first, then user modules' and the installed packages'."""
        out = dict(self.classes)
        for cls in installed(self.group):
            _add(out, cls)
        return out

    def effect_class(self, name: str) -> type[Effect]:
        """The effect called `name`: a built-in, one of a user module, else an installed entry point."""
        cls = self.classes.get(name) or self.available().get(name)
        if cls is None:
            raise EffectError(f"unknown effect '{name}' (known: {', '.join(self.available())}; a user effect needs "
                              "--effect-module, effect_modules in the plant file, or an entry point)")
        return cls


BUILTIN_REGISTRY = Registry()  # the built-ins alone: a plant model without user modules


def available() -> dict[str, type[Effect]]:
    """The built-in and installed effects by name (a plant model's own, user modules' among them:
    `model.registry.available()`)."""
    return BUILTIN_REGISTRY.available()


def effect_class(name: str) -> type[Effect]:
    """A built-in or installed effect class by name (a plant model's own: `model.registry.effect_class`)."""
    return BUILTIN_REGISTRY.effect_class(name)


def _add(classes: dict[str, type[Effect]], cls: type[Effect]) -> None:
    """Add an effect class by name; its name must be new: a user's effect named like a built-in is refused, and
    a class is the one already known only if it is the same definition (module and name)."""
    known = classes.get(cls.name)
    if known is not None and (known.__module__, known.__qualname__) != (cls.__module__, cls.__qualname__):
        raise EffectError(f"effect '{cls.name}' is defined twice ({_origin(known)} and {_origin(cls)}): "
                          "give one of them another name")
    classes[cls.name] = cls


def _checked(cls: type[Effect]) -> type[Effect]:
    """An effect class as a registry takes it: an Effect subclass with a snake_case name and a known `acts`."""
    if not (isinstance(cls, type) and issubclass(cls, Effect)) or not cls.name:
        raise EffectError(f"{cls!r} is not an Effect subclass with a name")
    if not cls.name.replace("_", "").isalnum() or cls.name != cls.name.lower():
        raise EffectError(f"effect name {cls.name!r} must be snake_case")
    if cls.acts not in ACTS:
        raise EffectError(f"effect '{cls.name}': acts={cls.acts!r}, must be one of {', '.join(ACTS)}")
    return cls


@cache
def installed(group: str = GROUP) -> tuple[type[Effect], ...]:
    """The effect classes installed packages declare as entry points of `group`, read once a process
    (importlib.metadata, 17 ms to import, only then)."""
    from importlib.metadata import entry_points

    classes: list[type[Effect]] = []
    for point in entry_points(group=group):
        loaded = point.load()
        classes += [_checked(cls) for cls in ([loaded] if isinstance(loaded, type) else _effect_classes(loaded))]
    return tuple(classes)


def _origin(cls: type[Effect]) -> str:
    """Where an effect class is defined: its module, or the file of a user's module."""
    file = getattr(sys.modules.get(cls.__module__), "__file__", None)
    if cls.__module__.startswith(USER_MODULES) and file:
        return file
    return cls.__module__


def _effect_classes(module: ModuleType) -> list[type[Effect]]:
    return [obj for _, obj in inspect.getmembers(module, inspect.isclass)
            if issubclass(obj, Effect) and obj is not Effect and obj.name and obj.__module__ == module.__name__]


_IMPORTED: dict[str, UserModule] = {}  # a user module is imported once a process, as Python imports a package


def import_user_module(path: str | Path) -> UserModule:
    """Import a user's effect module from its file (once a process): its effect classes and declared channels."""
    path = Path(path).resolve()
    if str(path) in _IMPORTED:
        return _IMPORTED[str(path)]
    if not path.is_file():
        raise EffectError(f"effect module {path}: no such file")
    module_name = f"{USER_MODULES}{path.stem}_{abs(hash(str(path))) % 10**8}"
    spec = importlib.util.spec_from_file_location(module_name, path)
    if spec is None or spec.loader is None:
        raise EffectError(f"effect module {path}: not a Python file")
    module = importlib.util.module_from_spec(spec)
    sys.modules[module_name] = module
    try:
        with declared_by_import() as declared:
            spec.loader.exec_module(module)
    except Exception as error:
        del sys.modules[module_name]
        raise EffectError(f"effect module {path}: {type(error).__name__}: {error}") from None
    classes = tuple(_checked(cls) for cls in _effect_classes(module))
    if not classes and not declared:
        raise EffectError(f"effect module {path}: defines no Effect subclass with a name and declares no channel")
    _IMPORTED[str(path)] = UserModule(classes, tuple(declared))
    return _IMPORTED[str(path)]
