"""The two plants every figure is measured on: the rigid default, and a realistic one.

The realistic plant is the bundled one with the effects a fitted plant file switches on:
elastic ropes (EA 7.5e7 N) with their own weight (60 N/m), and friction on the head
sheaves' load pins.
"""
from __future__ import annotations

from pathlib import Path

import yaml

from ..model.plant import Plant
from ..paths import default_plant_file

REALISTIC_EFFECTS = {"rope_elasticity": {"EA": 7.5e7}, "rope_weight": {"w": 60.0},
                     "sheave_friction": {"mu": 0.05}}


def realistic(plant: Plant) -> Plant:
    """`plant` with elastic ropes, their weight and sheave friction on."""
    return plant.with_changes(effects=REALISTIC_EFFECTS)


def realistic_plant_file(directory: Path) -> Path:
    """The bundled plant file with the realistic effects switched on, written into `directory` (for the
    CLI and the node, which read plant files)."""
    config = yaml.safe_load(default_plant_file().read_text())
    config["plant"]["effects"] = {name: {"enabled": True, **values} for name, values in REALISTIC_EFFECTS.items()}
    path = directory / "realistic_plant.yaml"
    path.write_text(yaml.safe_dump(config))
    return path
