"""What the remaining error follows: the ranking on residuals with a known cause, no finding on noise or
on unrelated drift, other topics' fields read from a real bag, and `compare` naming the payout as what
the load pins follow when the rope's weight is hidden in simulated data and missing from the model."""
from __future__ import annotations

import json

import numpy as np
import pytest
from effectbags import ELASTIC, SEED002, plant_file, simulate_bag
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from simbags import assert_clean, run_cli

from cable_winch_monitor.analysis.bagfields import read_fields
from cable_winch_monitor.analysis.compare import compare
from cable_winch_monitor.analysis.data import Dataset, read_bag
from cable_winch_monitor.analysis.follows import LOAD_PINS, Regressor, follows, what_follows
from cable_winch_monitor.bagio.reader import BagReader
from cable_winch_monitor.bagio.writer import BagWriter
from cable_winch_monitor.channels import BUILTIN_CHANNELS, TENSION_CHANNELS
from cable_winch_monitor.effects import PlantModel
from cable_winch_monitor.messages.records import build
from cable_winch_monitor.model.conditions import derivatives
from cable_winch_monitor.model.plantfile.plant import load_plant
from cable_winch_monitor.sim.profile import Profile

RATE = 10.0  # [Hz]
ROWS = 2000
CHANNELS = BUILTIN_CHANNELS.names()


def _smooth(rng: np.random.Generator, tau: float, n: int = ROWS) -> np.ndarray:
    """A first-order Gauss-Markov series with correlation time tau [s] (a drift, a slow temperature)."""
    out, a = np.zeros(n), np.exp(-1.0 / (RATE * tau))
    for k in range(1, n):
        out[k] = a * out[k - 1] + rng.normal()
    return out


