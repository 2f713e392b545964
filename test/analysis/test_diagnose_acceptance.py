"""diagnose and compare as a user runs them -- the command line, every library effect a candidate, the default
time budget -- on recordings a site or a laboratory would have, each simulated by the simulator's own physics
for the hidden effect (sim/physics.py, root-found equilibrium in sim/truth.py) at realistic noise:

1. a 20-minute sinking run 50-650 m (config/scenarios/sinking_run.yaml) whose ropes are elastic (EA 6.8e7 N)
   and weigh 58 N/m, against the bundled rigid plant: exactly rope_elasticity and rope_weight; the same with one
   winch's zero 3 cm off and the centre of gravity moved (+0.10, -0.08) m: exactly those four effects;
2. ropes lengthening with the shaft air (alpha 1.2e-5 /K, 18-34 degC on /shaft/temperature) against the right
   elastic plant: with the user's effect (examples/rope_temperature.py) exactly that; without it, what the
   error follows names the temperature times the payout, and the library effect standing in for it is a
   partial explanation;
3. the laboratory robot over its swivel pulleys with four calibration errors (test/helpers/labbags.py): exactly those.

Values within 10 %, held-out score <= 1.3, every selected fit converged. The stamps start at 1.7e9 s (clock
time): every time in the output is from the start of the recording. Minutes each: `make test-slow`.
"""
from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
import yaml
from labbags import EA as LAB_EA
from labbags import HIDDEN as LAB_HIDDEN
from labbags import LAB_PLANT, lab_bag
from simbags import assert_clean, run_cli

from cable_winch_monitor.analysis.data import read_bag
from cable_winch_monitor.analysis.evaluate import Evaluator, noise, split, thin
from cable_winch_monitor.effects import PlantModel
from cable_winch_monitor.model.plantfile.plant import load_plant
from cable_winch_monitor.paths import default_plant_file
from cable_winch_monitor.sim.scenario import load_scenario, scenario_path
from cable_winch_monitor.sim.simulate import simulate

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
WEIGHT = {"rope_weight": {"w": 58.0}}
MIXED = {**WEIGHT, "encoder_offset": {"d_2": 0.03}, "cog_offset": {"dx": 0.10, "dy": -0.08}}
TEMPERATURE = {"rope_temperature": {"alpha": 1.2e-5, "T_ref": 20.0}}


def _site_bag(directory: Path, name: str, effects: dict, ea: float = 6.8e7, air: dict | None = None) -> Path:
    """The bundled 20-minute sinking run (config/scenarios/sinking_run.yaml: 50-650 m at site noise, stamped
    from 1.7e9 s) with ropes of stiffness `ea` and the hidden `effects` instead of its rope weight."""
    config = load_scenario(scenario_path("sinking_run"))
    assert config["start_time"] > 1e9 and config["effects"] == WEIGHT  # clock time; what the file hides
    config["ropes"]["EA"], config["effects"] = ea, effects
    config["shaft_air"].update(air or {})
    simulate(config, directory / name)
    return directory / name


def _elastic_plant(directory: Path, ea: float) -> Path:
    """The bundled plant file with its ropes elastic: what a user who knows the ropes' stiffness has."""
    config = yaml.safe_load(default_plant_file().read_text())
    config["plant"]["effects"] = {"rope_elasticity": {"EA": ea}}
    path = directory / "elastic_plant.yaml"
    path.write_text(yaml.safe_dump(config))
    return path


def _diagnose(bag: Path, *options: str | Path) -> tuple[dict, str]:
    """`cable-winch-monitor diagnose BAG OPTIONS --json`: the JSON and the text, checked to be clean."""
    out = bag.parent / f"{bag.name}_diagnose.json"
    result = run_cli("diagnose", bag, *options, "--json", out, timeout=600.0)
    assert_clean(result, 0)
    return json.loads(out.read_text()), result.stdout


def _heldout_score(bag: Path, plant: Path | None, effects: dict, module: Path | None = None) -> float:
    """The true model's score on the held-out rows diagnose scores on: what 'down to the noise' is here."""
    file = load_plant(plant) if plant else load_plant()
    model = PlantModel.from_plant(file.with_changes(effect_modules=(str(module),)) if module is not None else file)
    model = model.with_effects([model.registry.effect_class(name)(values, model.plant)
                                for name, values in effects.items()])
    data = read_bag(bag, model)
    return Evaluator(data.subset(thin(split(data)[1], data.kinds, 150)), model).score(model, noise(model, data)[0])


