"""Where effects come from: the built-ins, the `cable_winch_monitor.effects` entry points, user modules.

A user module is any Python file defining Effect subclasses with a `name`; it is loaded
with `load_module(path)` (the CLI's --effect-module, or `effect_modules:` in a plant
file). An installed package adds effects without a path by declaring an entry point:

    [project.entry-points."cable_winch_monitor.effects"]
    my_effect = "my_package.effects:MyEffect"
"""
from __future__ import annotations

import importlib.util
import inspect
import sys
from importlib.metadata import entry_points
from pathlib import Path
from types import ModuleType

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


class EffectRegistry:
    """The effect classes known, by name: the built-ins from the start, then those of the installed packages'
    entry points (read only when a name is not known otherwise, or for a listing: reading every installed
    package's metadata costs 13 ms of each start) and of user modules."""

    def __init__(self, builtins: tuple[type[Effect], ...] = BUILTINS, group: str = GROUP):
        self.classes: dict[str, type[Effect]] = {cls.name: cls for cls in builtins}
        self.group = group
        self.entry_points_loaded = False

    def register(self, cls: type[Effect]) -> type[Effect]:
        """Add an effect class; its name must be new, snake_case, its `acts` known. A user's effect named like a
        built-in is refused whenever it comes; a class is the one already known only if it is that class, or
        the same definition (module and name) imported again."""
        if not (isinstance(cls, type) and issubclass(cls, Effect)) or not cls.name:
            raise EffectError(f"{cls!r} is not an Effect subclass with a name")
        if not cls.name.replace("_", "").isalnum() or cls.name != cls.name.lower():
            raise EffectError(f"effect name {cls.name!r} must be snake_case")
        if cls.acts not in ACTS:
            raise EffectError(f"effect '{cls.name}': acts={cls.acts!r}, must be one of {', '.join(ACTS)}")
        known = self.classes.get(cls.name)
        if known is not None and (known.__module__, known.__qualname__) != (cls.__module__, cls.__qualname__):
            raise EffectError(f"effect '{cls.name}' is defined twice ({_origin(known)} and {_origin(cls)}): "
                              "give one of them another name")
        self.classes[cls.name] = cls
        return cls

    def load_entry_points(self) -> None:
        """Register the effects that installed packages declare, once."""
        if self.entry_points_loaded:
            return
        self.entry_points_loaded = True
        for point in entry_points(group=self.group):
            loaded = point.load()
            for cls in [loaded] if isinstance(loaded, type) else _effect_classes(loaded):
                self.register(cls)

    def available(self) -> dict[str, type[Effect]]:
        """Every known effect by name: built-ins first, then entry points and loaded user modules."""
        self.load_entry_points()
        return dict(self.classes)

    def effect_class(self, name: str) -> type[Effect]:
        """The effect called `name`: a built-in, one of a loaded user module, else an installed entry point."""
        if name not in self.classes:
            self.load_entry_points()
        if name not in self.classes:
            raise EffectError(f"unknown effect '{name}' (known: {', '.join(self.available())}; a user effect needs "
                              "--effect-module or an entry point)")
        return self.classes[name]


REGISTRY = EffectRegistry()  # the package's: what user modules and entry points register into


def register(cls: type[Effect]) -> type[Effect]:
    """Add an effect class to the package's registry (usable as a decorator); see `EffectRegistry.register`."""
    return REGISTRY.register(cls)


def available() -> dict[str, type[Effect]]:
    """Every known effect by name: built-ins first, then entry points and loaded user modules."""
    return REGISTRY.available()


def effect_class(name: str) -> type[Effect]:
    """The effect called `name`: a built-in, one of a loaded user module, else an installed entry point."""
    return REGISTRY.effect_class(name)


def _origin(cls: type[Effect]) -> str:
    """Where an effect class is defined: its module, or the file of a user's module."""
    file = getattr(sys.modules.get(cls.__module__), "__file__", None)
    if cls.__module__.startswith(USER_MODULES) and file:
        return file
    return cls.__module__


def _effect_classes(module: ModuleType) -> list[type[Effect]]:
    return [obj for _, obj in inspect.getmembers(module, inspect.isclass)
            if issubclass(obj, Effect) and obj is not Effect and obj.name and obj.__module__ == module.__name__]


def load_module(path: str | Path) -> list[str]:
    """Import a user's effect module from a file and register its effects; their names."""
    path = Path(path).resolve()
    if not path.is_file():
        raise EffectError(f"effect module {path}: no such file")
    module_name = f"{USER_MODULES}{path.stem}_{abs(hash(str(path))) % 10**8}"
    if module_name not in sys.modules:
        spec = importlib.util.spec_from_file_location(module_name, path)
        if spec is None or spec.loader is None:
            raise EffectError(f"effect module {path}: not a Python file")
        module = importlib.util.module_from_spec(spec)
        sys.modules[module_name] = module
        try:
            spec.loader.exec_module(module)
        except Exception as error:
            del sys.modules[module_name]
            raise EffectError(f"effect module {path}: {type(error).__name__}: {error}") from None
    classes = _effect_classes(sys.modules[module_name])
    if not classes:
        raise EffectError(f"effect module {path}: defines no Effect subclass with a name")
    return [register(cls).name for cls in classes]