def _moves_and_stops(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Payout [m] and direction of motion (held through stops) of a plant lowering 20 m and hoisting 15 m
    by turns, 20 s per move and 10 s standing between moves."""
    knots, payout, heading = [0.0], [60.0], [1.0]
    for move in range(7):
        change = 20.0 if move % 2 == 0 else -15.0
        knots += [knots[-1] + 20.0, knots[-1] + 30.0]
        payout += [payout[-1] + change] * 2
        heading += [np.sign(change)] * 2
    direction = np.array(heading)[np.clip(np.searchsorted(knots, t, side="left"), 0, len(knots) - 1)]
    return np.interp(t, knots, payout), direction


def _regressors(rng: np.random.Generator) -> list[Regressor]:
    t = np.arange(ROWS) / RATE
    payout, direction = _moves_and_stops(t)
    return [Regressor("time", "time", "s", t), Regressor("payout", "the payout", "m", payout),
            Regressor("speed", "the payout speed", "m/s", np.gradient(payout, t)),
            Regressor("direction", "the direction of motion", "", direction, {1.0: "lowering", -1.0: "hoisting"}),
            Regressor("/shaft/temperature.temperature", "/shaft/temperature.temperature", "", _smooth(rng, 20.0))]


def test_residual_following_a_regressor_is_ranked_first_with_its_r():
    rng = np.random.default_rng(3)
    candidates = _regressors(rng)
    temperature = candidates[-1].values
    x = (temperature - temperature.mean()) / temperature.std()
    z = np.full((ROWS, len(CHANNELS)), np.nan)
    z[:, CHANNELS.index("depth")] = 4.0 / 3.0 * x + rng.normal(size=ROWS)  # r = (4/3) / sqrt(16/9 + 1) = 0.8
    z[:, CHANNELS.index("roll")] = rng.normal(size=ROWS)
    found = follows(z, list(CHANNELS), candidates)
    assert [f.target for f in found] == ["depth"], [f.sentence for f in found]
    depth = found[0]
    assert depth.regressor == "/shaft/temperature.temperature"
    assert depth.r == pytest.approx(0.8, abs=0.05) and depth.n == ROWS and depth.p < 0.01
    assert depth.slope * temperature.std() == pytest.approx(4.0 / 3.0, rel=0.1)
    assert depth.sentence.startswith(f"depth residual follows /shaft/temperature.temperature, r = {depth.r:.2f} "
                                     f"(n = {ROWS}")


def test_load_pins_together_and_a_direction_effect():
    rng = np.random.default_rng(4)
    candidates = _regressors(rng)
    payout = candidates[1].values
    z = np.full((ROWS, len(CHANNELS)), np.nan)
    for c in range(4):  # the rope's weight: every pin reads high in proportion to the payout
        z[:, c] = 0.1 * (payout - payout.mean()) + rng.normal(size=ROWS)
    lowering = candidates[3].values > 0  # sheave friction: the pitch reads +-1.5 sigma with the direction
    z[:, CHANNELS.index("pitch")] = np.where(lowering, 1.5, -1.5) + rng.normal(size=ROWS)
    found = {f.target: f for f in follows(z, list(CHANNELS), candidates)}
    assert set(found) == {LOAD_PINS, "pitch"}  # no single pin repeats what the pins together follow
    pins = found[LOAD_PINS]
    signal = 0.1 * payout.std()  # against the noise of a mean of four pins, 1/2 sigma
    assert pins.regressor == "payout" and pins.slope == pytest.approx(0.1, rel=0.05)
    assert pins.r == pytest.approx(signal / np.hypot(signal, 0.5), abs=0.05)
    assert pins.sentence.startswith(f"load-pin residuals follow the payout, r = {pins.r:.2f}")
    pitch = found["pitch"]
    assert pitch.regressor == "direction" and pitch.r > 0.8
    assert pitch.level_means["lowering"] == pytest.approx(1.5, abs=0.1)
    assert pitch.level_means["hoisting"] == pytest.approx(-1.5, abs=0.1)


def test_noise_and_unrelated_drift_give_no_finding():
    rng = np.random.default_rng(5)
    candidates = _regressors(rng)
    white = rng.normal(size=(ROWS, len(CHANNELS)))
    assert follows(white, list(CHANNELS), candidates) == []
    # drifting residuals correlate with any trend by chance; the effective sample size keeps that out
    findings = sum(len(follows(np.column_stack([_smooth(rng, 20.0) for _ in CHANNELS]), list(CHANNELS),
                               _regressors(rng))) for _ in range(10))
    assert findings <= 2  # of 10 x 7 residuals x 5 regressors; a naive n = 2000 test reports most of them


def _write_bag(path, count: int = 300):
    """Other topics beside a winch: a temperature (stamped 50 ms before logging), a motor current
    (no header: log time), an IMU on a crane, and a vendor type the reading type store does not know."""
    store = get_typestore(Stores.ROS2_JAZZY)  # the writer's store knows the vendor type, the reader's does not
    store.register(get_types_from_msg("float64 pressure\nstring note", "vendor_msgs/msg/Status"))
    def stamp(t: float) -> dict[str, int]:
        return {"sec": int(t), "nanosec": int(round((t - int(t)) * 1e9))}

    def header(t: float) -> dict[str, object]:
        return {"stamp": stamp(t), "frame_id": "shaft"}
    zero = [0.0] * 9
    with BagWriter(path, store) as writer:
        for k in range(count):
            t = 1000.0 + 0.5 * k
            log = int(round(t * 1e9))
            writer.write("/shaft/temperature", "sensor_msgs/msg/Temperature", log,
                         build("sensor_msgs/msg/Temperature", {"header": header(t - 0.05),
                                                               "temperature": 12.0 + 0.01 * k, "variance": 0.0}, store))
            writer.write("/winch/motor_current", "std_msgs/msg/Float64", log,
                         build("std_msgs/msg/Float64", {"data": 40.0 + np.sin(k / 10.0)}, store))
            writer.write("/crane/imu", "sensor_msgs/msg/Imu", log, build("sensor_msgs/msg/Imu", {
                "header": header(t), "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0},
                "orientation_covariance": zero, "angular_velocity": {"x": 0.0, "y": 0.0, "z": 0.01 * k},
                "angular_velocity_covariance": zero, "linear_acceleration": {"x": 0.0, "y": 0.0, "z": 9.8},
                "linear_acceleration_covariance": zero}, store))
            writer.write("/winch_1/joint_states", "sensor_msgs/msg/JointState", log, build(
                "sensor_msgs/msg/JointState", {"header": header(t), "name": ["winch_1"], "position": [60.0],
                                               "velocity": [0.0], "effort": [1e4]}, store))
            writer.write("/vendor/status", "vendor_msgs/msg/Status", log,
                         build("vendor_msgs/msg/Status", {"pressure": 1.0, "note": "ok"}, store))
    return path


def test_bag_fields_of_other_topics(tmp_path):
    bag = _write_bag(tmp_path / "extra")
    fields = read_fields(bag)
    imu = [f"/crane/imu.{part}.{axis}" for part in ("orientation", "angular_velocity", "linear_acceleration")
           for axis in "xyz"] + ["/crane/imu.orientation.w"]
    assert set(fields.series) == {"/shaft/temperature.temperature", "/shaft/temperature.variance",
                                  "/winch/motor_current.data", *imu}  # no stamps, covariances, strings, winches
    k = np.arange(300)
    t, v = fields.series["/shaft/temperature.temperature"]
    np.testing.assert_allclose(t, 1000.0 + 0.5 * k - 0.05, atol=1e-6)  # the header stamp
    np.testing.assert_allclose(v, 12.0 + 0.01 * k)
    t, v = fields.series["/winch/motor_current.data"]
    np.testing.assert_allclose(t, 1000.0 + 0.5 * k, atol=1e-6)  # no header: the log time
    np.testing.assert_allclose(v, 40.0 + np.sin(k / 10.0))
    np.testing.assert_allclose(fields.series["/crane/imu.angular_velocity.z"][1], 0.01 * k)
    assert "unknown type vendor_msgs/msg/Status" in fields.skipped["/vendor/status"]
    assert any("/vendor/status" in line for line in fields.remarks())


def test_bag_fields_are_capped_and_thinned_evenly(tmp_path):
    bag = _write_bag(tmp_path / "extra")
    fields = read_fields(bag, max_series=2, max_samples=40)
    assert len(fields.series) == 2 and any("not read" in note for note in fields.notes)
    for t, _ in fields.series.values():
        assert 20 <= t.size <= 40
        steps = np.diff(t)
        assert steps.max() <= 2.0 * steps.min() + 1e-9 and t[-1] - t[0] > 0.9 * 149.5  # even, whole span
    assert any("thinned evenly" in note for note in fields.notes)


@pytest.fixture(scope="module")
def rope_weight_bag(tmp_path_factory):
    """A recording whose ropes weigh 60 N/m, and a plant file that does not know it."""
    directory = tmp_path_factory.mktemp("rope_weight")
    plant = plant_file(directory, "elastic", SEED002, ELASTIC)
    return simulate_bag(directory, "rope_weight", plant, {"rope_weight": {"w": 60.0}}), plant


def test_compare_names_the_payout_for_a_hidden_rope_weight(tmp_path, rope_weight_bag):
    bag, plant = rope_weight_bag
    out, page = tmp_path / "compare.json", tmp_path / "compare.html"
    result = run_cli("compare", bag, "--config", plant, "--json", out, "--html", page)
    assert_clean(result, 0)
    first = json.loads(out.read_text())["follows"][0]
    assert first["channel"] == LOAD_PINS and first["regressor"] == "payout" and first["r"] > 0.8
    # the rope below each sheave adds w per metre of payout: the slope is the hidden weight per metre
    assert first["unit"] == "N" and first["slope"] == pytest.approx(60.0, rel=0.1)
    assert first["slope"] == pytest.approx(first["slope_sigma_per_unit"] * first["sigma"])
    assert "what the remaining error follows:\n  load-pin residuals follow the payout, r = " in result.stdout
    assert "What the remaining error follows" in page.read_text() and first["sentence"] in page.read_text()


@pytest.mark.slow
def test_diagnose_without_the_effect_in_its_library_names_the_payout(tmp_path, rope_weight_bag):
    bag, plant = rope_weight_bag
    out = tmp_path / "diagnose.json"
    result = run_cli("diagnose", bag, "--config", plant, "--candidates", "cog_offset,sheave_friction", "--json", out)
    assert_clean(result, 0)
    report = json.loads(out.read_text())
    assert report["selected"] == []  # neither stands in for the rope's weight ...
    first = report["follows"][0]      # ... and the held-out error still follows the payout
    assert first["channel"] == LOAD_PINS and first["regressor"] == "payout" and first["r"] > 0.8
    assert first["n"] == report["split"]["held_out_rows"] - sum(
        report["channels"][name]["count"] for name in ("roll", "depth"))  # winch rows of the held-out set
    assert f"what the remaining error follows:\n  {first['sentence']}" in result.stdout


STOP_AND_GO = {"start_length": 40.0, "segments": [{"move": 12.0, "speed": 1.0, "accel": 0.2}, {"stop": 3.0},
                                                  {"move": -8.0, "speed": 1.0, "accel": 0.2}, {"stop": 3.0}] * 3}


def test_load_pins_carrying_the_platform_inertia_follow_the_payout_acceleration(tmp_path):
    """The ropes carry m (g - a) while the winches accelerate; the model carries m g. The truth's
    acceleration is the simulator's commanded profile, which the ranking never sees."""
    plant = plant_file(tmp_path, "elastic", SEED002, ELASTIC)
    bag = simulate_bag(tmp_path, "stop_and_go", plant, {}, profile=STOP_AND_GO, duration=80.0)
    data = read_bag(bag)
    profile = Profile(STOP_AND_GO["start_length"], STOP_AND_GO["segments"])
    phase = np.clip(np.searchsorted(profile.starts, data.times, side="right") - 1, 0, None)
    accel = np.array([profile.phases[k].accel for k in phase])  # paying out faster: the platform accelerates down
    model = PlantModel.from_plant(load_plant(plant))
    pins = [data.channels.index(name) for name in TENSION_CHANNELS]
    data.measured[:, pins] -= model.plant.mass * accel[:, None] / 4.0  # shared by four ropes
    result = compare(model, data)
    first = result.follows[0]
    assert first.target == LOAD_PINS and first.regressor == "acceleration" and first.r < -0.7, first.sentence
    assert first.sigma == result.noise[pins[0]] and first.unit == "N"
    assert first.slope * first.sigma == pytest.approx(-model.plant.mass / 4.0, rel=0.1)  # N per m/s^2
    assert first.sentence.startswith("load-pin residuals follow the payout acceleration, r = -0.")


STEEL = 1.2e-5  # [1/K] thermal expansion of the ropes


def test_compare_names_a_field_of_a_topic_the_package_does_not_read(tmp_path):
    """The shaft air swings by 25 K and the ropes lengthen with it, so the platform hangs lower than the
    model puts it; the temperature is on a topic of its own in the bag, which the model does not read."""
    plant = plant_file(tmp_path, "elastic", SEED002, ELASTIC)
    recording = simulate_bag(tmp_path, "nominal", plant, {})
    bag = tmp_path / "with_temperature"

    def temperature(t: np.ndarray) -> np.ndarray:  # [deg C]: ventilation cycles
        return 5.0 + 25.0 * np.sin(2.0 * np.pi * t / 70.0)

    with BagWriter(bag) as writer:
        for item in BagReader(recording):
            writer.write_raw(item.topic, item.msgtype, item.log_time, item.data)
        for t in np.arange(0.0, 110.0, 1.0):
            stamp = {"sec": int(t), "nanosec": 0}
            writer.write("/shaft/temperature", "sensor_msgs/msg/Temperature", int(t * 1e9), build(
                "sensor_msgs/msg/Temperature", {"header": {"stamp": stamp, "frame_id": "shaft"},
                                                "temperature": float(temperature(t)), "variance": 0.0}))
    data = read_bag(bag)
    depth = data.channels.index("depth")
    data.measured[:, depth] -= STEEL * data.lengths.mean(axis=1) * (temperature(data.times) - 5.0)  # z is up
    result = compare(PlantModel.from_plant(load_plant(plant)), data, read_fields(bag))
    found = {f.target: f for f in result.follows}
    assert found["depth"].regressor == "/shaft/temperature.temperature" and found["depth"].r < -0.8
    assert found["depth"].sentence.startswith("depth residual follows /shaft/temperature.temperature, r = -0.")


def _dataset(rng: np.random.Generator, sideways: bool = False) -> Dataset:
    """Winch rows at 10 Hz of a platform lowered to 600 m and hoisted (or, `sideways`, of a robot whose winches 1
    and 4 pay out while 2 and 3 haul in, and back), with a shaft temperature cycling 18-34 degC."""
    t = np.arange(ROWS) / RATE
    payout = 100.0 + 250.0 * (1.0 - np.cos(2.0 * np.pi * t / 150.0))
    if sideways:
        swing = 0.3 * np.sin(2.0 * np.pi * t / 40.0)
        lengths = np.column_stack([1.5 + swing, 1.5 - swing, 1.5 - swing, 1.5 + swing])
    else:
        lengths = np.column_stack([payout] * 4) + 0.01 * rng.normal(size=(ROWS, 4)).cumsum(axis=0) / 30.0
    speeds, accelerations = derivatives(t, lengths, np.full((ROWS, 4), np.nan))
    temperature = 26.0 + 8.0 * np.sin(2.0 * np.pi * t / 120.0)
    return Dataset("synthetic", t, np.zeros(ROWS, int), lengths, speeds, accelerations,
                   np.full((ROWS, len(CHANNELS)), np.nan), tuple(CHANNELS),
                   inputs={"/shaft/temperature.temperature": temperature})


def test_depth_following_the_temperature_times_the_payout():
    """Ropes lengthening by alpha (T - T_ref) l: neither the temperature nor the payout alone, their product
    (with its offset T_ref unknown to the ranking) is what the depth error follows, its slope alpha."""
    rng = np.random.default_rng(11)
    data = _dataset(rng)
    temperature, payout = data.inputs["/shaft/temperature.temperature"], data.lengths.mean(axis=1)
    depth = data.channels.index("depth")
    data.measured[:, depth] = -10.0
    residuals = np.full_like(data.measured, np.nan)
    residuals[:, depth] = -1.2e-5 * (temperature - 20.0) * payout + rng.normal(0.0, 0.005, ROWS)
    noise = np.ones(len(CHANNELS))
    noise[depth] = 0.005
    found = what_follows(data, residuals, noise)
    assert found and found[0].target == "depth", [f.sentence for f in found]
    assert found[0].regressor == "/shaft/temperature.temperature x payout" and found[0].measure == "R"
    assert found[0].r < -0.8 and found[0].slope * 0.005 == pytest.approx(-1.2e-5, rel=0.05)  # alpha, in m per K m
    assert "times the payout, R = " in found[0].sentence


def test_each_load_pin_follows_its_own_winch_direction_times_its_tension():
    """Pulley friction on a robot moving sideways: each load cell reads mu T less paying out, more hauling in;
    the mean direction of the four winches is nil throughout."""
    rng = np.random.default_rng(12)
    data = _dataset(rng, sideways=True)
    assert np.all(np.abs(np.sign(data.directions.sum(axis=1))) < 1)  # two winches each way: no common direction
    tensions = 30.0 + 5.0 * np.sin(np.arange(ROWS)[:, None] / 50.0 + np.arange(4))
    pins = [data.channels.index(name) for name in TENSION_CHANNELS]
    data.measured[:, pins] = tensions
    residuals = np.full_like(data.measured, np.nan)
    residuals[:, pins] = -0.08 * data.directions * tensions + rng.normal(0.0, 0.3, (ROWS, 4))
    data.measured[:, pins] += residuals[:, pins]  # measured = the model's tension + residual
    noise = np.full(len(CHANNELS), 0.3)
    found = what_follows(data, residuals, noise)
    assert [(f.target, f.regressor) for f in found] == [(LOAD_PINS, "direction x tension")], \
        [f.sentence for f in found]
    assert found[0].slope * 0.3 == pytest.approx(-0.08, rel=0.1)  # mu wrap: N per N of tension paying out