def _assert_found(report: dict, text: str, hidden: dict) -> None:
    """Exactly the hidden effects selected and found (converged, honest), each fitted value within 10 % of the
    truth (one the truth leaves at zero within 10 % of the effect's largest), the held-out score <= 1.3, no
    time in clock seconds."""
    assert sorted(report["selected"]) == sorted(hidden), (report["selected"], report["refused"], report["unfinished"])
    assert sorted(report["found"]) == sorted(hidden) and not report["partial"]
    effects = {e["name"]: e for e in report["effects"]}
    for name, params in hidden.items():
        largest = max(abs(v) for v in params.values())
        fitted = {k: v for k, v in effects[name]["params"].items() if effects[name]["uncertainties"][k] is not None}
        assert set(params) <= set(fitted), (name, fitted)
        for key, value in fitted.items():
            assert abs(value - params.get(key, 0.0)) <= 0.1 * (abs(params[key]) if key in params else largest), \
                (name, key, value, params)
    assert report["score_after"] <= 1.3 < report["score"]
    assert not re.search(r"\b1[67]\d{8}(\.\d+)?\b", text), "a time printed in clock seconds"


@pytest.mark.slow
@pytest.mark.parametrize("hidden", [WEIGHT, MIXED], ids=["weight", "weight, a winch's zero, the centre of gravity"])
def test_elastic_ropes_against_the_rigid_plant(tmp_path, hidden):
    bag = _site_bag(tmp_path, "site", hidden)
    truth = {"rope_elasticity": {"EA": 6.8e7}, **hidden}
    assert _heldout_score(bag, None, truth) < 1.15
    report, text = _diagnose(bag)
    _assert_found(report, text, truth)


@pytest.fixture(scope="module")
def warm_ropes(tmp_path_factory):
    """Ropes lengthening with the shaft air, which cycles 18-34 degC over the sinking run; the plant file is
    right but for that."""
    directory = tmp_path_factory.mktemp("temperature")
    air = {"temperature": 26.0, "amplitude": 8.0, "period": 600.0}
    return _site_bag(directory, "temperature", TEMPERATURE, ea=7.5e7, air=air), _elastic_plant(directory, 7.5e7)


@pytest.mark.slow
def test_the_users_temperature_effect_is_found(warm_ropes):
    bag, plant = warm_ropes
    module = EXAMPLES / "rope_temperature.py"
    assert _heldout_score(bag, plant, TEMPERATURE, module) < 1.15
    report, text = _diagnose(bag, "--config", plant, "--effect-module", module)
    _assert_found(report, text, {"rope_temperature": {"alpha": 1.2e-5}})


@pytest.mark.slow
def test_without_the_temperature_effect_the_error_follows_temperature_times_payout(warm_ropes, tmp_path):
    bag, plant = warm_ropes
    follows = "/shaft/temperature.temperature x payout"
    report, text = _diagnose(bag, "--config", plant)
    assert report["partial"] and report["found"] == []  # a stand-in explains part of it: not found
    assert all(e["partial"] and not e["found"] for e in report["effects"] if e["selected"])
    assert re.search(r"partial explanation: .*\[\w+: ", text) and "\nfound:" not in text
    first = report["follows"][0]
    assert first["channel"] == "depth" and first["regressor"] == follows and first["r"] < -0.8
    assert first["slope"] == pytest.approx(-1.2e-5, rel=0.1)  # metres of depth per K per metre of payout: alpha
    assert "depth residual follows /shaft/temperature.temperature times the payout" in text
    out, page = tmp_path / "compare.json", tmp_path / "compare.html"
    result = run_cli("compare", bag, "--config", plant, "--json", out, "--html", page, timeout=300.0)
    assert_clean(result, 0)
    compared = json.loads(out.read_text())
    assert compared["follows"][0]["regressor"] == follows and compared["failure_regions"]
    assert "depth residual follows /shaft/temperature.temperature times the payout" in result.stdout
    assert follows in page.read_text() and compared["follows"][0]["sentence"] in page.read_text()


@pytest.mark.slow
def test_the_lab_robots_calibration_errors_are_found(tmp_path):
    bag = lab_bag(tmp_path)
    hidden = {**LAB_HIDDEN, "rope_elasticity": {"EA": LAB_EA}}
    assert _heldout_score(bag, LAB_PLANT, hidden) < 1.15
    report, text = _diagnose(bag, "--config", LAB_PLANT)
    _assert_found(report, text, hidden)
