"""The plant file's tracking keys (`plant.track`, `plant.track_tolerance`, the shares of use): names resolved
against the effects, tolerances against the file's values; a wrong key is one line naming it, before any work."""
from __future__ import annotations

import copy
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from cable_winch_monitor.effects import PlantModel
from cable_winch_monitor.effects.base import span
from cable_winch_monitor.effects.tracked import tracked_parameters
from cable_winch_monitor.model.plantfile.plant import PlantConfigError, load_plant
from cable_winch_monitor.paths import default_plant_file

BASE = yaml.safe_load(default_plant_file().read_text())
ROOT = Path(__file__).resolve().parents[2]


def plant_file(tmp_path: Path, **keys) -> Path:
    config = copy.deepcopy(BASE)
    config["plant"].update(keys)
    path = tmp_path / "plant.yaml"
    path.write_text(yaml.safe_dump(config))
    return path


def test_names_resolve_to_parameters_with_their_start_and_tolerance(tmp_path):
    """An effect switched on starts at the file's value, one switched off at its default; an effect's name
    alone tracks every parameter it fits (not its settings); tolerances by parameter, by effect, or 5 % of the
    file's value (twice the fit step where that is zero)."""
    path = plant_file(tmp_path, effects={"rope_elasticity": {"EA": 6.8e7}, "sheave_friction": {"enabled": False}},
                      track=["rope_elasticity.EA", "encoder_offset", "sheave_friction", "rope_weight.w"],
                      track_tolerance={"encoder_offset": {"absolute": 0.01}, "encoder_offset.d_3": {"absolute": 0.02},
                                       "rope_weight.w": {"relative": 0.1}},
                      track_sigma=0.3, track_rate=2.0)
    plant = load_plant(path)
    PlantModel.from_plant(plant)
    tracked = {t.key: t for t in tracked_parameters(plant)}
    assert list(tracked) == ["rope_elasticity.EA", "encoder_offset.d_1", "encoder_offset.d_2", "encoder_offset.d_3",
                             "encoder_offset.d_4", "sheave_friction.mu", "rope_weight.w"]
    ea = tracked["rope_elasticity.EA"]
    assert ea.start == 6.8e7 and ea.enabled and ea.tolerance == pytest.approx(0.05 * 6.8e7) and ea.acts == "rope_law"
    assert [tracked[f"encoder_offset.d_{i}"].tolerance for i in range(1, 5)] == [0.01, 0.01, 0.02, 0.01]
    assert not tracked["encoder_offset.d_1"].enabled and tracked["encoder_offset.d_1"].start == 0.0
    mu = tracked["sheave_friction.mu"]  # off in the file: its default is the start; its wrap angle is a setting
    assert mu.start == 0.05 and not mu.enabled and mu.tolerance == pytest.approx(0.05 * 0.05)
    weight = tracked["rope_weight.w"]  # off: the default, plant-relative: 0.003 m g per metre of the plant's span
    assert weight.start == pytest.approx(0.003 * plant.weight / span(plant))
    assert weight.tolerance == pytest.approx(0.1 * weight.start)
    assert (plant.track.sigma, plant.track.rate, plant.track.drift) == (0.3, 2.0, 0.2)


ERRORS = {
    "not-a-list": ({"track": {"rope_elasticity": "EA"}}, "key 'plant.track' must be a list of parameter names"),
    "bad-name": ({"track": ["rope_elasticity.EA.x"]}, "key 'plant.track': 'rope_elasticity.EA.x' is not a name"),
    "twice": ({"track": ["rope_weight.w", "rope_weight.w"]}, "key 'plant.track': 'rope_weight.w' is listed twice"),
    "unknown-effect": ({"track": ["rope_elastic.EA"]}, "key 'plant.track': unknown effect 'rope_elastic'"),
    "unknown-parameter": ({"track": ["rope_elasticity.EB"]},
                          "key 'plant.track': effect 'rope_elasticity' has no parameter 'EB' (known: EA)"),
    "a-setting": ({"track": ["sheave_friction.wrap"]},
                  "key 'plant.track': 'sheave_friction.wrap' is a setting of the effect, not a parameter it fits"),
    "named-twice": ({"track": ["encoder_offset", "encoder_offset.d_2"]},
                    "key 'plant.track': 'encoder_offset.d_2' is named twice"),
    "tolerance-kind": ({"track": ["rope_weight.w"], "track_tolerance": {"rope_weight.w": {"percent": 5}}},
                       "key 'plant.track_tolerance.rope_weight.w' must be {relative: share} or {absolute: value}"),
    "tolerance-negative": ({"track": ["rope_weight.w"], "track_tolerance": {"rope_weight.w": {"absolute": -1}}},
                           "key 'plant.track_tolerance.rope_weight.w.absolute' must be a positive number, got -1"),
    "tolerance-untracked": ({"track": ["rope_weight.w"], "track_tolerance": {"encoder_offset.d_1": {"absolute": 0.01}}},
                            "key 'plant.track_tolerance.encoder_offset.d_1': not a tracked parameter"),
    "relative-to-zero": ({"track": ["encoder_offset.d_1"], "track_tolerance": {"encoder_offset.d_1": {"relative": 0.1}}},
                         "key 'plant.track_tolerance.encoder_offset.d_1': relative to a file value of 0"),
    "sigma-boolean": ({"track": ["rope_weight.w"], "track_sigma": True}, "key 'plant.track_sigma' must be a positive"),
    "rate-zero": ({"track": ["rope_weight.w"], "track_rate": 0}, "key 'plant.track_rate' must be a positive number"),
}


@pytest.mark.parametrize("name", ERRORS)
def test_a_wrong_key_is_one_line_naming_it(tmp_path, name):
    keys, words = ERRORS[name]
    path = plant_file(tmp_path, **keys)
    with pytest.raises(PlantConfigError) as error:
        PlantModel.from_plant(load_plant(path))
    message = str(error.value)
    assert words in message and "\n" not in message, message


@pytest.mark.parametrize("name", ["unknown-parameter", "relative-to-zero", "rate-zero"])
def test_replay_refuses_a_wrong_key_in_one_line_before_reading_the_bag(tmp_path, name):
    keys, words = ERRORS[name]
    path = plant_file(tmp_path, **keys)
    result = subprocess.run([sys.executable, "-m", "cable_winch_monitor.cli", "replay", str(ROOT / "bags" / "all_channels"),
                             "--out", str(tmp_path / "out"), "--config", str(path)], capture_output=True, text=True,
                            timeout=120)
    assert result.returncode == 2 and "Traceback" not in result.stdout + result.stderr
    assert result.stderr.count("\n") == 1 and words in result.stderr, result.stderr
    assert not (tmp_path / "out").exists()


def test_a_users_effect_is_tracked_by_its_name(tmp_path):
    """A user's effect (examples/rope_temperature.py, loaded by the plant file) is tracked as a built-in one:
    its fitted parameter alpha, not its setting T_ref."""
    path = plant_file(tmp_path, effect_modules=[str(ROOT / "examples" / "rope_temperature.py")],
                      track=["rope_temperature"], track_tolerance={"rope_temperature.alpha": {"absolute": 1e-6}})
    plant = load_plant(path)
    [alpha] = tracked_parameters(plant, PlantModel.from_plant(plant).registry)
    assert (alpha.key, alpha.start, alpha.tolerance, alpha.enabled) == ("rope_temperature.alpha", 0.0, 1e-6, False)
