"""Bags for the bag tests: short simulated scenarios written into a test's temporary directory."""
from __future__ import annotations

import csv
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import yaml

from cable_winch_monitor.bagio.reader import BagReader
from cable_winch_monitor.model.plantfile.plant import Plant, load_plant
from cable_winch_monitor.paths import default_plant_file
from cable_winch_monitor.sim.scenario import load_scenario, scenario_path
from cable_winch_monitor.sim.simulate import TRUTH_FILE, simulate

CLI = [str(Path(sys.executable).parent / "cable-winch-monitor")]


def simulated(directory: Path, scenario: str, *overrides: str, seed: int | None = None) -> Path:
    """A bag of a bundled scenario (with `--set` overrides) in `directory`/<scenario>."""
    out = directory / scenario
    simulate(load_scenario(scenario_path(scenario), overrides, seed), out)
    return out


def messages(bag: Path, topics: dict[str, str] | None = None) -> list[Any]:
    """Every decoded message of a bag (rosbags type store), in log order."""
    return list(BagReader(bag, topics))


def truth(bag: Path) -> list[dict[str, str]]:
    with (bag / TRUTH_FILE).open() as file:
        return list(csv.DictReader(file))


def run_cli(*args: str | Path, timeout: float = 120.0) -> subprocess.CompletedProcess:
    """`cable-winch-monitor ARGS` in a subprocess (text output)."""
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    return subprocess.run([*CLI, *map(str, args)], capture_output=True, text=True, timeout=timeout, env=env)


def assert_clean(result: subprocess.CompletedProcess, code: int) -> None:
    """Exit status `code` and no traceback anywhere in the output."""
    output = result.stdout + result.stderr
    assert "Traceback" not in output, output
    assert result.returncode == code, output


def encoder_tracking_plant(directory: Path) -> Plant:
    """The bundled plant tracking its encoders' offsets live, written into `directory` and loaded: a replay on it
    writes every output topic, /model/parameters too."""
    config = yaml.safe_load(default_plant_file().read_text())
    config["plant"]["track"] = ["encoder_offset"]
    plant_file = directory / "tracking.yaml"
    plant_file.write_text(yaml.safe_dump(config))
    return load_plant(plant_file)
