"""`simulate`: scenarios and overrides checked with clear errors, determinism, rates and noise."""
from __future__ import annotations

from collections import Counter, defaultdict

import numpy as np
import pytest
from simbags import assert_clean, messages, run_cli, simulated, truth

from cable_winch_monitor.model.statics.geometry import roll_pitch_of_quaternion
from cable_winch_monitor.paths import config_dir
from cable_winch_monitor.sim.scenario import ScenarioError, load_scenario, scenario_path
from cable_winch_monitor.sim.simulate import simulate

SCENARIOS = sorted(p.stem for p in (config_dir() / "scenarios").glob("*.yaml"))


def test_bundled_scenarios_load():
    assert {"nominal_lowering", "lag_slack", "sync_critical", "all_channels", "benchmark"} <= set(SCENARIOS)
    for name in SCENARIOS:
        assert load_scenario(scenario_path(name))["name"] == name


@pytest.mark.parametrize("overrides, message", [
    (["sync.sigmaa=0.1"], "unknown key 'sync.sigmaa' (known: sigma, tau, events, drives)"),
    (["ropes.EA=stiff"], "key 'ropes.EA' must be a number, got 'stiff'"),
    (["ropes.model=steel"], "key 'ropes.model' must be one of rigid, elastic"),
    (["sync.events.3.lag=0.1"], "has 1 items, no item 3"),
    (["sync.events.0.winch=5"], "key 'sync.events[0].winch' must be 1..4"),
    (["sensors.imu.rate=0"], "key 'sensors.imu.rate' must be positive"),
    (["profile.segments=[{move: 1.0}]"], "key 'profile.segments[0]' needs 'speed'"),
    (["ropes.model.kind=x"], "'ropes.model' is a value, not a section"),
    (["no_equals_sign"], "expected key=value"),
    (["profile.segments.0.move=-100"], "key 'profile.segments[0].move' hoists the cables to a payout of -20 m"),
])
def test_errors_name_the_key(overrides, message):
    with pytest.raises(ScenarioError, match="lag_slack.yaml: .*" + message.replace("[", r"\[").replace("]", r"\]")
                       .replace("(", r"\(").replace(")", r"\)")):
        load_scenario(scenario_path("lag_slack"), overrides)


def test_cli_errors_are_clean(tmp_path):
    result = run_cli("simulate", "lag_slack", "--out", tmp_path / "bag", "--set", "sync.tua=3")
    assert_clean(result, 2)
    assert result.stderr.startswith("error: scenario") and "unknown key 'sync.tua'" in result.stderr
    assert_clean(run_cli("simulate", tmp_path / "missing.yaml", "--out", tmp_path / "bag"), 2)
    assert not (tmp_path / "bag").exists()


def test_deterministic_for_a_seed(tmp_path):
    first, second, other = (simulated(tmp_path / name, "all_channels", "duration=3", seed=seed)
                            for name, seed in (("a", 7), ("b", 7), ("c", 8)))
    data = [next(bag.glob("*.mcap")).read_bytes() for bag in (first, second, other)]
    assert data[0] == data[1] and data[0] != data[2]
    assert (first / "ground_truth.csv").read_bytes() == (second / "ground_truth.csv").read_bytes()
    again = tmp_path / "d" / "all_channels"  # the scenario.yaml written beside a bag makes it again
    simulate(load_scenario(first / "scenario.yaml"), again)
    assert next(again.glob("*.mcap")).read_bytes() == data[0]


