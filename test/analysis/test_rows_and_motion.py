"""How a recording becomes rows, and what the plant was doing at each: measurements stamped together are one
row; motion is labelled winch by winch (a platform moving sideways is not standing); a slow channel far off
is a failure region whatever the faster channels do. Bags simulated by the simulator's own truth."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml
from effectbags import ELASTIC, SEED002, plant_file, simulate_bag
from labbags import EA, HIDDEN, LAB_PLANT, lab_bag

from cable_winch_monitor.analysis import report
from cable_winch_monitor.analysis.compare import compare
from cable_winch_monitor.analysis.data import read_bag
from cable_winch_monitor.analysis.evaluate import Evaluator, noise, split, thin
from cable_winch_monitor.analysis.motion import MOTIONS, SHIFTING, STANDING, motions
from cable_winch_monitor.bagio.reader import BagReader
from cable_winch_monitor.effects import PlantModel, effect_class
from cable_winch_monitor.model.conditions import directions
from cable_winch_monitor.model.plantfile.plant import load_plant
from cable_winch_monitor.sim.scenario import load_scenario
from cable_winch_monitor.sim.simulate import simulate

ROOT = Path(__file__).resolve().parents[2]
LAB_SCENARIO = ROOT / "config" / "scenarios" / "lab_robot.yaml"


def _lab_bag(directory: Path, name: str, *overrides: str) -> Path:
    config = load_scenario(LAB_SCENARIO, ["duration=40.0", *overrides])
    simulate(config, directory / name)
    return directory / name


def _messages(bag: Path) -> dict[str, int]:
    counts: dict[str, int] = {}
    for item in BagReader(bag):
        counts[item.topic] = counts.get(item.topic, 0) + 1
    return counts


def test_measurements_stamped_together_are_one_row(tmp_path):
    """A logger stamping its load cells and AHRS at once: one row measuring both; 35 ms apart: two rows."""
    together = read_bag(_lab_bag(tmp_path, "together", "sensors.imu.lag_min=0.0", "sensors.imu.lag_max=0.0"))
    apart = read_bag(_lab_bag(tmp_path, "apart"))
    imu = _messages(tmp_path / "together")["/platform/imu"]
    assert not np.any(together.kinds == together.sources.index("/platform/imu"))  # no AHRS row of its own
    both = np.isfinite(together.measured[:, together.channels.index("tension_cable_1")]) & \
        np.isfinite(together.measured[:, together.channels.index("roll")])
    assert both.sum() >= imu - 1  # every AHRS reading joined its winch sample
    assert np.sum(apart.kinds == apart.sources.index("/platform/imu")) >= imu - 1  # 30-40 ms apart: own rows
    assert len(apart) - len(together) >= imu - 2
    model = PlantModel.from_plant(load_plant(ROOT / "config" / "lab_robot_plant.yaml"))
    rows = np.flatnonzero(both)[:20]
    for estimate in Evaluator(together.subset(rows)).estimates(model):  # one estimate of both sensors
        assert estimate.fused and {"tension_cable_1", "roll", "pitch"} <= set(estimate.used)


def test_motion_follows_each_winch():
    speeds = np.array([[0.24, -0.24, -0.24, 0.24],   # sideways: the mean payout stands still
                       [0.0, 0.0, 0.0, 0.0], [0.5, 0.5, 0.5, 0.5], [-0.3, -0.3, -0.3, -0.3],
                       [0.05, 0.0, 0.0, 0.0], [np.nan, np.nan, np.nan, np.nan]])
    assert [MOTIONS[k] for k in motions(speeds)] == ["shifting", "standing", "lowering", "hoisting", "lowering",
                                                     "standing"]


def test_a_robot_moving_sideways_is_shifting_not_standing(tmp_path):
    """The lab scenario moves the platform in y from 30 s to 34 s (winches 1, 2 out, 3, 4 in at 3 cm/s)
    while the profile stops: the mean payout speed is nil there, each winch moves."""
    data = read_bag(_lab_bag(tmp_path, "sideways"))
    config = yaml.safe_load((tmp_path / "sideways" / "scenario.yaml").read_text())
    event = next(e for e in config["sync"]["events"] if e["start"] == 30.0)
    inside = (data.times > event["start"] + 0.3) & (data.times < event["start"] + event["duration"] - 0.3)
    labels = motions(data.speeds[inside])
    assert np.abs(np.nanmean(data.speeds[inside], axis=1)).max() < 0.02  # the old, mean-speed label: standing
    assert np.mean(labels == SHIFTING) > 0.95 and not np.any(labels == STANDING)


def test_slow_channel_off_by_many_sigma_is_a_failure_region(tmp_path):
    """Ropes 48 mm longer than the model at 400 m (10 K above the zeroing temperature): the depth gauge, 2 of
    every 22 rows, reads 10 sigma deep while load pins and inclinometer agree."""
    plant = plant_file(tmp_path, "elastic", SEED002, ELASTIC)
    bag = simulate_bag(tmp_path, "warm", plant, {"rope_temperature": {"alpha": 1.2e-5, "T_ref": 20.0}},
                       profile={"start_length": 400.0, "segments": [{"move": 20.0, "speed": 0.5, "accel": 0.1}]},
                       duration=60.0, shaft_air={"temperature": 30.0})
    result = compare(PlantModel.from_plant(load_plant(plant)), read_bag(bag))
    assert result.channels["depth"].score > 5.0
    assert all(result.channels[f"tension_cable_{i}"].score < 1.5 for i in range(1, 5))
    assert result.regions, "the depth gauge's error is a failure region"
    region = result.regions[0]
    assert [m["channel"] for m in region["channels"]] == ["depth"] and region["channels"][0]["measured"] == \
        "below model"
    assert region["end"] - region["start"] > 50.0 and region["start"] < 2.0  # seconds from the start, all along
    assert "failure regions (|error| > 3 sigma): 1" in report.compare_text(result)


def test_a_thinned_subset_keeps_the_direction_each_winch_last_moved_in(tmp_path):
    """Friction holds the slip of the last motion through a stop: the direction is a matter of the whole
    recording, and a thinned subset (the rows a fit uses) keeps it; found again from the subset's own rows,
    a short move between them is missed and the friction acts the wrong way."""
    data = read_bag(lab_bag(tmp_path))
    rows = thin(split(data)[1], data.kinds, 150)
    subset = data.subset(rows)
    np.testing.assert_array_equal(subset.directions, data.directions[rows])
    assert np.mean(directions(subset.speeds) != data.directions[rows]) > 0.05  # what the subset alone would say
    model = PlantModel.from_plant(load_plant(LAB_PLANT))
    truth = model.with_effects([effect_class(name)(values, model.plant) for name, values in HIDDEN.items()]
                               + [effect_class("rope_elasticity")({"EA": EA}, model.plant)])
    assert Evaluator(subset, model).score(truth, noise(model, data)[0]) < 1.3  # the truth explains them
