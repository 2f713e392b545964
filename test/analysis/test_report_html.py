"""The compare report: failure regions described by the motion they really span, and the HTML report rendered
offline in headless Chromium (plotly inline, no console errors), with a screenshot."""
from __future__ import annotations

import csv
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from effectbags import SEED002, plant_file, simulate_bag

from cable_winch_monitor.analysis.compare import compare
from cable_winch_monitor.analysis.data import read_bag
from cable_winch_monitor.analysis.html import write_report
from cable_winch_monitor.effects import PlantModel
from cable_winch_monitor.model.plantfile.plant import load_plant
from cable_winch_monitor.sim.profile import Profile
from cable_winch_monitor.sim.simulate import TRUTH_FILE

ROOT = Path(__file__).resolve().parents[2]
SCREENSHOT = ROOT / "build" / "report" / "report.png"  # docs/report.png is a copy
MOVES = 27
# 27 moves: down 1 m and up 0.5 m in turn, a second's stop between; the ropes weigh 60 N/m, which the plant
# file does not know, so the load pins read more than the model all along: one region spanning every move.
PROFILE = {"start_length": 40.0, "segments": [
    segment for k in range(MOVES) for segment in (
        [{"move": 1.0 if k % 2 == 0 else -0.5, "speed": 0.5, "accel": 0.5}]
        + ([{"stop": 1.0}] if k < MOVES - 1 else []))]}


@pytest.fixture(scope="module")
def moves(tmp_path_factory):
    directory = tmp_path_factory.mktemp("moves")
    plant = plant_file(directory, "rigid", SEED002, {})
    bag = simulate_bag(directory, "moves", plant, {"rope_weight": {"w": 60.0}}, profile=PROFILE, duration=100.0)
    return bag, compare(PlantModel.from_plant(load_plant(plant)), read_bag(bag))


def truth_shares(bag: Path, start: float, end: float) -> dict[str, float]:
    """Lowering / hoisting / shifting / standing shares in [start, end] of the winch samples, by the payout
    speed each winch was commanded (the simulator's profile; no winch here lags by script)."""
    with (bag / TRUTH_FILE).open() as file:
        times = np.array([float(r["time"]) for r in csv.DictReader(file) if r["stream"] not in ("imu", "position")])
    profile = Profile(PROFILE["start_length"], PROFILE["segments"])
    speed = np.array([profile(t)[1] for t in times[(times >= start) & (times <= end)]])
    out, in_ = speed > 0.02, speed < -0.02
    return {"lowering": np.mean(out), "hoisting": np.mean(in_), "shifting": 0.0, "standing": np.mean(~out & ~in_)}


def test_a_region_over_27_moves_is_described_by_the_motions_it_spans(moves):
    bag, result = moves
    region = max(result.regions, key=lambda r: r["end"] - r["start"])
    span = result.data.times[-1] - result.data.times[0]
    assert region["end"] - region["start"] > 0.9 * span, "one region over all the moves"
    start = result.data.times[0]  # regions are timed from the start of the recording
    truth = truth_shares(bag, start + region["start"], start + region["end"])
    for motion, share in truth.items():
        assert region["motion"][motion] == pytest.approx(share, abs=0.06), (motion, region["motion"])
        assert share > 0.1 or motion == "shifting", (motion, share)
    for motion in ("lowering", "hoisting", "standing"):
        assert f"{motion} {100 * region['motion'][motion]:.0f} %" in region["description"]
    assert abs(sum(region["motion"].values()) - 1.0) < 1e-9


def chromium(*args: str, profile: Path) -> subprocess.CompletedProcess:
    """Headless Chromium with every host name unresolvable: anything the page tried to fetch would fail aloud."""
    binary = shutil.which("chromium") or shutil.which("chromium-browser")
    assert binary, "chromium is needed for this test: make setup-test installs it (as root with apt-get)"
    return subprocess.run([binary, "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                           "--disable-component-update", "--disable-sync", "--no-first-run",
                           f"--user-data-dir={profile}", "--host-resolver-rules=MAP * ~NOTFOUND",
                           "--enable-logging=stderr", "--v=0", *args],
                          check=False, capture_output=True, text=True, timeout=180)


def console_errors(result: subprocess.CompletedProcess) -> list[str]:
    return [line for line in result.stderr.splitlines()
            if "CONSOLE" in line or "Uncaught" in line or "ERR_NAME_NOT_RESOLVED" in line or "Failed to load" in line]


def test_html_report_renders_offline_in_chromium(moves, tmp_path):
    _, result = moves
    report = tmp_path / "report.html"
    write_report(result, report)
    html = report.read_text()
    assert "<script src" not in html and "<link" not in html and "<img" not in html, "one file, nothing to fetch"
    dom = chromium("--dump-dom", report.as_uri(), profile=tmp_path / "profile")
    assert dom.returncode == 0, dom.stderr[-2000:]
    assert not console_errors(dom), console_errors(dom)
    plots = len(re.findall(r'<div[^>]*class="[^"]*js-plotly-plot', dom.stdout))  # divs plotly has drawn into
    assert plots == 1 + len(result.channels), "an overview and one figure per channel, drawn by plotly"
    for text in ("time from the start of the recording", "lowering", "hoisting", "standing", ">R1<"):
        assert text in dom.stdout, text
    SCREENSHOT.parent.mkdir(parents=True, exist_ok=True)
    shot = chromium("--virtual-time-budget=10000", "--window-size=1300,1500", f"--screenshot={SCREENSHOT}",
                    report.as_uri(), profile=tmp_path / "profile")
    assert shot.returncode == 0 and not console_errors(shot), shot.stderr[-2000:]
    assert SCREENSHOT.stat().st_size > 50_000
