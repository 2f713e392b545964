"""Plants and a scenario for the effect tests: the seed-002 platform with elastic ropes as the nominal
model, a lowering and a hoist with winch drift, realistic sensors (the simulator's defaults: 1 mm
encoders and 150 N load pins at 10 Hz, a 0.01 deg inclinometer 30-40 ms after each winch sample, a
5 mm depth gauge at 2 Hz). The truth is the simulator's own (sim/truth.py), not the fitted model."""
from __future__ import annotations

from pathlib import Path

import yaml

from cable_winch_monitor.sim.scenario import load_scenario
from cable_winch_monitor.sim.simulate import simulate

SEED002 = {"a": 2.0, "b": 2.5, "h": 10.0, "k1": 0.25, "k2": 0.2}
WIDE = {"anchors": [[5.0, 5.5, 0.0], [-5.0, 5.5, 0.0], [-5.0, -5.5, 0.0], [5.0, -5.5, 0.0]],
        "attachments": [[2.0, 2.5, 0.0], [-2.0, 2.5, 0.0], [-2.0, -2.5, 0.0], [2.0, -2.5, 0.0]],
        "centre_of_gravity": [0.5, 0.5, -10.0]}
ELASTIC = {"rope_elasticity": {"enabled": True, "EA": 7.5e7}}
SENSORS = {"imu": {"enabled": True}, "position": {"enabled": True}}
NOISE = {"tension": 150.0, "roll": 1.745e-4, "pitch": 1.745e-4, "depth": 0.005, "length": 0.001}
LOWER_AND_HOIST = {"start_length": 60.0, "segments": [{"move": 50.0, "speed": 1.0, "accel": 0.1}, {"stop": 8.0},
                                                      {"move": -25.0, "speed": 1.0, "accel": 0.1}]}
SHALLOW = {"start_length": 8.0, "segments": [{"move": 22.0, "speed": 0.5, "accel": 0.1}, {"stop": 5.0},
                                             {"move": -12.0, "speed": 0.5, "accel": 0.1}]}


def plant_file(directory: Path, name: str, geometry: dict, effects: dict) -> Path:
    """A plant YAML with the given geometry and effects, noise levels as the bundled plant."""
    path = directory / f"{name}.yaml"
    path.write_text(yaml.safe_dump({"plant": {
        "name": name, "geometry": geometry, "mass": 10000.0, "g": 9.8, "shaft": {"radius": 4.0},
        "outline": {"decks": [{"name": "deck_1", "z": 0.0, "radius": 3.6, "count": 12}]},
        "noise": NOISE, "effects": effects}}))
    return path


def simulate_bag(directory: Path, name: str, plant: Path, hidden: dict, profile: dict = LOWER_AND_HOIST,
                 duration: float = 110.0, **extra: object) -> Path:
    """A bag of `plant` with the effects `hidden` ({name: {param: value}}) added to the truth."""
    scenario = directory / f"{name}_scenario.yaml"
    scenario.write_text(yaml.safe_dump({"plant": str(plant), "duration": duration, "profile": profile,
                                        "sync": {"sigma": 0.02, "tau": 20.0}, "sensors": SENSORS,
                                        "effects": hidden, **extra}))
    out = directory / name
    simulate(load_scenario(scenario), out)
    return out
