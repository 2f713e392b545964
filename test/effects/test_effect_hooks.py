"""A user's effect whose hook raises, or gives a wrench or a prediction that is not finite: the sample is
refused with its reason (solve, replay: the first reason in the summary; compare: the rows not solved), or
the command stops with one line naming the effect and the hook; never a traceback. Where every sample is
refused, replay and compare fail with that reason in one line."""
from __future__ import annotations

import shutil
from pathlib import Path

import pytest
import yaml
from simbags import assert_clean, run_cli

from cable_winch_monitor.paths import default_plant_file, demo_bag

HOOKS = '''
import numpy as np
from cable_winch_monitor.effects import Effect, Parameter

K = (Parameter("k", "-", 0.0, (-1.0, 1.0), 0.1, "unused"),)


class RaisingLoad(Effect):
    name, acts, parameters = "raising_load", "load", K

    def load(self, wrench, plant, conditions):
        raise RuntimeError("the hook broke")


class NanLoad(Effect):
    name, acts, parameters = "nan_load", "load", K

    def load(self, wrench, plant, conditions):
        return wrench * np.nan


class RaisingLengths(Effect):
    name, acts, parameters = "raising_lengths", "geometry", K

    def lengths(self, lengths, conditions):
        raise KeyError("temperature")


class EarlyFailure(Effect):
    name, acts, parameters = "early_failure", "load", K

    def load(self, wrench, plant, conditions):
        if conditions.time < 10.0:
            raise ValueError("no reading yet")
        return wrench


class NanMeasure(Effect):
    name, acts, parameters = "nan_measure", "measurement", K

    def measure(self, channels, solution, plant, conditions):
        channels["tension_cable_1"] = float("nan")


class ShapelessMeasure(Effect):
    name, acts, parameters = "shapeless_measure", "measurement", K

    def measure_states(self, channels, states, plant, conditions):
        channels["tension_cable_2"] = channels["tension_cable_2"][:1]
'''
REASONS = {"raising_load": "effect 'raising_load': its load hook raised RuntimeError: the hook broke",
           "nan_load": "effect 'nan_load': its load hook gave a wrench that is not 6 finite numbers: [nan, nan",
           "raising_lengths": "effect 'raising_lengths': its lengths hook raised KeyError: 'temperature'"}
PREDICTION = {"nan_measure": "effect 'nan_measure': its measure hook gave tension_cable_1 = nan at a solved state",
              "shapeless_measure": "effect 'shapeless_measure': its measure hook gave other than one value per "
                                   "state"}


@pytest.fixture(scope="module")
def plants(tmp_path_factory) -> dict[str, Path]:
    """The bundled plant (its sensors fused) with one of the hooks' effects on, by effect name."""
    folder = tmp_path_factory.mktemp("hooks")
    (folder / "hooks.py").write_text(HOOKS)
    out = {}
    for name in [*REASONS, "early_failure", *PREDICTION]:
        config = yaml.safe_load(default_plant_file().read_text())
        config["plant"]["effect_modules"] = ["hooks.py"]
        config["plant"]["effects"] = {name: {"k": 0.1}}
        out[name] = folder / f"{name}.yaml"
        out[name].write_text(yaml.safe_dump(config))
    return out


@pytest.mark.parametrize("effect", REASONS)
def test_a_failing_hook_refuses_each_sample_with_its_reason(plants, tmp_path, effect):
    solved = run_cli("solve", "20.3", "20.1", "20.5", "20.2", "--config", plants[effect])
    assert_clean(solved, 1)
    assert "invalid input" in solved.stdout and REASONS[effect] in solved.stdout
    replayed = run_cli("replay", demo_bag(), "--out", tmp_path / "out", "--config", plants[effect], "--quiet")
    assert_clean(replayed, 2)  # the job could not be done: every sample refused
    assert "tension states: invalid input 2049" in replayed.stdout
    assert f"  invalid input: {REASONS[effect]}" in replayed.stdout and "(first of 2049 samples)" in replayed.stdout
    assert replayed.stderr.count("\n") == 1 and replayed.stderr.startswith(
        f"error: no sample of {demo_bag()} could be solved: all 2049 are invalid input: {REASONS[effect]}")
    compared = run_cli("compare", demo_bag(), "--config", plants[effect])
    assert_clean(compared, 2)
    assert "the model could not solve any row (2663 of 2663 rows: invalid input: " + REASONS[effect] in compared.stderr
    assert compared.stderr.count("\n") == 1 and "score" not in compared.stdout


def test_a_hook_failing_on_some_samples_costs_those_only(plants):
    compared = run_cli("compare", demo_bag(), "--config", plants["early_failure"])
    assert_clean(compared, 0)
    line = next(line for line in compared.stdout.splitlines() if line.startswith("not solved: "))
    rows = int(line.split()[2])
    assert 0 < rows < 2663 and "of 2663 rows: invalid input: effect 'early_failure': its load hook raised " \
        "ValueError: no reading yet" in line


@pytest.mark.parametrize("effect", PREDICTION)
def test_a_prediction_that_is_not_a_number_a_state_stops_the_command_with_one_line(plants, tmp_path, effect):
    for args in (("replay", demo_bag(), "--out", tmp_path / "out", "--quiet"), ("compare", demo_bag())):
        result = run_cli(*args, "--config", plants[effect])
        assert_clean(result, 2)
        assert result.stderr.count("\n") == 1 and PREDICTION[effect] in result.stderr, result.stderr
    assert not (tmp_path / "out").exists(), "a replay stopped by an error leaves no bag"


def test_a_fleet_replay_names_a_bag_whose_every_sample_is_refused(plants, tmp_path):
    bags = tmp_path / "bags"
    shutil.copytree(demo_bag(), bags / "shaft_a")
    result = run_cli("replay", bags, "--out", tmp_path / "out", "--config", plants["raising_load"])
    assert_clean(result, 1)
    assert f"  error shaft_a: no sample of {bags / 'shaft_a'} could be solved: all 2049 are invalid input: " \
        f"{REASONS['raising_load']}" in result.stdout
