"""Malformed plant files give one line naming the key or limit, in the CLI and the node; never a traceback."""
from __future__ import annotations

import copy
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

from cable_winch_monitor.model.plantfile.plant import PlantConfigError, load_plant
from cable_winch_monitor.paths import default_plant_file
from cable_winch_monitor.safe_yaml import MAX_DEPTH, YamlLimitError, parse_yaml

BASE = yaml.safe_load(default_plant_file().read_text())
RECTANGLE = [[2.0, 2.5, 0.0], [-2.0, 2.5, 0.0], [-2.0, -2.5, 0.0], [2.0, -2.5, 0.0]]
BOMB = ('a: &a ["x","x","x","x","x","x","x","x","x"]\n'
        + "".join(f"{chr(98 + i)}: &{chr(98 + i)} [" + ",".join([f"*{chr(97 + i)}"] * 9) + "]\n" for i in range(8))
        + "plant: *i\n")


def edited(**geometry_or_sections) -> str:
    config = copy.deepcopy(BASE)
    for key, value in geometry_or_sections.items():
        section, _, name = key.partition("__")
        (config["plant"][section] if name else config["plant"]).update({name or section: value})
    return yaml.safe_dump(config)


def points(anchors=RECTANGLE, attachments=RECTANGLE) -> str:
    config = copy.deepcopy(BASE)
    config["plant"]["geometry"] = {"anchors": anchors, "attachments": attachments, "centre_of_gravity": [0, 0, -10]}
    return yaml.safe_dump(config)


CASES = {
    "alias-bomb": (BOMB, "more than 1,000,000 values once its aliases are expanded"),
    "deep-nesting": ("plant: " + "[" * 20000 + "]" * 20000, f"nested deeper than {MAX_DEPTH} levels"),
    "binary": (bytes(range(256)) * 8, "not a text file"),
    "too-large": ("# padding\n" * 200_000, "more than the 1,048,576 a YAML file may have"),
    "decks-a-number": (edited(outline__decks=5), "'outline.decks' must be a list"),
    "deck-count-words": (edited(outline__decks=[{"z": 0.0, "radius": 3.6, "count": "many"}]),
                         "'outline.decks[0].count' must be a whole number"),
    "limits-words": (edited(limits={"max_payout": "far"}), "'plant.limits.max_payout' must be a number"),
    "noise-a-string": (edited(noise="loud"), "'plant.noise' must be a mapping"),
    "noise-a-list": (edited(noise=[1, 2]), "'plant.noise' must be a mapping"),
    "noise-zero": (edited(noise={"length": 0.0}), "'plant.noise.length' must be a 1-sigma noise in [1e-09, 1e+09]"),
    "noise-negative": (edited(noise={"tension": -150.0}), "'plant.noise.tension' must be a 1-sigma noise"),
    "noise-underflowing": (edited(noise={"length": 1e-300}), "'plant.noise.length' must be a 1-sigma noise"),
    "noise-nan": (edited(noise={"roll": float("nan")}), "'plant.noise.roll' must be a finite number"),
    "noise-a-boolean": (edited(noise={"depth": True}), "'plant.noise.depth' must be a number, got True"),
    "mass-a-boolean": (edited(mass=True), "'plant.mass' must be a number, got True"),
    "weight-not-finite": (edited(mass=1e308), "'plant.mass' = 1e+308 kg: its weight m g = inf N must be finite"),
    "bounds-a-boolean": (edited(effect_bounds={"rope_weight": {"w": [True, 5.0]}}),
                         "'plant.effect_bounds.rope_weight.w' must be [low, high]"),
    "anchors-booleans": (points(anchors=[[True, 2.5, 0.0]] + RECTANGLE[1:]),
                         "'plant.geometry.anchors' must be a list of [x, y, z] points"),
    "effect-spec-a-list": (edited(effects={"rope_weight": [1, 2]}), "'plant.effects.rope_weight' must be a mapping"),
    "identical-anchors": (points(anchors=[[1.0, 1.0, 0.0]] * 4), "'plant.geometry.anchors': points 1 and 2 are identical"),
    "collinear-anchors": (points(anchors=[[k, 0.0, 0.0] for k in range(4)]),
                          "'plant.geometry.anchors': all points lie on one line"),
    "identical-attachments": (points(attachments=[RECTANGLE[0]] * 2 + RECTANGLE[2:]),
                              "'plant.geometry.attachments': points 1 and 2 are identical"),
}


def write(tmp_path: Path, content: str | bytes) -> Path:
    path = tmp_path / "plant.yaml"
    path.write_bytes(content if isinstance(content, bytes) else content.encode())
    return path


