"""Every user error of the command line is one line and a non-zero exit, found before the work starts."""
from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import time
from pathlib import Path

import pytest
from simbags import CLI, assert_clean, run_cli, simulated

from cable_winch_monitor.bagio.writer import BagWriter
from cable_winch_monitor.messages import records
from cable_winch_monitor.paths import demo_bag

MISSING_FOLDER = Path("/nonexistent-folder/out")


def one_error_line(result) -> str:
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), result.stderr
    return lines[0]


@pytest.fixture(scope="module")
def lengths_only_bag(tmp_path_factory) -> Path:
    """Ten seconds of the four winches with no load pins, inclinometer or depth gauge: nothing to compare."""
    path = tmp_path_factory.mktemp("bags") / "lengths_only"
    with BagWriter(path) as writer:
        for k in range(100):
            ns = 1_700_000_000 * 10 ** 9 + k * 100_000_000
            header = {"stamp": {"sec": ns // 10 ** 9, "nanosec": ns % 10 ** 9}, "frame_id": ""}
            message = records.build("sensor_msgs/msg/JointState", {
                "header": header, "name": ["cable_1", "cable_2", "cable_3", "cable_4"],
                "position": [20.3 + 0.05 * k] * 4, "velocity": [0.5] * 4, "effort": []})
            writer.write("/winch/joint_states", "sensor_msgs/msg/JointState", ns, message)
    return path


@pytest.mark.parametrize("args, words", [
    (("diagnose", "{bag}", "--candidates", "rope_weight,no_such_effect"), "unknown effect 'no_such_effect'"),
    (("fit", "{bag}", "--effects", "no_such_effect"), "unknown effect 'no_such_effect'"),
    (("limits", "--length", "nan"), "--length nan: the payout must lie in"),
    (("limits", "--length", "1e300"), "the payout must lie in (0, 3000] m"),
])
def test_unknown_names_and_absurd_numbers(args, words):
    result = run_cli(*(str(demo_bag()) if a == "{bag}" else a for a in args))
    assert_clean(result, 2)
    assert words in one_error_line(result)


@pytest.mark.parametrize("args, option", [
    (("compare", "--json", MISSING_FOLDER / "x.json"), "--json"),
    (("compare", "--html", MISSING_FOLDER / "x.html"), "--html"),
    (("diagnose", "--json", MISSING_FOLDER / "x.json"), "--json"),
    (("fit", "--effects", "rope_weight", "--write-config", MISSING_FOLDER / "x.yaml"), "--write-config"),
    (("compare", "--html", "/tmp"), "--html"),
])
def test_unwritable_outputs_are_refused_before_the_bag_is_read(args, option):
    """The bag does not exist either: the output path is checked first, so the error names the option."""
    command, *rest = args
    result = run_cli(command, "/nonexistent-bag", *rest)
    assert_clean(result, 2)
    line = one_error_line(result)
    assert line.startswith(f"error: {option} ") and ("does not exist" in line or "is a directory" in line), line


@pytest.mark.parametrize("command", [("compare",), ("diagnose",), ("fit", "--effects", "rope_weight")])
def test_a_bag_without_measurements_says_so_and_exits_non_zero(lengths_only_bag, command):
    result = run_cli(command[0], lengths_only_bag, *command[1:])
    assert_clean(result, 2)
    assert "no measurements to compare the model with" in one_error_line(result)
    assert "score" not in result.stdout


def test_a_binary_metadata_file_is_noted_and_the_mcap_read(tmp_path):
    bag = tmp_path / "bag"
    shutil.copytree(demo_bag(), bag)
    (bag / "metadata.yaml").write_bytes(bytes(range(256)) * 16)
    result = run_cli("replay", bag, "--out", tmp_path / "out", "--quiet")
    assert_clean(result, 0)
    assert "metadata.yaml is unreadable" in result.stdout and "not a text file" in result.stdout
    assert "samples: 2049 (solved 2049" in result.stdout


@pytest.mark.parametrize("budget", ["-1", "nan", "inf", "soon"])
def test_a_budget_that_is_no_number_of_seconds_is_a_usage_error(budget):
    """-1 and nan meant "no limit" (0 says that); the bag is not read."""
    result = run_cli("diagnose", "/nonexistent-bag", f"--budget={budget}")
    assert_clean(result, 2)
    assert f"argument --budget: must be a number of seconds >= 0 (0: no limit), got '{budget}'" in result.stderr


def test_fleet_diagnose_keeps_to_its_budget_per_bag(tmp_path):
    """Each bag of a fleet within --budget (it was ignored: "budget": null); the table's JSON says it too."""
    fleet = tmp_path / "fleet"
    fleet.mkdir()
    shutil.copytree(demo_bag().parent / "lag_slack", fleet / "lag_slack")
    result = run_cli("diagnose", fleet, "--budget", "0.001", "--candidates", "rope_weight", "--out", tmp_path / "out",
                     "--json", tmp_path / "table.json")
    assert_clean(result, 0)
    report = json.loads((tmp_path / "out" / "lag_slack.json").read_text())
    assert report["budget"] is not None and report["budget"] <= 0.001
    assert any(item.startswith("candidate rope_weight") for item in report["unfinished"])
    assert json.loads((tmp_path / "table.json").read_text())["budget"] == 0.001


@pytest.mark.parametrize("command", [("diagnose", "--budget", "30"), ("fit", "--effects", "rope_weight")])
def test_a_bag_too_short_to_hold_data_out_is_refused(tmp_path, command):
    """15 s of every sensor: diagnose ended in "need at least one array to concatenate", fit printed a held-out
    score of nan."""
    bag = simulated(tmp_path, "all_channels", "duration=15")
    result = run_cli(command[0], bag, *command[1:])
    assert_clean(result, 2)
    assert "its measurements span 14.9 s, too short to hold data out" in one_error_line(result)
    assert "nan" not in result.stdout


def _as_at_a_terminal() -> None:
    """Ctrl-C's default disposition in the child: a suite started in the background (nohup, `&`) passes SIGINT on
    ignored, and Python then installs no KeyboardInterrupt."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def test_ctrl_c_ends_a_command_with_one_line(tmp_path):
    """Ctrl-C in a command other than replay (simulating a 20-minute run takes half a minute): "interrupted" and
    exit 130, no traceback (replay finishes its output bag and summary itself: test_replay_signals.py)."""
    process = subprocess.Popen([*CLI, "simulate", "sinking_run", "--out", str(tmp_path / "bag")],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               text=True, env=dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST"),
                               preexec_fn=_as_at_a_terminal)
    time.sleep(4.0)  # past the imports, into the work
    assert process.poll() is None, "finished before it could be interrupted"
    process.send_signal(signal.SIGINT)
    out, err = process.communicate(timeout=60)
    assert_clean(subprocess.CompletedProcess(process.args, process.returncode, out, err), 130)
    assert err.strip().endswith("interrupted")