def test_rates_noise_and_timing(tmp_path):
    bag = simulated(tmp_path, "all_channels", "duration=20", "sync.events=[]")
    items = messages(bag)
    stamps = defaultdict(list)
    for item in items:
        stamp = item.message.header.stamp.sec * 10**9 + item.message.header.stamp.nanosec
        assert item.log_time > stamp  # received after it was stamped
        stamps[item.topic].append(stamp)
    rates = {topic: len(s) / 20.0 for topic, s in stamps.items()}
    assert rates == pytest.approx({**{f"/winch_{i}/joint_states": 10.0 for i in range(1, 5)},
                                   "/platform/imu": 10.0, "/platform/position": 2.0}, abs=0.11)
    # the inclinometer stamps each reading 30-40 ms after a winch stamp
    lags = np.array(stamps["/platform/imu"]) - np.array(stamps["/winch_1/joint_states"][:len(stamps["/platform/imu"])])
    assert 30e6 <= lags.min() and lags.max() <= 40e6 and np.ptp(lags) > 5e6
    assert all(np.all(np.diff(s) > 0) for s in stamps.values())
    assert max(Counter(s for values in stamps.values() for s in values).values()) == 1  # never aligned
    assert [item.log_time for item in items] == sorted(item.log_time for item in items)
    # encoder noise: measured minus true lengths
    rows = {round(float(row["time"]) * 1e9): row for row in truth(bag) if row["stream"] == "winch_2"}
    errors = [item.message.position[0] - float(rows[s]["length_2"]) for item, s in
              ((i, i.message.header.stamp.sec * 10**9 + i.message.header.stamp.nanosec) for i in items
               if i.topic == "/winch_2/joint_states")]
    assert np.std(errors) == pytest.approx(0.001, rel=0.3) and abs(np.mean(errors)) < 0.0005
    # load pins, inclinometer and depth gauge: their realistic noise about the truth (weightless ropes:
    # the pin reads the tension at the platform)
    by_time = {round(float(row["time"]) * 1e9): row for row in truth(bag)}
    pins, tilts, depths = [], [], []
    for item in items:
        stamp = item.message.header.stamp.sec * 10**9 + item.message.header.stamp.nanosec
        row = by_time[stamp]
        if item.topic == "/winch_3/joint_states":
            pins.append(item.message.effort[0] - float(row["tension_3"]))
        elif item.topic == "/platform/imu":
            quaternion = [getattr(item.message.orientation, k) for k in "xyzw"]
            tilts.append(roll_pitch_of_quaternion(quaternion)[0] - float(row["roll"]))
        elif item.topic == "/platform/position":
            depths.append(item.message.point.z - float(row["z"]))
    assert np.std(pins) == pytest.approx(150.0, rel=0.3)
    assert np.std(tilts) == pytest.approx(np.radians(0.01), rel=0.3)
    assert np.std(depths) == pytest.approx(0.005, rel=0.4)
    imu = next(item.message for item in items if item.topic == "/platform/imu")
    assert imu.orientation_covariance[8] > 1e3 and imu.angular_velocity_covariance[0] == -1.0
    depth = next(item.message for item in items if item.topic == "/platform/position")
    assert np.isnan(depth.point.x) and np.isnan(depth.point.y) and depth.point.z < -50.0


@pytest.mark.parametrize("model, taut_count", [("rigid", 3), ("elastic", 4)])
def test_rope_model_switch(tmp_path, model, taut_count):
    """Millimetre drift: rigid ropes leave one slack, elastic ones (EA 500 MN, 2.5 mm stretch) all carry load."""
    overrides = ["duration=3", f"ropes.model={model}", "sync.sigma=0.001"]
    config = load_scenario(scenario_path("nominal_lowering"), overrides)
    simulate(config, tmp_path / "bag")
    assert {len(row["taut"].split()) for row in truth(tmp_path / "bag")} == {taut_count}


def test_shaft_air_thermometer(tmp_path):
    """/shaft/temperature: sensor_msgs/Temperature at 1 Hz, 0.1 K about the scenario's ventilation cycle."""
    bag = simulated(tmp_path, "nominal_lowering", "duration=30", "sensors.temperature.enabled=true",
                    "shaft_air.amplitude=3.0", "shaft_air.period=20.0", "effects={rope_temperature: {}}")
    readings = [item for item in messages(bag) if item.topic == "/shaft/temperature"]
    assert len(readings) == pytest.approx(30, abs=1)
    assert readings[0].msgtype == "sensor_msgs/msg/Temperature" and readings[0].message.variance == pytest.approx(0.01)
    errors = [item.message.temperature - (15.0 + 3.0 * np.sin(2.0 * np.pi * (item.message.header.stamp.sec
              + item.message.header.stamp.nanosec * 1e-9) / 20.0)) for item in readings]
    assert np.std(errors) == pytest.approx(0.1, rel=0.4) and abs(np.mean(errors)) < 0.06
