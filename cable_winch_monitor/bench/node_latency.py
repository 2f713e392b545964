"""End-to-end latency of the winch_monitor node: winch sample published -> /platform/pose received.

Starts the node in its own process (DDS on loopback, a domain of its own), publishes a
platform being lowered at 50 Hz with small synchronisation errors between the winches,
each message with the load pins' readings (the equilibrium's tensions of the true lengths
plus 150 N of noise), so that a plant with `noise.length` fuses every sample, and prints
the latency percentiles and the node process's CPU share. Not a test: run

    .venv/bin/python -m cable_winch_monitor.bench.node_latency [--samples 2000] [--rate 50]
"""
from __future__ import annotations

import argparse
import fcntl
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

import numpy as np
import rclpy
from geometry_msgs.msg import PoseStamped
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState

from cable_winch_monitor_msgs.msg import TensionDistribution

from ..channels import TENSION_CHANNELS
from ..effects import PlantModel
from ..model.conditions import ConditionsTracker
from ..model.plant import CABLE_NAMES, load_plant

LOWERING_SPEED = 0.2        # [m/s] payout speed of all four winches
SYNC_AMPLITUDE = 2e-3       # [m] slow drift of each winch against the others
ENCODER_NOISE = 1e-3        # [m] 1-sigma jitter of each length reading (drum encoders at site)
PIN_NOISE = 150.0           # [N] 1-sigma noise of each load pin
START_LENGTH = 20.0         # [m]
CONNECT_TIMEOUT = 20.0      # [s]


def lowering(samples: int, rate: float, seed: int = 2, plant_file: Path | None = None,
             start: float = START_LENGTH) -> np.ndarray:
    """Winch readings (samples, 8): the lengths of a steady lowering from `start` [m] with per-winch
    drifts and encoder jitter, then the load pins of the lengths without the jitter as the plant's
    model reads them (its equilibrium and measurement effects: the rope's weight, sheave friction),
    with 150 N of noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(samples)[:, None] / rate
    drift = SYNC_AMPLITUDE * np.sin(2 * np.pi * t / 8.0 + rng.uniform(0, 2 * np.pi, 4))
    true = start + LOWERING_SPEED * t + drift
    model = PlantModel.from_plant(load_plant(plant_file) if plant_file else load_plant())
    tracker = ConditionsTracker()
    conditions = [tracker.update(float(at), row, np.full(4, np.nan)) for at, row in zip(t[:, 0], true)]
    predicted = model.predict_solutions(model.solve_batch(true, conditions), conditions)
    pins = np.column_stack([predicted[name] for name in TENSION_CHANNELS])
    return np.hstack([true + rng.normal(0.0, ENCODER_NOISE, (samples, 4)),
                      pins + rng.normal(0.0, PIN_NOISE, (samples, 4))])


@contextmanager
def leased_domain(pool: range = range(90, 100)) -> Iterator[int]:
    """A ROS_DOMAIN_ID from `pool` that no test run holds: the lock files of the tests' DDS harness."""
    for domain in pool:
        with open(Path(tempfile.gettempdir()) / f"cable_winch_monitor.domain_{domain}.lock", "w") as handle:
            try:
                fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                continue
            yield domain
            return
    raise SystemExit(f"node_latency: every ROS domain id in {pool.start}..{pool.stop - 1} is taken")


def cpu_seconds(pid: int) -> float:
    """utime + stime of a process from /proc/<pid>/stat."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def start_node(domain_id: int, solver: str, log: Path, plant_file: Path | None = None) -> subprocess.Popen:
    """`winch_monitor` in its own process (on `plant_file`, else the bundled plant), output to `log`."""
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain_id), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    command = [str(Path(sys.executable).parent / "winch_monitor"), "--ros-args", "-p", f"solver:={solver}"]
    if plant_file is not None:
        command += ["-p", f"plant_file:={plant_file}"]
    with log.open("w") as output:
        return subprocess.Popen(command, env=env, stdout=output, stderr=subprocess.STDOUT)


class Probe:
    """The benchmark's own node: publishes winch samples, time-stamps the poses and tension states."""

    def __init__(self, domain_id: int):
        self.context = Context()
        rclpy.init(context=self.context, domain_id=domain_id)
        self.node = rclpy.create_node("winch_monitor_latency_probe", context=self.context)
        qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
        self.publisher = self.node.create_publisher(JointState, "/winch/joint_states", qos)
        self.received: dict[tuple[int, int], int] = {}
        self.taut: dict[tuple[int, int], tuple[bool, ...]] = {}
        self.subscriptions = [
            self.node.create_subscription(PoseStamped, "/platform/pose", self._on_pose, qos),
            self.node.create_subscription(TensionDistribution, "/cables/tension", self._on_tension, qos)]
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.thread = threading.Thread(target=self.executor.spin, daemon=True)
        self.thread.start()

    def _on_pose(self, msg) -> None:
        self.received[(msg.header.stamp.sec, msg.header.stamp.nanosec)] = time.perf_counter_ns()

    def _on_tension(self, msg) -> None:
        self.taut[(msg.header.stamp.sec, msg.header.stamp.nanosec)] = tuple(c.taut for c in msg.cables)

    def connected(self) -> bool:
        return self.publisher.get_subscription_count() > 0 and all(
            s.get_publisher_count() > 0 for s in self.subscriptions)

    def publish(self, readings: np.ndarray) -> tuple[tuple[int, int], int]:
        """One sample (lengths, then load pins) stamped now; its stamp key and the send time [ns, perf_counter]."""
        msg = JointState(name=list(CABLE_NAMES), position=[float(v) for v in readings[:4]],
                         effort=[float(v) for v in readings[4:]])
        now = time.time_ns()
        msg.header.stamp.sec, msg.header.stamp.nanosec = now // 1_000_000_000, now % 1_000_000_000
        msg.header.frame_id = "shaft"
        sent = time.perf_counter_ns()
        self.publisher.publish(msg)
        return (msg.header.stamp.sec, msg.header.stamp.nanosec), sent

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


