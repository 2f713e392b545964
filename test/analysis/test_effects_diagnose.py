"""Every built-in effect hidden in simulated data is found by `diagnose`, its parameters recovered."""
from __future__ import annotations

import pytest
from effectbags import ELASTIC, SEED002, SHALLOW, WIDE, plant_file, simulate_bag

from cable_winch_monitor.analysis.data import read_bag
from cable_winch_monitor.analysis.diagnose import diagnose
from cable_winch_monitor.analysis.evaluate import noise
from cable_winch_monitor.effects import PlantModel, available
from cable_winch_monitor.model.plantfile.plant import load_plant

# effect: (hidden parameters, plant, profile); a geometry differs only where the effect needs it to show
CASES = {
    "rope_elasticity": ({"EA": 7.5e7}, "rigid", None),
    "rope_weight": ({"w": 60.0}, "elastic", None),
    "encoder_scale": ({"k_1": 4e-4, "k_2": -2e-4, "k_3": 3e-4, "k_4": -1e-4}, "elastic", None),
    "encoder_offset": ({"d_1": 0.02, "d_2": -0.015, "d_3": 0.01, "d_4": 0.005}, "elastic", None),
    "sheave_friction": ({"mu": 0.04}, "elastic", None),
    "cog_offset": ({"dx": 0.15, "dy": -0.1}, "elastic", None),
    "payload_mass": ({"dm": 400.0}, "elastic", None),
    # the tangent point moves by r (1 - cos phi): second order in the rope angle, so it needs
    # strongly inclined ropes (wide sheaves, shallow platform) to show at all
    "sheave_geometry": ({"r": 2.5}, "wide", SHALLOW),
    "tension_sensor_bending": ({"B": 150.0}, "elastic", None),
    "load_pin_calibration": ({"zero_1": 2000.0, "zero_3": -1500.0, "gain_2": 0.03, "gain_4": -0.02}, "elastic", None),
    # ropes up posts from winches at their feet, over pulleys: the wrapped arc changes with the rope angle
    "pulley_geometry": ({"r": 1.0}, "wide", SHALLOW),
}


# effects of a sensor's mounting, applied to the recorded readings themselves (the simulator's
# inclinometer reads the true attitude): effect -> (channel offsets, confounders screened with it)
MOUNTED = {"inclinometer_offset": ({"roll": 0.01, "pitch": -0.008}, ["cog_offset", "encoder_offset"])}


@pytest.fixture(scope="module")
def plants(tmp_path_factory):
    directory = tmp_path_factory.mktemp("plants")
    return {"elastic": plant_file(directory, "elastic", SEED002, ELASTIC),
            "rigid": plant_file(directory, "rigid", SEED002, {}),
            "wide": plant_file(directory, "wide", WIDE, ELASTIC)}


def _diagnosis(tmp_path, plants, name, hidden, plant, profile):
    kwargs = {"profile": profile, "duration": 100.0} if profile else {}
    if name == "rope_elasticity":  # the scenario's own switch for elastic truth
        bag = simulate_bag(tmp_path, name, plants[plant], {}, ropes={"model": "elastic", "EA": hidden["EA"]}, **kwargs)
    else:
        bag = simulate_bag(tmp_path, name, plants[plant], {name: hidden}, **kwargs)
    base = PlantModel.from_plant(load_plant(plants[plant]))
    data = read_bag(bag)
    return diagnose(base, data, noise(base, data)[0], list(CASES))


def test_every_builtin_has_a_case():
    builtins = {name for name, cls in available().items() if cls.__module__.startswith("cable_winch_monitor.")}
    assert builtins == set(CASES) | set(MOUNTED)


@pytest.mark.slow
@pytest.mark.parametrize("name", list(MOUNTED))
def test_mounting_offset_is_found(tmp_path, plants, name):
    """The readings of a tilted sensor are the platform's attitude plus the mounting: shift the recorded columns."""
    offsets, confounders = MOUNTED[name]
    bag = simulate_bag(tmp_path, "nominal", plants["elastic"], {}, duration=60.0)
    base = PlantModel.from_plant(load_plant(plants["elastic"]))
    data = read_bag(bag)
    for channel, offset in offsets.items():
        data.measured[:, data.channels.index(channel)] += offset
    result = diagnose(base, data, noise(base, data)[0], [name, *confounders])
    assert result.selected == [name], [(c.name, c.score_after) for c in result.ranking]
    params = result.final.params(name)
    for key, true in offsets.items():
        assert abs(params[key]["value"] - true) <= 0.1 * abs(true), (key, true, params[key])
    assert result.ladder[0].score_heldout > 5.0 and result.ladder[-1].score_heldout <= 1.3


@pytest.mark.slow
@pytest.mark.parametrize("name", list(CASES))
def test_hidden_effect_is_found(tmp_path, plants, name):
    hidden, plant, profile = CASES[name]
    result = _diagnosis(tmp_path, plants, name, hidden, plant, profile)
    assert result.ranking[0].name == name, [(c.name, c.score_after) for c in result.ranking]
    best = result.ranking[0]
    assert result.selected == [name]
    params = result.final.params(name)
    for key, true in hidden.items():
        value, sigma = params[key]["value"], params[key]["sigma"]
        assert abs(value - true) <= max(0.1 * abs(true), 2.0 * sigma), (key, true, value, sigma)
    assert result.ladder[-1].score_heldout <= 1.3 < best.score_before or name == "sheave_geometry"
    assert result.ladder[-1].score_heldout <= 1.3


@pytest.mark.slow
def test_nothing_hidden_selects_nothing(tmp_path, plants):
    bag = simulate_bag(tmp_path, "nominal", plants["elastic"], {})
    base = PlantModel.from_plant(load_plant(plants["elastic"]))
    data = read_bag(bag)
    result = diagnose(base, data, noise(base, data)[0], list(CASES))
    assert result.selected == [] and result.final is None
    assert result.ladder[0].score_heldout < 1.15
    assert len(result.ranking) == len(CASES) - 1  # every candidate was screened and none was significant
