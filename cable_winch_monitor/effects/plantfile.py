"""A plant file for a plant model: the file it was read from, with the model's effects and their values."""
from __future__ import annotations

import copy
from pathlib import Path

import yaml

from .model import PlantModel


def write_plant(model: PlantModel, path: str | Path, by: str) -> None:
    """The plant file of `model.plant` with `model`'s effects switched on (and their user modules listed),
    headed by a comment saying what wrote it (`by`)."""
    config = copy.deepcopy(dict(model.plant.raw))
    section = dict(config.get("plant", {}))
    section["effects"] = model.effects_config()
    modules = model.user_modules()
    if modules:
        section["effect_modules"] = modules
    else:
        section.pop("effect_modules", None)
    config["plant"] = section
    Path(path).write_text(f"# written by {by}\n" + yaml.safe_dump(config, sort_keys=False))
