"""Channels declared once, conditions every effect sees, loads effects act on, one solve path.

The bags here are written with the package's own writer from hand-made messages: these
tests are about plumbing (which value reaches which effect or channel), not about fits.
"""
from __future__ import annotations

import math
import textwrap
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from cable_winch_monitor import channels
from cable_winch_monitor.analysis.compare import compare
from cable_winch_monitor.analysis.data import read_bag
from cable_winch_monitor.bagio.reader import BagError
from cable_winch_monitor.bagio.writer import BagWriter
from cable_winch_monitor.channels import BUILTIN_CHANNELS, Channel, ChannelError, ChannelRegistry, declare
from cable_winch_monitor.effects import EffectError, PlantModel, Registry, effect_class
from cable_winch_monitor.messages.fields import header
from cable_winch_monitor.messages.records import build
from cable_winch_monitor.model.conditions import Conditions, ConditionsTracker, derivatives
from cable_winch_monitor.model.plantfile.plant import CABLE_NAMES, PlantConfigError, load_plant, plant_from_mapping
from cable_winch_monitor.monitor.clearance import solution_clearance
from cable_winch_monitor.monitor.inputs import JointSample
from cable_winch_monitor.monitor.limits import synchronisation_limits
from cable_winch_monitor.monitor.pipeline import MonitorPipeline

PACKAGE = Path(__file__).resolve().parents[1] / "cable_winch_monitor"
EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
CAGE_CHANNEL = '''
"""A sensor the package does not know: a load cell under the platform's cage, reading the sum of the tensions."""
from cable_winch_monitor.channels import Channel, declare

declare(Channel("cage_load", "N", "cage_load", ("/cage/load",), "std_msgs/msg/Float64", "data",
                predict=lambda solution, plant, conditions: float(solution.tensions.sum())))
'''


