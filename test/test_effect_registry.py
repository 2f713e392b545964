"""Where effects come from: the built-ins first, then the entry points installed packages declare."""
from __future__ import annotations

import sys
from pathlib import Path

import pytest

from cable_winch_monitor.effects import EffectError, available, effect_class, registry
from cable_winch_monitor.effects.rope import RopeElasticity

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


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
    monkeypatch.setattr(registry, "_registry", {})
    monkeypatch.setattr(registry, "_entry_points_loaded", False)
    yield
    sys.modules.pop("rope_temperature", None)


def test_an_installed_packages_entry_point_adds_its_effect(installed):
    """A built-in is found without reading the installed packages' metadata; a name only an entry point
    declares is found there, and listed with the built-ins."""
    assert effect_class("rope_elasticity") is RopeElasticity and not registry._entry_points_loaded
    cls = effect_class("rope_temperature")
    assert registry._entry_points_loaded
    assert cls.__module__ == "rope_temperature" and cls.name == "rope_temperature"
    assert {"rope_elasticity", "rope_temperature"} <= set(available())


def test_a_name_nobody_declares_lists_what_is_known(installed):
    with pytest.raises(EffectError, match="unknown effect 'rope_colour'.*rope_temperature"):
        effect_class("rope_colour")
