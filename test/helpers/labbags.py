"""The laboratory robot of config/lab_robot_plant.yaml, simulated with calibration errors its plant file does
not know: the AHRS mounted tilted by 0.80 deg roll and -0.50 deg pitch, the platform 1 kg heavier, cables of
EA 2e4 N where the file has them rigid, and friction in the pulleys (mu 0.06 over a quarter turn: the load
cells read 9 % low paying out, 9 % high hauling in). Lab noise: encoders 0.1 mm, load cells 0.3 N, the AHRS
0.05 deg 30-40 ms after each winch sample, motion capture 1 mm at 5 Hz. The platform is lowered, hoisted and
moved sideways both ways in x and y (each winch moves both ways). The truth is the simulator's own
(sim/truth.py over sim/pulleys.py), not the package's model."""
from __future__ import annotations

from pathlib import Path

import yaml

from cable_winch_monitor.paths import lab_plant_file
from cable_winch_monitor.sim.scenario import load_scenario
from cable_winch_monitor.sim.simulate import simulate

LAB_PLANT = lab_plant_file()
HIDDEN = {"inclinometer_offset": {"roll": 0.0140, "pitch": -0.0087}, "payload_mass": {"dm": 1.0},
          "sheave_friction": {"mu": 0.06}}
EA = 2.0e4
UP_AND_DOWN = [{"stop": 2.0}, {"move": 1.0, "speed": 0.1, "accel": 0.2}, {"stop": 4.0},
               {"move": -1.3, "speed": 0.1, "accel": 0.2}, {"stop": 4.0}, {"move": 0.6, "speed": 0.1, "accel": 0.2},
               {"stop": 4.0}, {"move": 0.5, "speed": 0.1, "accel": 0.2}, {"stop": 4.0},
               {"move": -1.0, "speed": 0.1, "accel": 0.2}, {"stop": 4.0}, {"move": 0.6, "speed": 0.1, "accel": 0.2}]


def _sideways(start: float, lag: float, out: tuple[int, ...]) -> list[dict]:
    """Winches `out` pay out `lag` more while the others haul in as much, over 4 s, held 6 s, and back."""
    return [{"winch": w, "lag": -lag if w in out else lag, "start": start, "duration": 4.0, "hold": 6.0}
            for w in range(1, 5)]


SIDEWAYS = [{"winch": 3, "lag": -0.02, "start": 0.0, "duration": 0.0}, *_sideways(6.0, 0.15, (2, 3)),
            *_sideways(30.0, 0.12, (3, 4)), *_sideways(70.0, 0.12, (1, 4)), *_sideways(95.0, 0.1, (1, 2))]


def lab_bag(directory: Path, name: str = "lab", duration: float = 120.0, hidden: dict | None = None) -> Path:
    """Simulate the lab robot with its calibration errors (`hidden`, default HIDDEN and cables of EA) into
    directory/name."""
    scenario = directory / f"{name}.yaml"
    scenario.write_text(yaml.safe_dump({
        "plant": str(LAB_PLANT), "duration": duration, "seed": 3,
        "profile": {"start_length": 1.4, "segments": UP_AND_DOWN}, "ropes": {"model": "elastic", "EA": EA},
        "effects": HIDDEN if hidden is None else hidden, "sync": {"sigma": 0.001, "tau": 20.0, "events": SIDEWAYS},
        "sensors": {"joint_states": {"length_noise": 0.0001, "velocity_noise": 0.0005, "tension_noise": 0.3},
                    "imu": {"enabled": True, "noise": 8.7e-4},
                    "position": {"enabled": True, "rate": 5.0, "noise": 0.001, "horizontal": True}}}))
    simulate(load_scenario(scenario), directory / name)
    return directory / name