def ramp(t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Payout 50 m + a ramp accelerating at 0.2 m/s^2 for 5 s, then 1 m/s: lengths, speeds, accelerations."""
    accelerating = t < 5.0
    lengths = np.where(accelerating, 50.0 + 0.1 * t ** 2, 52.5 + (t - 5.0))
    speeds = np.where(accelerating, 0.2 * t, 1.0)
    return lengths, speeds, np.where(accelerating, 0.2, 0.0)


def test_payout_accelerations_from_speeds_and_from_lengths_alone():
    rng = np.random.default_rng(1)
    t = np.arange(0.0, 10.0, 0.1)
    lengths, speeds, truth = ramp(t)
    noisy_lengths = lengths[:, None] + rng.normal(0.0, 0.001, (t.size, 4))
    noisy_speeds = speeds[:, None] + rng.normal(0.0, 0.002, (t.size, 4))
    inside = (np.abs(t - 5.0) > 0.6) & (t > 0.6) & (t < 9.4)  # a window away from the kink and the ends
    _, from_speeds = derivatives(t, noisy_lengths, noisy_speeds)
    speeds_from_lengths, from_lengths = derivatives(t, noisy_lengths, np.full((t.size, 4), np.nan))
    assert np.abs(from_speeds[inside] - truth[inside, None]).max() < 0.02
    assert np.abs(speeds_from_lengths[inside] - speeds[inside, None]).max() < 0.01
    assert np.abs(from_lengths[inside] - truth[inside, None]).max() < 0.05
    tracker = ConditionsTracker()
    live = [tracker.update(t[k:k + 1], noisy_lengths[k:k + 1], noisy_speeds[k:k + 1])[0] for k in range(t.size)]
    late = (t > 2.0) & (t < 4.9)  # the causal window has filled and not yet met the kink
    assert np.abs(np.array([c.acceleration for c in live])[late] - 0.2).max() < 0.02
    assert live[-1].direction.tolist() == [1.0] * 4 and live[-1].time == pytest.approx(t[-1])


def test_a_load_effect_changes_the_tensions_by_m_times_a():
    registry = Registry([EXAMPLES / "platform_inertia.py"])
    model = PlantModel(load_plant(), (registry.effect_class("platform_inertia")({"k": 1.0}),), registry=registry)
    lengths = np.array([120.3, 120.1, 120.5, 120.2])
    still = model.solve(lengths, conditions=Conditions())
    braking = Conditions(accelerations=np.full(4, -0.4))  # a lowering braking: the ropes carry m (g + 0.4)
    moving = model.solve(lengths, conditions=braking)
    plant = model.plant
    assert still.ok and moving.ok and moving.taut_set == still.taut_set
    np.testing.assert_allclose(moving.tensions, still.tensions * (plant.g + 0.4) / plant.g, rtol=1e-9)
    np.testing.assert_allclose(moving.load[:3], [0.0, 0.0, -plant.mass * (plant.g + 0.4)])


def write_bag(path: Path, temperature: bool = True, cage: bool = False) -> Path:
    """Ten seconds of one platform sample per 0.1 s: joint states (lengths, speeds, load pins), a shaft
    temperature at 1 Hz rising 1 K/s, and a cage load cell."""
    solution = MonitorPipeline(load_plant()).model.solve(np.full(4, 60.0))
    with BagWriter(path) as writer:
        for k in range(100):
            stamp = (k // 10, (k % 10) * 100_000_000)
            ns = stamp[0] * 1_000_000_000 + stamp[1]
            writer.write("/winch/joint_states", channels.JOINT_STATE, ns, build(channels.JOINT_STATE, {
                "header": header(stamp, ""), "name": list(CABLE_NAMES), "position": [60.0 + 0.01 * k] * 4,
                "velocity": [0.1] * 4, "effort": solution.tensions.tolist()}))
            if temperature and k % 10 == 5:
                writer.write("/shaft/temperature", "sensor_msgs/msg/Temperature", ns, build(
                    "sensor_msgs/msg/Temperature", {"header": header(stamp), "temperature": 20.0 + k / 10.0,
                                                    "variance": 0.01}))
            if cage and k % 2 == 1:
                writer.write("/cage/load", "std_msgs/msg/Float64", ns, build("std_msgs/msg/Float64",
                                                                              {"data": load_plant().weight + 500.0}))
    return path


def test_an_extra_input_reaches_the_effect_interpolated_in_analysis_and_latest_live(tmp_path):
    registry = Registry([EXAMPLES / "rope_temperature.py"])
    warm = PlantModel(load_plant(), (registry.effect_class("rope_temperature")(),), registry=registry)
    spec = warm.inputs[0]
    data = read_bag(write_bag(tmp_path / "warm"), warm)
    rows = data.kinds == 0
    inside = rows & (data.times > 0.5) & (data.times < 9.5)
    np.testing.assert_allclose(data.inputs[spec.key][inside], 20.0 + data.times[inside], atol=1e-9)
    with pytest.raises(BagError, match="/shaft/temperature"):
        read_bag(write_bag(tmp_path / "no_temperature", temperature=False), warm)
    plant = load_plant()
    config = {"plant": {**plant.raw["plant"], "effects": {"rope_temperature": {"alpha": 1.2e-5}},
                        "effect_modules": [str(EXAMPLES / "rope_temperature.py")]}}
    pipeline = MonitorPipeline(plant_from_mapping(config))
    assert [i.key for i in pipeline.model.inputs] == [spec.key]
    pipeline.on_input(spec, 3.5, SimpleNamespace(temperature=23.5))
    pipeline.on_input(spec, 4.5, SimpleNamespace(temperature=24.5))
    assert pipeline.inputs_at(4.0) == {spec.key: pytest.approx(24.0)}
    assert pipeline.inputs_at(9.0) == {spec.key: pytest.approx(24.5)}  # live: the latest value
    output = pipeline.on_joint_state(JointSample(9.0, CABLE_NAMES, [300.0] * 4))
    cold = PlantModel(plant).solve([300.0] * 4)
    assert output.solution.position[2] == pytest.approx(cold.position[2] - 300.0 * 1.2e-5 * 4.5, abs=1e-6)


def test_a_user_channel_takes_part_in_compare_and_in_the_residuals(tmp_path):
    module = tmp_path / "cage.py"
    module.write_text(textwrap.dedent(CAGE_CHANNEL))  # a module that only declares a channel (no effect)
    plant = plant_from_mapping({"plant": {**load_plant().raw["plant"], "effect_modules": [str(module)], "noise": {
        **load_plant().noise, "cage_load": 200.0}}})
    model = PlantModel.from_plant(plant)
    assert "cage_load" in model.channels.names() and model.channels.user
    assert model.reads_conditions  # no effect: the user's channel reads them
    data = read_bag(write_bag(tmp_path / "cage", cage=True), model)
    column = data.channels.index("cage_load")
    assert np.isfinite(data.measured[:, column]).sum() >= 40
    result = compare(model, data)
    assert result.channels["cage_load"].rms == pytest.approx(500.0, abs=1.0)  # reads m g + 500 N
    assert result.channels["cage_load"].noise == 200.0
    pipeline = MonitorPipeline(plant)
    pipeline.on_joint_state(JointSample(1.0, CABLE_NAMES, [60.0] * 4))
    residual = pipeline.on_measurement("/cage/load", 1.01, SimpleNamespace(data=plant.weight + 500.0))
    assert residual.channels == ("cage_load",) and residual.values[0] == pytest.approx(500.0, abs=1e-6)


def test_a_users_module_changes_only_the_models_whose_plant_file_names_it(tmp_path):
    """Two plant models in one process, one with a user's sensor: the other neither reads nor fuses it, and a
    module's channels are taken by every model that names it, however often it is named."""
    module = tmp_path / "cage.py"
    module.write_text(textwrap.dedent(CAGE_CHANNEL))
    raw = load_plant().raw["plant"]
    caged = PlantModel.from_plant(plant_from_mapping({"plant": {**raw, "effect_modules": [str(module)]}}))
    again = PlantModel.from_plant(plant_from_mapping({"plant": {**raw, "effect_modules": [str(module)]}}))
    plain = PlantModel.from_plant(load_plant())
    assert "cage_load" in caged.channels.names() and "cage_load" in again.channels.names()
    assert "cage_load" not in plain.channels.names() and not plain.channels.user
    assert plain.channels.names() == BUILTIN_CHANNELS.names()
    assert MonitorPipeline(load_plant()).read_channels("/cage/load", SimpleNamespace(data=1.0)) == {}
    with pytest.raises(PlantConfigError, match="plant.noise.cage_load"):  # a plain model's file cannot weigh it
        PlantModel.from_plant(plant_from_mapping({"plant": {**raw, "noise": {**load_plant().noise, "cage_load": 1.0}}}))


def test_a_channel_is_declared_in_a_module_or_given_to_a_registry_of_ones_own():
    cage = Channel("cage_load", "N", "cage_load", ("/cage/load",), "std_msgs/msg/Float64", "data",
                   predict=lambda solution, plant, conditions: 0.0)
    with pytest.raises(ChannelError, match="declare\\(\\) is for an effect module"):
        declare(cage)
    assert ChannelRegistry([cage]).sensor_of("cage_load") == "/cage/load"
    with pytest.raises(ChannelError, match="declared twice"):
        ChannelRegistry([cage, replace(cage, topics=("/other/load",))])


def test_traversal_is_kept_with_effects_and_refused_with_elastic_ropes():
    plant = load_plant()
    model = PlantModel(plant, (effect_class("cog_offset")({"dx": 0.1}),), solver="traversal")
    assert model.solve([20.3, 20.1, 20.5, 20.2]).method == "traversal"
    pipeline = MonitorPipeline(plant_from_mapping({"plant": {**plant.raw["plant"], "effects": {
        "cog_offset": {"dx": 0.1}}}}), solver="traversal")
    output = pipeline.on_joint_state(JointSample(1.0, CABLE_NAMES, [20.3, 20.1, 20.5, 20.2]))
    assert output.solution.method == "traversal"
    with pytest.raises(EffectError, match="rope_elasticity"):
        PlantModel(plant, (effect_class("rope_elasticity")({"EA": 7.5e7}),), solver="traversal")


def test_clearance_is_the_plant_with_its_effects():
    plant = load_plant()
    narrow = textwrap.dedent('''
        from cable_winch_monitor.effects import Effect, Parameter

        class WiderDecks(Effect):
            """Decks that stick out further than the plant file says (a test of where clearance is computed)."""
            name = "wider_decks"
            acts = "geometry"
            parameters = (Parameter("s", "-", 1.05, (1.0, 2.0), 0.01, "outline scale"),)

            def plant(self, plant):
                from cable_winch_monitor.model.plantfile.plant import OutlinePoint
                return plant.with_changes(outline=tuple(OutlinePoint(p.name, p.position * [self["s"], self["s"], 1.0])
                                                        for p in plant.outline))
        ''')
    path = Path(PACKAGE.parent / "build")
    path.mkdir(exist_ok=True)
    module = path / "wider_decks_effect.py"
    module.write_text(narrow)
    config = {"plant": {**plant.raw["plant"], "effects": {"wider_decks": {"s": 1.05}}, "effect_modules": [str(module)]}}
    pipeline = MonitorPipeline(plant_from_mapping(config))
    output = pipeline.on_joint_state(JointSample(1.0, CABLE_NAMES, [120.0] * 4))
    nominal = solution_clearance(plant, output.solution)
    assert output.clearance.value == pytest.approx(nominal.value - 0.05 * 3.6, abs=1e-6)
    checked, clearance, _ = pipeline.evaluate([120.0] * 4)
    assert clearance.value == pytest.approx(output.clearance.value)


def test_limits_use_the_plants_effects():
    plant = load_plant()
    groups = [(0,), (1,)]
    rigid = synchronisation_limits(PlantModel(plant), 300.0, groups)
    elastic = synchronisation_limits(PlantModel(plant, (effect_class("rope_elasticity")({"EA": 7.5e7}),)), 300.0,
                                     groups)
    assert all(limit.taut_limit == pytest.approx(0.02, abs=1e-3) for limit in rigid)  # rigid: slack at once
    assert all(e.taut_limit > r.taut_limit + 0.01 for e, r in zip(elastic, rigid))  # stretched ropes stay taut


def test_channel_list_is_the_one_declaration():
    names = BUILTIN_CHANNELS.names()
    assert names[:4] == channels.TENSION_CHANNELS and {"roll", "pitch", "depth"} <= set(names)
    predicted = PlantModel(load_plant()).predict(PlantModel(load_plant()).solve([60.0] * 4))
    assert set(names) <= set(predicted) and all(math.isfinite(predicted[n]) for n in names)