def warm_up(plant_file: Path | None = None, samples: int = 100, rate: float = 50.0) -> np.ndarray:
    """Readings of the lowering into the benchmark's start length: its load pins read as in the
    benchmark, so that the node's gates are open when the timing starts."""
    return lowering(samples, rate, 1, plant_file, START_LENGTH - LOWERING_SPEED * samples / rate)


def connect(probe: Probe, node: subprocess.Popen, warming: np.ndarray) -> None:
    """Wait for matching, then publish the `warming` readings (`warm_up`) at 50 Hz."""
    deadline = time.monotonic() + CONNECT_TIMEOUT
    while not probe.connected():
        if node.poll() is not None or time.monotonic() > deadline:
            raise SystemExit("node_latency: the winch_monitor node did not come up")
        time.sleep(0.05)
    for readings in warming:
        probe.publish(readings)
        time.sleep(0.02)
    time.sleep(0.2)
    if not probe.received:
        raise SystemExit("node_latency: no pose came back during the warm-up")


def publish_paced(probe: Probe, readings: np.ndarray, rate: float) -> dict[tuple[int, int], int]:
    """Publish one sample per 1/rate seconds from now; stamp key -> send time [ns, perf_counter]."""
    sent: dict[tuple[int, int], int] = {}
    start = time.monotonic()
    for k, sample in enumerate(readings):
        time.sleep(max(0.0, start + k / rate - time.monotonic()))
        key, at = probe.publish(sample)
        sent[key] = at
    return sent


def percentiles(values_ms: np.ndarray) -> str:
    if values_ms.size == 0:
        return "n/a"
    p50, p99 = np.percentile(values_ms, [50, 99])
    return f"p50 {p50:.2f} ms, p99 {p99:.2f} ms, max {values_ms.max():.2f} ms (n={values_ms.size})"


@dataclass
class Latency:
    """Publish-to-pose latencies [ms] of every sample, of those where the taut set held and where it
    changed, and the node's CPU [s] over the wall time [s] of the run."""

    all: np.ndarray
    steady: np.ndarray
    changed: np.ndarray
    cpu: float
    wall: float


def measure(samples: int, rate: float, domain_id: int, solver: str = "energy",
            plant_file: Path | None = None) -> Latency:
    """Start the node, publish a lowering at `rate`, and time each pose coming back."""
    readings, warming = lowering(samples, rate, plant_file=plant_file), warm_up(plant_file)
    with tempfile.TemporaryDirectory() as scratch:
        node = start_node(domain_id, solver, Path(scratch) / "node.log", plant_file)
        probe = Probe(domain_id)
        try:
            connect(probe, node, warming)
            probe.received.clear()
            cpu0, wall0 = cpu_seconds(node.pid), time.monotonic()
            sent = publish_paced(probe, readings, rate)
            time.sleep(0.5)
            cpu, wall = cpu_seconds(node.pid) - cpu0, time.monotonic() - wall0
        finally:
            probe.close()
            node.send_signal(signal.SIGINT)
            node.wait(timeout=10)
    latency = {key: (probe.received[key] - at) / 1e6 for key, at in sent.items() if key in probe.received}
    keys = list(sent)
    switched = {b for a, b in zip(keys, keys[1:]) if probe.taut.get(a, ()) != probe.taut.get(b, ())}
    return Latency(np.array(list(latency.values())), np.array([v for k, v in latency.items() if k not in switched]),
                   np.array([v for k, v in latency.items() if k in switched]), cpu, wall)


def run(samples: int, rate: float, domain_id: int, solver: str, plant_file: Path | None = None) -> int:
    result = measure(samples, rate, domain_id, solver, plant_file)
    print(f"winch_monitor end-to-end latency ({solver} solver, {plant_file or 'bundled plant'}), {samples} samples "
          f"at {rate:g} Hz, lowering {LOWERING_SPEED} m/s, sync drift {SYNC_AMPLITUDE * 1e3:g} mm, "
          f"jitter {ENCODER_NOISE * 1e3:g} mm, load pins {PIN_NOISE:g} N")
    print(f"  poses received      {result.all.size} of {samples}")
    print(f"  all samples         {percentiles(result.all)}")
    print(f"  taut set unchanged  {percentiles(result.steady)}")
    print(f"  taut set changed    {percentiles(result.changed)}")
    print(f"  node CPU share      {100.0 * result.cpu / result.wall:.1f} % of one core ({result.cpu:.2f} s CPU in "
          f"{result.wall:.2f} s)")
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=2000)
    parser.add_argument("--rate", type=float, default=50.0, help="samples per second")
    parser.add_argument("--domain-id", type=int, help="ROS domain (default: one no test run holds)")
    parser.add_argument("--solver", default="energy", choices=("energy", "traversal"))
    parser.add_argument("--plant-file", type=Path, help="plant YAML for the node (default: the bundled plant)")
    args = parser.parse_args(argv)
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    if args.domain_id is not None:
        return run(args.samples, args.rate, args.domain_id, args.solver, args.plant_file)
    with leased_domain() as domain:
        return run(args.samples, args.rate, domain, args.solver, args.plant_file)


if __name__ == "__main__":
    sys.exit(main())
