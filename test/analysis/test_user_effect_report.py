"""A user's own effect (a module outside the package) in simulate, compare, diagnose and fit; the plant
file `fit` writes drives replay (the HTML report: test_report_html.py)."""
from __future__ import annotations

import json
import textwrap

import pytest
from effectbags import ELASTIC, SEED002, plant_file, simulate_bag
from simbags import assert_clean, run_cli

from cable_winch_monitor.model.plantfile.plant import load_plant
from cable_winch_monitor.monitor.pipeline import MonitorPipeline

USER_EFFECT = '''
"""A load-pin zero error per cable: not in the library."""
from cable_winch_monitor.effects import Effect, Parameter
from cable_winch_monitor.model.plantfile.plant import CABLE_NAMES


class LoadPinBias(Effect):
    """Each load pin reads b_i more than the rope tension (zero drift of the strain gauges)."""

    name = "load_pin_bias"
    title = "the load pins' zero has drifted"
    acts = "measurement"
    parameters = tuple(Parameter(f"b_{i}", "N", 0.0, (-2e4, 2e4), 200.0, f"zero error, pin {i}") for i in range(1, 5))
    signature = "a constant tension offset per cable"

    def measure(self, channels, solution, plant, conditions):
        for i, name in enumerate(CABLE_NAMES, 1):
            channels[f"tension_{name}"] += self[f"b_{i}"]
'''
BIAS = {"b_1": 3000.0, "b_2": 0.0, "b_3": -2000.0, "b_4": 1500.0}


@pytest.fixture(scope="module")
def user_bag(tmp_path_factory):
    directory = tmp_path_factory.mktemp("user_effect")
    module = directory / "my_effects.py"
    module.write_text(textwrap.dedent(USER_EFFECT))
    plant = plant_file(directory, "elastic", SEED002, ELASTIC)
    bag = simulate_bag(directory, "biased", plant, {"load_pin_bias": BIAS}, duration=90.0,
                       effect_modules=[str(module)])
    return directory, module, plant, bag


def _json(path):
    return json.loads(path.read_text())


@pytest.mark.slow
def test_user_effect_found_fitted_and_used(user_bag):
    directory, module, plant, bag = user_bag
    before = directory / "compare.json"
    assert_clean(run_cli("compare", bag, "--config", plant, "--json", before), 0)
    assert _json(before)["score"] > 2.0
    diagnosis = directory / "diagnose.json"
    # the built-in load_pin_calibration (zero and gain) would explain the same bias: screened without it
    candidates = "load_pin_bias,payload_mass,sheave_friction,encoder_offset,tension_sensor_bending"
    result = run_cli("diagnose", bag, "--config", plant, "--effect-module", module, "--json", diagnosis,
                     "--candidates", candidates)
    assert_clean(result, 0)
    assert "the load pins' zero has drifted" in result.stdout
    ranked = _json(diagnosis)["effects"]
    assert ranked[0]["name"] == "load_pin_bias" and ranked[0]["selected"]
    fitted = directory / "fit.json"
    new_plant = directory / "fitted_plant.yaml"
    assert_clean(run_cli("fit", bag, "--config", plant, "--effect-module", module, "--effects", "load_pin_bias",
                         "--write-config", new_plant, "--json", fitted), 0)
    fit = _json(fitted)
    for key, true in BIAS.items():
        value, sigma = fit["effects"][0]["params"][key], fit["effects"][0]["uncertainties"][key]
        assert abs(value - true) <= max(0.1 * abs(true), 2.0 * sigma)
    assert fit["before"]["held_out"]["score"] > 2.0 and fit["after"]["held_out"]["score"] <= 1.3
    # the written plant file names the module: compare and the monitor pipeline use the effect without flags
    after = directory / "compare_after.json"
    assert_clean(run_cli("compare", bag, "--config", new_plant, "--json", after), 0)
    assert _json(after)["score"] <= 1.3
    assert MonitorPipeline(load_plant(new_plant)).model.names() == ["rope_elasticity", "load_pin_bias"]
    replayed = run_cli("replay", bag, "--out", directory / "replayed", "--config", new_plant, "--quiet")
    assert_clean(replayed, 0)
    assert "tension states: taut {1,2,3,4}" in replayed.stdout  # elastic ropes from the plant file: all four carry