@pytest.mark.parametrize("name", CASES)
def test_load_plant_refuses_with_the_key_and_quickly(tmp_path, name):
    content, words = CASES[name]
    path = write(tmp_path, content)
    started = time.perf_counter()
    with pytest.raises(PlantConfigError) as error:
        load_plant(path)
    assert time.perf_counter() - started < 5.0  # the alias bomb took 40-70 s and ended in MemoryError
    message = str(error.value)
    assert words in message and str(path) in message and "\n" not in message, message


@pytest.mark.parametrize("name", ["alias-bomb", "binary", "collinear-anchors", "deck-count-words"])
def test_the_cli_prints_one_line_and_exits_2(tmp_path, name):
    content, words = CASES[name]
    path = write(tmp_path, content)
    result = subprocess.run([sys.executable, "-m", "cable_winch_monitor.cli", "solve", "20.3", "20.1", "20.5", "20.2",
                             "--config", str(path)], capture_output=True, text=True, timeout=60)
    assert result.returncode == 2
    assert result.stderr.count("\n") == 1 and words in result.stderr, result.stderr
    assert "Traceback" not in result.stdout + result.stderr


@pytest.mark.parametrize("name", ["alias-bomb", "binary", "identical-anchors"])
def test_the_node_stops_with_one_line_naming_the_problem(tmp_path, name):
    from ros_harness import DomainLease, run_node_to_exit

    content, words = CASES[name]
    path = write(tmp_path, content)
    lease = DomainLease()
    try:
        result = run_node_to_exit(lease.domain_id, {"plant_file": path})
    finally:
        lease.release()
    assert result.returncode == 2
    assert words in result.stderr and "Traceback" not in result.stderr + result.stdout, result.stderr


@pytest.mark.parametrize("sections, words", [
    ({"noise": {**BASE["plant"]["noise"], "tensoin": 150.0}},
     "unknown key 'plant.noise.tensoin' (known: length, tension, roll, pitch, x, y, depth"),
    ({"effects": {"rope_weight": {"w": True}}}, "parameter 'w' must be a number, got True"),
])
def test_what_only_the_effect_layer_can_check_is_refused_before_any_solve(tmp_path, sections, words):
    """A noise key no declared channel has (a user's channel may be declared by a module the plant file
    loads), an effect parameter given as a boolean (`true` was taken as 1 N/m)."""
    path = write(tmp_path, edited(**sections))
    result = subprocess.run([sys.executable, "-m", "cable_winch_monitor.cli", "solve", "20.3", "20.1", "20.5", "20.2",
                             "--config", str(path)], capture_output=True, text=True, timeout=60)
    assert result.returncode == 2 and "Traceback" not in result.stdout + result.stderr
    assert result.stderr.count("\n") == 1 and words in result.stderr, result.stderr


CAGE = """
from cable_winch_monitor.channels import Channel, declare
from cable_winch_monitor.effects import Effect, Parameter

declare(Channel("cage_load", "N", "cage_load", ("/cage/load",), "std_msgs/msg/Float64", "data",
                predict=lambda solution, plant, conditions: float(solution.tensions.sum())))


class CageGain(Effect):
    name = "cage_gain"
    parameters = (Parameter("k", "-", 0.0, (-1.0, 1.0), 0.01, "gain error of the cage's load cell"),)
"""


def test_a_relative_effect_module_is_found_beside_the_plant_file_and_declares_its_noise_key(tmp_path, monkeypatch):
    (tmp_path / "plants" / "modules").mkdir(parents=True)
    (tmp_path / "plants" / "modules" / "cage.py").write_text(CAGE)
    plant_path = tmp_path / "plants" / "plant.yaml"
    plant_path.write_text(edited(effect_modules=["modules/cage.py"],
                                 noise={**BASE["plant"]["noise"], "cage_load": 200.0}))
    monkeypatch.chdir(tmp_path)  # not the plant file's folder
    plant = load_plant(Path("plants") / "plant.yaml")
    assert plant.effect_modules == (str(Path("plants") / "modules" / "cage.py"),)
    result = subprocess.run([sys.executable, "-m", "cable_winch_monitor.cli", "solve", "20.3", "20.1", "20.5", "20.2",
                             "--config", "plants/plant.yaml"], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    assert "taut {1,2,4}" in result.stdout


def test_yaml_within_the_limits_reads_as_safe_load_does():
    text = "a: &x [1, 2, {b: c}]\nd: *x\ne: " + "[" * (MAX_DEPTH - 2) + "1" + "]" * (MAX_DEPTH - 2) + "\n"
    assert parse_yaml(text) == yaml.safe_load(text)
    with pytest.raises(YamlLimitError, match="not valid YAML"):
        parse_yaml("plant: [a, b\n  mass: {\n")
    with pytest.raises(YamlLimitError, match="not valid YAML"):
        parse_yaml("!!python/object:os.system x")
