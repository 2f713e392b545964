"""The plants every figure is measured on: the rigid default, a realistic one, and the plant files a site has.

The realistic plant is the bundled one with the effects a fitted plant file switches on:
elastic ropes (EA 7.5e7 N) with their own weight (60 N/m), and friction on the head
sheaves' load pins. The site cases are recordings whose plant file is wrong the way a
site's is (`SITE_CASES`): elastic ropes (EA 6.8e7 N, 58 N/m, config/scenarios/site_elastic)
replayed with the bundled rigid plant file, or with one whose EA is 10 % high; stiff ropes
with encoder errors the plant file does not know (site_encoders); and the correct file.
"""
from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

import yaml

from ..model.plantfile.plant import Plant
from ..paths import default_plant_file

REALISTIC_EFFECTS = {"rope_elasticity": {"EA": 7.5e7}, "rope_weight": {"w": 60.0},
                     "sheave_friction": {"mu": 0.05}}
SITE_EA, SITE_WEIGHT = 6.8e7, 58.0  # [N], [N/m] the ropes of config/scenarios/site_elastic.yaml
# what a site tracks live (plant.track): the ropes' stiffness and weight, the encoders' zeros, the load pins' zeros
TRACKED = ("rope_elasticity.EA", "rope_weight.w", "encoder_offset",
           *(f"load_pin_calibration.zero_{i}" for i in range(1, 5)))


class SiteCase(NamedTuple):
    """A recording and the plant file it is replayed with."""

    name: str
    scenario: str                       # a bundled scenario
    effects: dict[str, dict[str, float]]  # switched on in the bundled plant file
    what: str


SITE_CASES = (
    SiteCase("a", "site_elastic", {}, "elastic ropes, the bundled rigid plant file"),
    SiteCase("b", "site_elastic", {"rope_elasticity": {"EA": 1.1 * SITE_EA}, "rope_weight": {"w": SITE_WEIGHT}},
             "elastic ropes, EA 10 % high in the plant file"),
    SiteCase("c", "site_encoders", {}, "stiff ropes, an encoder 0.3 % long and one 4 cm off"),
    SiteCase("d", "site_elastic", {"rope_elasticity": {"EA": SITE_EA}, "rope_weight": {"w": SITE_WEIGHT}},
             "elastic ropes, the correct plant file"),
)


def realistic(plant: Plant) -> Plant:
    """`plant` with elastic ropes, their weight and sheave friction on."""
    return plant.with_changes(effects=REALISTIC_EFFECTS)


def realistic_plant_file(directory: Path) -> Path:
    """The bundled plant file with the realistic effects switched on, written into `directory` (for the
    CLI and the node, which read plant files)."""
    return plant_file(directory / "realistic_plant.yaml", REALISTIC_EFFECTS)


def plant_file(path: Path, effects: dict[str, dict[str, float]]) -> Path:
    """The bundled plant file with `effects` switched on, written to `path`."""
    config = yaml.safe_load(default_plant_file().read_text())
    if effects:
        config["plant"]["effects"] = {name: {"enabled": True, **values} for name, values in effects.items()}
    path.write_text(yaml.safe_dump(config))
    return path


def tracking_plant_file(path: Path, ea: float = SITE_EA, track: bool = True) -> Path:
    """The bundled plant file with elastic ropes of axial stiffness `ea` [N] and the site's rope weight, tracking
    TRACKED (the encoders' zeros with a tolerance of 1 cm, the rest the package's defaults; `track` False: the
    same file tracking nothing, to tell what tracking costs from what the model costs), written to `path`."""
    plant_file(path, {"rope_elasticity": {"EA": ea}, "rope_weight": {"w": SITE_WEIGHT}})
    if not track:
        return path
    config = yaml.safe_load(path.read_text())
    config["plant"]["track"] = list(TRACKED)
    config["plant"]["track_tolerance"] = {"encoder_offset": {"absolute": 0.01}}
    path.write_text(yaml.safe_dump(config))
    return path
