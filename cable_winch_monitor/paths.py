"""Where the package's shipped configuration lives: the source tree or the ROS share dir."""
from __future__ import annotations

import sys
from pathlib import Path

PACKAGE_NAME = "cable_winch_monitor"


def config_dir() -> Path:
    """`config/` of the source checkout (editable install) or `share/cable_winch_monitor/config`."""
    source = Path(__file__).resolve().parent.parent / "config"
    if source.is_dir():
        return source
    return Path(sys.prefix) / "share" / PACKAGE_NAME / "config"


def default_plant_file() -> Path:
    """The bundled seed-002 plant."""
    return config_dir() / "seed002_plant.yaml"


def demo_bag() -> Path:
    """The bundled all-channels bag of the source checkout (`bags/all_channels`)."""
    return Path(__file__).resolve().parent.parent / "bags" / "all_channels"


def lab_bag() -> Path:
    """The laboratory robot's recording of the source checkout (`bags/lab_robot`: swivel pulleys)."""
    return Path(__file__).resolve().parent.parent / "bags" / "lab_robot"


def lab_plant_file() -> Path:
    """The laboratory robot's plant file."""
    return config_dir() / "lab_robot_plant.yaml"
