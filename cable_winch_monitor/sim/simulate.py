"""Run a scenario: the true plant at every sensor sample, the noisy readings into a rosbag2 bag.

At each sample time (all streams merged in time order) the commanded payout plus the
synchronisation errors give the lengths the winches report, the truth (`sim.truth`, the
simulator's own equilibrium and effect physics, independent of the package's model)
gives the true equilibrium and the noise-free readings, and the sensor of that stream
reports them with noise. Messages are written
in receive order (log time = header stamp + a random latency), as a recorder would.
Beside the bag: ground_truth.csv (one row per sample) and scenario.yaml (as resolved).
"""
from __future__ import annotations

import csv
import heapq
import time
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from ..bagio.writer import BagWriter
from ..messages.fields import Stamp, stamp_ns
from ..messages.records import build
from ..model.plantfile.plant import load_plant
from ..model.statics.geometry import roll_pitch_yaw
from ..model.statics.result import Solution
from ..monitor.clearance import solution_clearance
from .profile import Profile, air_temperature
from .sensors import Sensors, Stream, sensor_streams
from .sync import SyncErrors
from .truth import Sample, TruthModel

TRUTH_FILE = "ground_truth.csv"
SCENARIO_FILE = "scenario.yaml"
TAIL = 5.0  # [s] simulated after the profile ends when the scenario gives no duration
TRUTH_COLUMNS = (["time", "stream"] + [f"length_{i}" for i in range(1, 5)] + ["status", "taut", "x", "y", "z", "roll",
                 "pitch", "yaw"] + [f"tension_{i}" for i in range(1, 5)] + ["clearance"])


@dataclass
class SimResult:
    out: Path
    duration: float
    messages: Counter[str] = field(default_factory=Counter)
    states: Counter[str] = field(default_factory=Counter)
    wall: float = 0.0

    def format(self) -> str:
        lines = [f"simulated {self.duration:.1f} s into {self.out} in {self.wall:.1f} s",
                 "messages: " + ", ".join(f"{topic} {n}" for topic, n in sorted(self.messages.items())),
                 "true tension states: " + ", ".join(f"{s} {n}" for s, n in self.states.most_common()),
                 f"ground truth: {self.out / TRUTH_FILE}"]
        return "\n".join(lines)


def _stamp(seconds: float) -> Stamp:
    sec, nanosec = divmod(int(round(seconds * 1e9)), 1_000_000_000)
    return sec, nanosec


def _events(streams: list[Stream]) -> Iterator[tuple[float, Stream]]:
    """(time, stream) of every sample of every stream, in time order."""
    merged = heapq.merge(*[zip(s.times.tolist(), [k] * len(s.times)) for k, s in enumerate(streams)])
    for t, k in merged:
        yield t, streams[k]


def _truth_row(t: float, stream: str, lengths: np.ndarray, truth: Solution, clearance: float) -> list[Any]:
    pose: list[Any] = [np.nan] * 6
    tensions: list[Any] = [np.nan] * 4
    if truth.ok:
        assert truth.position is not None and truth.rotation is not None and truth.tensions is not None  # a pose
        pose = [*truth.position, *roll_pitch_yaw(truth.rotation)]
        tensions = list(truth.tensions)
    taut = " ".join(str(i) for i in truth.taut_set)
    number = "{:.9g}".format
    return [f"{t:.9f}", stream, *map(number, lengths), truth.status.value, taut,
            *map(number, [*pose, *tensions, clearance])]


def simulate(config: dict[str, Any], out: str | Path) -> SimResult:
    """Simulate a checked scenario (sim.scenario.load_scenario) into a new bag directory `out`."""
    started = time.perf_counter()
    plant = load_plant(config["plant"])
    sync_rng, timing_rng, noise_rng, latency_rng = (np.random.default_rng(s) for s in
                                                    np.random.SeedSequence(config["seed"]).spawn(4))
    profile = Profile(config["profile"]["start_length"], config["profile"]["segments"])
    duration = config["duration"] if config["duration"] is not None else profile.end + TAIL
    sync = SyncErrors(config["sync"]["sigma"], config["sync"]["tau"], config["sync"]["events"], sync_rng)
    truth = TruthModel(plant, config)
    sensors = Sensors(config["sensors"], noise_rng, config["start_time"])
    streams = sensor_streams(config["sensors"], duration, timing_rng)
    latency = config["sensors"]["latency"]
    result = SimResult(Path(out), duration)
    pending: list[tuple[int, int, str, str, Any]] = []  # log time, order, topic, type, message: flushed in log order
    with BagWriter(out) as writer, (Path(out) / TRUTH_FILE).open("w", newline="") as truth_file:
        resolved = {key: value for key, value in config.items() if key != "name"}  # loads again as a scenario
        (Path(out) / SCENARIO_FILE).write_text(yaml.safe_dump(resolved, sort_keys=False))
        table = csv.writer(truth_file)
        table.writerow(TRUTH_COLUMNS)
        for order, (t, stream) in enumerate(_events(streams)):
            commanded, speed, acceleration = profile(t)
            errors, rates = sync(t)
            lengths, air = commanded + errors, air_temperature(config["shaft_air"], t)
            sample = Sample(t, speed + rates, acceleration, air)
            if config["sync"]["drives"] == "ropes":  # the ropes are paid out so; the encoders report them
                state, channels = truth.paid_out(lengths, sample)
                lengths = truth.reported(lengths, air)
            else:
                state, channels = truth(lengths, sample)
            clearance = solution_clearance(plant, state)
            table.writerow(_truth_row(config["start_time"] + t, stream.name, lengths, state,
                                      clearance.value if clearance is not None else np.nan))
            result.states[state.tension_state] += 1
            stamp = _stamp(config["start_time"] + t)
            while pending and pending[0][0] <= stamp_ns(stamp):
                _flush(writer, pending)
            values = sensors.reading(stamp, stream, lengths, speed + rates, channels, air)
            if values is not None:
                log_time = stamp_ns(stamp) + int(latency * latency_rng.uniform(0.5, 1.5) * 1e9)
                heapq.heappush(pending, (log_time, order, stream.topic, stream.msgtype, build(stream.msgtype, values)))
        while pending:
            _flush(writer, pending)
        result.messages = writer.counts
    result.wall = time.perf_counter() - started
    return result


def _flush(writer: BagWriter, pending: list[tuple[int, int, str, str, Any]]) -> None:
    log_time, _, topic, msgtype, message = heapq.heappop(pending)
    writer.write(topic, msgtype, log_time, message)
