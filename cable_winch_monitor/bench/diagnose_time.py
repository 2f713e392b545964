"""Benchmark: `diagnose` on a 20-minute recording at 10 Hz (inclinometer 15 Hz, depth gauge 1.5 Hz).

Simulates the bag first (the truth: seed-002 plant with elastic ropes and their weight),
then times reading it and diagnosing it against a plant file that already holds both, as
the CLI does, within the CLI's default budget of three minutes (what did not fit in it is
printed).
Run: python -m cable_winch_monitor.bench.diagnose_time [--keep DIR]
"""
from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import yaml

from ..analysis.diagnose import diagnose_bag
from ..model.plantfile.plant import load_plant
from ..paths import default_plant_file
from ..sim.scenario import load_scenario
from ..sim.simulate import simulate

DURATION = 1200.0
TARGET = 60.0  # [s]


def _inputs(directory: Path) -> tuple[Path, Path]:
    """A plant file (bundled plant + elastic ropes and their weight) and a 20-minute scenario."""
    config = yaml.safe_load(default_plant_file().read_text())
    config["plant"]["effects"] = {"rope_elasticity": {"enabled": True, "EA": 7.5e7},
                                  "rope_weight": {"enabled": True, "w": 60.0}}
    plant = directory / "plant.yaml"
    plant.write_text(yaml.safe_dump(config))
    scenario = directory / "scenario.yaml"
    scenario.write_text(yaml.safe_dump({
        "plant": str(plant), "duration": DURATION,
        "profile": {"start_length": 50.0, "segments": [
            {"move": 300.0, "speed": 1.0, "accel": 0.1}, {"stop": 60.0}, {"move": -200.0, "speed": 1.0, "accel": 0.1},
            {"stop": 60.0}, {"move": 250.0, "speed": 1.0, "accel": 0.1}]},
        "sync": {"sigma": 0.01, "tau": 30.0},
        "sensors": {"imu": {"enabled": True, "rate": 15.0},
                    "position": {"enabled": True, "rate": 1.5}},
        "effects": {"rope_weight": {"w": 60.0}}}))
    return plant, scenario


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--keep", help="directory to simulate into and keep (default: a temporary one)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as scratch:
        directory = Path(args.keep or scratch)
        directory.mkdir(parents=True, exist_ok=True)
        plant_path, scenario = _inputs(directory)
        started = time.perf_counter()
        simulate(load_scenario(scenario), directory / "bag")
        print(f"simulated {DURATION / 60:.0f} min into {directory / 'bag'} in {time.perf_counter() - started:.1f} s")
        started = time.perf_counter()
        result, _ = diagnose_bag(directory / "bag", load_plant(plant_path), budget=TARGET)
        wall = time.perf_counter() - started
    print(f"diagnose: {result.train_rows} training and {result.heldout_rows} held-out rows, "
          f"{result.solves} equilibrium solves, selected {result.selected}, "
          f"held-out score {result.ladder[0].score_heldout:.3f} -> {result.ladder[-1].score_heldout:.3f}")
    print(f"unfinished at the {TARGET:.0f} s budget: {'; '.join(result.unfinished) or 'nothing'}")
    print(f"wall time {wall:.1f} s (target {TARGET:.0f} s): {'OK' if wall <= TARGET else 'TOO SLOW'}")
    return 0 if wall <= TARGET else 1


if __name__ == "__main__":
    raise SystemExit(main())
