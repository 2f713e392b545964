"""Where effects come from: the built-ins first, then the entry points installed packages declare."""
from __future__ import annotations

import sys
from pathlib import Path

import pytest

from cable_winch_monitor.effects import EffectError, available, effect_class, registry
from cable_winch_monitor.effects.rope import RopeElasticity

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


@pytest.fixture
def installed(tmp_path, monkeypatch):
    """A package 'shaft-effects' installed on the path, declaring the example rope_temperature effect as
    its entry point; the registry as at start-up."""
    info = tmp_path / "shaft_effects-1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: shaft-effects\nVersion: 1.0\n")
    (info / "entry_points.txt").write_text(f"[{registry.GROUP}]\nrope_temperature = rope_temperature:RopeTemperature\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.syspath_prepend(str(EXAMPLES))
    monkeypatch.setattr(registry, "REGISTRY", registry.EffectRegistry())  # the installed packages not read yet
    yield
    sys.modules.pop("rope_temperature", None)


def test_an_installed_packages_entry_point_adds_its_effect(installed):
    """A built-in is found without reading the installed packages' metadata; a name only an entry point
    declares is found there, and listed with the built-ins."""
    assert effect_class("rope_elasticity") is RopeElasticity and not registry.REGISTRY.entry_points_loaded
    cls = effect_class("rope_temperature")
    assert registry.REGISTRY.entry_points_loaded
    assert cls.__module__ == "rope_temperature" and cls.name == "rope_temperature"
    assert {"rope_elasticity", "rope_temperature"} <= set(available())


def test_a_name_nobody_declares_lists_what_is_known(installed):
    with pytest.raises(EffectError, match="unknown effect 'rope_colour'.*rope_temperature"):
        effect_class("rope_colour")


SHADOW = '''
from cable_winch_monitor.effects.base import Effect, Parameter


class {cls}(Effect):
    name = "{name}"
    title = "a user's rope weight"
    acts = "rope_law"
    parameters = (Parameter("w", "N/m", 0.0, (0.0, 1000.0), 1.0, "weight per metre"),)
'''


@pytest.fixture
def fresh_registry(monkeypatch):
    """The registry as at start-up (the built-ins alone), the installed packages' entry points taken as read."""
    fresh = registry.EffectRegistry()
    fresh.entry_points_loaded = True
    monkeypatch.setattr(registry, "REGISTRY", fresh)


@pytest.mark.parametrize("built_ins_first", [False, True])
@pytest.mark.parametrize("cls", ["MyWeight", "RopeWeight"])  # RopeWeight: the built-in's own class name
def test_a_user_effect_named_like_a_built_in_is_refused_in_any_order(fresh_registry, tmp_path, built_ins_first, cls):
    module = tmp_path / "shadow.py"
    module.write_text(SHADOW.format(cls=cls, name="rope_weight"))
    if built_ins_first:
        available()
    with pytest.raises(EffectError, match="effect 'rope_weight' is defined twice"):
        registry.load_module(module)
    assert effect_class("rope_weight").__module__ == "cable_winch_monitor.effects.rope"


def test_two_user_modules_cannot_define_one_name(fresh_registry, tmp_path):
    (tmp_path / "one.py").write_text(SHADOW.format(cls="Cable", name="cable_drag"))
    (tmp_path / "two.py").write_text(SHADOW.format(cls="Cable", name="cable_drag"))
    assert registry.load_module(tmp_path / "one.py") == ["cable_drag"]
    assert registry.load_module(tmp_path / "one.py") == ["cable_drag"]  # the same file again is the same effect
    with pytest.raises(EffectError, match="effect 'cable_drag' is defined twice"):
        registry.load_module(tmp_path / "two.py")
