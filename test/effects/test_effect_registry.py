"""Where effects come from: the built-ins first, then a plant model's user modules and the entry points
installed packages declare; each model's registry its own."""
from __future__ import annotations

import pickle
import sys
from pathlib import Path

import pytest

from cable_winch_monitor.effects import BUILTIN_REGISTRY, EffectError, PlantModel, Registry, registry
from cable_winch_monitor.effects.rope import RopeElasticity
from cable_winch_monitor.model.plantfile.plant import load_plant, plant_from_mapping

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


@pytest.fixture
def installed(tmp_path, monkeypatch):
    """A package 'shaft-effects' installed on the path, declaring the example rope_temperature effect as
    its entry point, the installed packages not read yet."""
    info = tmp_path / "shaft_effects-1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: shaft-effects\nVersion: 1.0\n")
    (info / "entry_points.txt").write_text(f"[{registry.GROUP}]\nrope_temperature = rope_temperature:RopeTemperature\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.syspath_prepend(str(EXAMPLES))
    registry.installed.cache_clear()
    yield
    registry.installed.cache_clear()
    sys.modules.pop("rope_temperature", None)


def test_an_installed_packages_entry_point_adds_its_effect(installed):
    """A built-in is found without reading the installed packages' metadata; a name only an entry point
    declares is found there, and listed with the built-ins."""
    assert BUILTIN_REGISTRY.effect_class("rope_elasticity") is RopeElasticity and registry.installed.cache_info().currsize == 0
    cls = BUILTIN_REGISTRY.effect_class("rope_temperature")
    assert registry.installed.cache_info().currsize == 1
    assert cls.__module__ == "rope_temperature" and cls.name == "rope_temperature"
    assert {"rope_elasticity", "rope_temperature"} <= set(BUILTIN_REGISTRY.available())


def test_a_name_nobody_declares_lists_what_is_known(installed):
    with pytest.raises(EffectError, match="unknown effect 'rope_colour'.*rope_temperature"):
        BUILTIN_REGISTRY.effect_class("rope_colour")


SHADOW = '''
from cable_winch_monitor.effects.base import Effect, Parameter


class {cls}(Effect):
    name = "{name}"
    title = "a user's rope weight"
    acts = "rope_law"
    parameters = (Parameter("w", "N/m", 0.0, (0.0, 1000.0), 1.0, "weight per metre"),)
'''


@pytest.mark.parametrize("cls", ["MyWeight", "RopeWeight"])  # RopeWeight: the built-in's own class name
def test_a_user_effect_named_like_a_built_in_is_refused(tmp_path, cls):
    module = tmp_path / f"shadow_{cls}.py"
    module.write_text(SHADOW.format(cls=cls, name="rope_weight"))
    with pytest.raises(EffectError, match="effect 'rope_weight' is defined twice"):
        Registry([module])
    assert BUILTIN_REGISTRY.effect_class("rope_weight").__module__ == "cable_winch_monitor.effects.rope"


def test_two_user_modules_cannot_define_one_name(tmp_path):
    (tmp_path / "one.py").write_text(SHADOW.format(cls="Cable", name="cable_drag"))
    (tmp_path / "two.py").write_text(SHADOW.format(cls="Cable", name="cable_drag"))
    one = Registry([tmp_path / "one.py"])
    assert one.effect_class("cable_drag") is Registry([tmp_path / "one.py", tmp_path / "one.py"]).effect_class(
        "cable_drag")  # the same file again is the same effect, imported once
    with pytest.raises(EffectError, match="effect 'cable_drag' is defined twice"):
        one.with_modules([tmp_path / "two.py"])


def test_a_models_registry_has_its_plant_files_modules_and_no_others(tmp_path):
    """The user modules a plant file names make its model's registry; a model of another file knows only the
    built-ins, whatever was loaded before it; the registry pickles as its modules' paths."""
    module = tmp_path / "drag.py"
    module.write_text(SHADOW.format(cls="Cable", name="cable_drag"))
    raw = load_plant().raw["plant"]
    dragged = PlantModel.from_plant(plant_from_mapping({"plant": {**raw, "effect_modules": [str(module)],
                                                                  "effects": {"cable_drag": {"w": 2.0}}}}))
    assert dragged.names() == ["cable_drag"] and dragged.user_modules() == [str(module.resolve())]
    plain = PlantModel.from_plant(load_plant())
    assert "cable_drag" in dragged.registry.available() and "cable_drag" not in plain.registry.available()
    with pytest.raises(EffectError, match="unknown effect 'cable_drag'"):
        plain.registry.effect_class("cable_drag")
    copy = pickle.loads(pickle.dumps(dragged.registry))
    assert copy.modules == dragged.registry.modules and copy.effect_class("cable_drag") is Registry(
        [module]).effect_class("cable_drag")
    assert dragged.with_effects([]).registry is dragged.registry  # a model made from it keeps its registry


def test_a_module_that_defines_nothing_is_refused_with_its_path(tmp_path):
    empty = tmp_path / "empty.py"
    empty.write_text("x = 1\n")
    with pytest.raises(EffectError, match="empty.py: defines no Effect subclass with a name and declares no channel"):
        Registry([empty])
    with pytest.raises(EffectError, match="no such file"):
        Registry([tmp_path / "missing.py"])
