"""A topic the plant's effects read but the bag lacks: every command that reads a bag refuses it with one line
naming the topic, before any work (replay went through every sample as "invalid input" and exited 0)."""
from __future__ import annotations

import shutil
from pathlib import Path

import pytest
import yaml
from simbags import assert_clean, run_cli

from cable_winch_monitor.messages.topics import listed_topics
from cable_winch_monitor.paths import default_plant_file, demo_bag

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
WORDS = "the plant's effects read /shaft/temperature.temperature (sensor_msgs/msg/Temperature), which the bag does " \
        "not have"


@pytest.fixture(scope="module")
def temperature_plant(tmp_path_factory) -> Path:
    """The bundled plant with the README's rope_temperature effect on (it reads /shaft/temperature)."""
    config = yaml.safe_load(default_plant_file().read_text())
    config["plant"]["effect_modules"] = [str(EXAMPLES / "rope_temperature.py")]
    config["plant"]["effects"] = {"rope_temperature": {"alpha": 1e-5}}
    path = tmp_path_factory.mktemp("plant") / "plant.yaml"
    path.write_text(yaml.safe_dump(config))
    return path


@pytest.fixture(scope="module")
def fleet(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("fleet")
    shutil.copytree(demo_bag(), folder / "all_channels")
    return folder


@pytest.mark.parametrize("command", [("replay", "--out", "{out}", "--quiet"), ("compare",), ("diagnose",),
                                     ("fit", "--effects", "rope_weight")])
def test_each_command_refuses_the_bag_before_the_work(temperature_plant, tmp_path, command):
    args = [str(tmp_path / "out") if a == "{out}" else a for a in command[1:]]
    result = run_cli(command[0], demo_bag(), "--config", temperature_plant, *args)
    assert_clean(result, 2)
    assert result.stderr.count("\n") == 1 and WORDS in result.stderr, result.stderr
    assert "samples" not in result.stdout and not (tmp_path / "out").exists()


@pytest.mark.parametrize("command", ["replay", "diagnose"])
def test_a_fleet_names_the_topic_for_each_bag(temperature_plant, fleet, tmp_path, command):
    result = run_cli(command, fleet, "--config", temperature_plant, "--out", tmp_path / "out")
    assert_clean(result, 1)
    assert f"error all_channels: {fleet / 'all_channels'}: {WORDS}" in result.stdout
    assert not (tmp_path / "out" / "all_channels").exists()


def test_a_bag_cut_short_lists_no_topics_and_is_refused_once_read(temperature_plant, tmp_path):
    """Without a summary the topics are known only by reading: compare reads, then refuses it the same way."""
    cut = tmp_path / "cut.mcap"
    data = (demo_bag() / "all_channels.mcap").read_bytes()
    cut.write_bytes(data[:len(data) * 3 // 4])
    assert listed_topics(cut) is None
    assert listed_topics(demo_bag())["/winch_1/joint_states"] == 513
    result = run_cli("compare", cut, "--config", temperature_plant)
    assert_clean(result, 2)
    assert WORDS in result.stderr
