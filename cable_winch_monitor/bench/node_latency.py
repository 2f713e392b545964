"""End-to-end latency of the winch_monitor node: winch sample published -> /platform/pose received.

Starts the node in its own process (DDS on loopback, a domain of its own), publishes a
platform being lowered at 50 Hz with small synchronisation errors between the winches,
each message with the load pins' readings (the equilibrium's tensions of the true lengths
plus 150 N of noise), so that a plant with `noise.length` fuses every sample, and prints
the latency percentiles and the node process's CPU share. With `--recording BAG` it plays a
recording instead (`measure_recording`: every input topic at its log time, /clock beside, the
node on `use_sim_time`), as a site's node receives its winches, inclinometer and depth gauge.
Not a test: run

    .venv/bin/python -m cable_winch_monitor.bench.node_latency [--samples 2000] [--rate 50]
    .venv/bin/python -m cable_winch_monitor.bench.node_latency --recording BAG --plant-file FILE
"""
from __future__ import annotations

import argparse
import fcntl
import math
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import rclpy
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState

from cable_winch_monitor_msgs.msg import TensionDistribution

from ..bagio.reader import BagReader
from ..channels import TENSION_CHANNELS
from ..effects import PlantModel
from ..live.scheduler import PROCESSED, QUEUED
from ..messages.fields import JOINT_STATE, input_topics
from ..model.conditions import ConditionsTracker
from ..model.plantfile.plant import CABLE_NAMES, load_plant
from ..nodes.conversions import message_class

LOWERING_SPEED = 0.2        # [m/s] payout speed of all four winches
SYNC_AMPLITUDE = 2e-3       # [m] slow drift of each winch against the others
ENCODER_NOISE = 1e-3        # [m] 1-sigma jitter of each length reading (drum encoders at site)
PIN_NOISE = 150.0           # [N] 1-sigma noise of each load pin
START_LENGTH = 20.0         # [m]
CONNECT_TIMEOUT = 20.0      # [s]
SETTLE = 2.0                # [s] of a recording played before the latencies count (the node's first samples)
SOLVER_STATUS = "winch_monitor: solver"
NODE_TIMES = (QUEUED, PROCESSED)  # the node's own latency in its solver diagnostics


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
    conditions = ConditionsTracker().update(t[:, 0], true, np.full_like(true, np.nan))
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


def start_node(domain_id: int, solver: str, log: Path, plant_file: Path | None = None,
               sim_time: bool = False) -> subprocess.Popen:
    """`winch_monitor` in its own process (on `plant_file`, else the bundled plant; on /clock where
    `sim_time`), output to `log`."""
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain_id), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    command = [str(Path(sys.executable).parent / "winch_monitor"), "--ros-args", "-p", f"solver:={solver}"]
    if plant_file is not None:
        command += ["-p", f"plant_file:={plant_file}"]
    if sim_time:
        command += ["-p", "use_sim_time:=true"]
    with log.open("w") as output:
        return subprocess.Popen(command, env=env, stdout=output, stderr=subprocess.STDOUT)


class Probe:
    """The benchmark's own node: publishes winch samples, time-stamps the poses and tension states, keeps the
    node's latest solver diagnostics."""

    def __init__(self, domain_id: int):
        self.context = Context()
        rclpy.init(context=self.context, domain_id=domain_id)
        self.node = rclpy.create_node("winch_monitor_latency_probe", context=self.context)
        qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
        self.publisher = self.node.create_publisher(JointState, "/winch/joint_states", qos)
        self.clock = self.node.create_publisher(Clock, "/clock", qos)
        self.raw: dict[str, Any] = {"/winch/joint_states": self.publisher}
        self.received: dict[tuple[int, int], int] = {}
        self.taut: dict[tuple[int, int], tuple[bool, ...]] = {}
        self.solver: dict[str, str] = {}
        self.subscriptions = [
            self.node.create_subscription(PoseStamped, "/platform/pose", self._on_pose, qos),
            self.node.create_subscription(TensionDistribution, "/cables/tension", self._on_tension, qos),
            self.node.create_subscription(DiagnosticArray, "/diagnostics", self._on_diagnostics, 10)]
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.thread = threading.Thread(target=self.executor.spin, daemon=True)
        self.thread.start()

    def _on_pose(self, msg) -> None:
        self.received[(msg.header.stamp.sec, msg.header.stamp.nanosec)] = time.perf_counter_ns()

    def _on_tension(self, msg) -> None:
        self.taut[(msg.header.stamp.sec, msg.header.stamp.nanosec)] = tuple(c.taut for c in msg.cables)

    def _on_diagnostics(self, msg: DiagnosticArray) -> None:
        for status in msg.status:
            if status.name == SOLVER_STATUS:
                self.solver = {kv.key: kv.value for kv in status.values}

    def next_solver_status(self, timeout: float = 5.0, sim_time: int | None = None) -> dict[str, str]:
        """The node's solver status (key -> value) from its next /diagnostics; a node on /clock has its clock
        moved on from `sim_time` [ns] meanwhile (its diagnostics timer runs on it)."""
        self.solver = {}
        deadline = time.monotonic() + timeout
        while not self.solver:
            if time.monotonic() > deadline:
                raise SystemExit("node_latency: no /diagnostics from the node")
            if sim_time is not None:
                sim_time += 100_000_000
                self.clock.publish(Clock(clock=Time(sec=sim_time // 1_000_000_000, nanosec=sim_time % 1_000_000_000)))
            time.sleep(0.02)
        return self.solver

    def node_times(self, sim_time: int | None = None) -> dict[str, str]:
        """The node's own queueing and merge-to-outputs times of its latest samples (p50, p99, max [ms]), from its
        next /diagnostics (`sim_time`: as `next_solver_status`): what the latency is made of inside the node."""
        solver = self.next_solver_status(sim_time=sim_time)
        return {name: value for name, value in solver.items() if name.startswith(NODE_TIMES)}

    def connected(self) -> bool:
        return self.publisher.get_subscription_count() > 0 and all(
            s.get_publisher_count() > 0 for s in self.subscriptions)

    def publish_raw(self, topic: str, msgtype: str, data: bytes) -> None:
        """A recorded message's bytes on its topic (its publisher made at the first)."""
        publisher = self.raw.get(topic)
        if publisher is None:
            qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
            publisher = self.raw[topic] = self.node.create_publisher(message_class(msgtype), topic, qos)
        publisher.publish(data)

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
    """Wait for matching, then publish the `warming` readings (`warm_up`) at 50 Hz (none: no warm-up)."""
    deadline = time.monotonic() + CONNECT_TIMEOUT
    while not probe.connected():
        if node.poll() is not None or time.monotonic() > deadline:
            raise SystemExit("node_latency: the winch_monitor node did not come up")
        time.sleep(0.05)
    for readings in warming:
        probe.publish(readings)
        time.sleep(0.02)
    time.sleep(0.2)
    if len(warming) and not probe.received:
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
    changed, the node's CPU [s] over the wall time [s] of the run, and the node's own account of its latest
    samples' times."""

    all: np.ndarray
    steady: np.ndarray
    changed: np.ndarray
    cpu: float
    wall: float
    node: dict[str, str]  # the node's own times of its latest samples (`Probe.node_times`)


def measure(samples: int, rate: float, domain_id: int, solver: str = "energy",
            plant_file: Path | None = None) -> Latency:
    """Start the node, publish a lowering at `rate`, and time each pose coming back."""
    readings, warming = lowering(samples, rate, plant_file=plant_file), warm_up(plant_file)
    with _node_and_probe(domain_id, solver, plant_file, sim_time=False) as (node, probe):
        connect(probe, node, warming)
        probe.received.clear()
        cpu0, wall0 = cpu_seconds(node.pid), time.monotonic()
        sent = publish_paced(probe, readings, rate)
        time.sleep(0.5)
        cpu, wall = cpu_seconds(node.pid) - cpu0, time.monotonic() - wall0
        times = probe.node_times()
    return _latency(probe, sent, cpu, wall, times)


@contextmanager
def _node_and_probe(domain_id: int, solver: str, plant_file: Path | None,
                    sim_time: bool) -> Iterator[tuple[subprocess.Popen, Probe]]:
    """The node in its own process and a probe node talking to it; both stopped on the way out."""
    with tempfile.TemporaryDirectory() as scratch:
        log = Path(scratch) / "node.log"
        node = start_node(domain_id, solver, log, plant_file, sim_time=sim_time)
        probe = Probe(domain_id)
        try:
            yield node, probe
        finally:
            probe.close()
            stop(node, log)


def stop(node: subprocess.Popen, log: Path, timeout: float = 10.0) -> None:
    """SIGINT, as Ctrl-C would; a node that has not ended after `timeout` seconds has its threads' stacks
    written to its log (SIGUSR1), printed, and is killed: the benchmark goes on with its other figures."""
    node.send_signal(signal.SIGINT)
    try:
        node.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        node.send_signal(signal.SIGUSR1)
        time.sleep(1.0)
        print(f"winch_monitor did not end within {timeout:g} s of SIGINT (killed); its log and threads:\n"
              f"{log.read_text(errors='replace')[-8000:]}", file=sys.stderr)
        node.kill()
        node.wait()


def measure_recording(bag: Path, domain_id: int, plant_file: Path | None = None, seconds: float = math.inf,
                      settle: float = SETTLE) -> Latency:
    """Play the first `seconds` of a recording's inputs to the node (on /clock: its stamps stay the
    recording's) at their log times, and time each winch message to its pose; the first `settle` seconds
    (the node's start) are played but not counted."""
    items = []
    for item in BagReader(bag, input_topics()):
        items.append(item)
        if (item.log_time - items[0].log_time) * 1e-9 > seconds:
            break
    first = items[0].log_time
    with _node_and_probe(domain_id, "energy", plant_file, sim_time=True) as (node, probe):
        for item in items[:1]:  # a publisher on each input topic before the wait for matching
            probe.publish_raw(item.topic, item.msgtype, item.data)
        connect(probe, node, np.empty((0, 8)))
        sent: dict[tuple[int, int], int] = {}
        started, counted = time.monotonic(), None
        for item in items:
            since = (item.log_time - first) * 1e-9
            time.sleep(max(0.0, started + since - time.monotonic()))
            if counted is None and since >= settle:
                counted, cpu0, wall0 = True, cpu_seconds(node.pid), time.monotonic()
            sec, nanosec = divmod(item.log_time, 1_000_000_000)
            probe.clock.publish(Clock(clock=Time(sec=sec, nanosec=nanosec)))
            at = time.perf_counter_ns()
            probe.publish_raw(item.topic, item.msgtype, item.data)
            if counted and item.msgtype == JOINT_STATE:
                stamp = item.message.header.stamp
                sent[(stamp.sec, stamp.nanosec)] = at
        time.sleep(0.5)
        cpu, wall = cpu_seconds(node.pid) - cpu0, time.monotonic() - wall0
        times = probe.node_times(sim_time=items[-1].log_time)
    return _latency(probe, sent, cpu, wall, times)


def _latency(probe: Probe, sent: dict[tuple[int, int], int], cpu: float, wall: float,
             times: dict[str, str]) -> Latency:
    """Each sent sample's latency, those where the taut set held and where it changed."""
    latency = {key: (probe.received[key] - at) / 1e6 for key, at in sent.items() if key in probe.received}
    keys = list(sent)
    switched = {b for a, b in zip(keys, keys[1:]) if probe.taut.get(a, ()) != probe.taut.get(b, ())}
    return Latency(np.array(list(latency.values())), np.array([v for k, v in latency.items() if k not in switched]),
                   np.array([v for k, v in latency.items() if k in switched]), cpu, wall, times)


def run(samples: int, rate: float, domain_id: int, solver: str, plant_file: Path | None = None,
        recording: Path | None = None) -> int:
    if recording is not None:
        result = measure_recording(recording, domain_id, plant_file, samples / rate + SETTLE)
        print(f"winch_monitor end-to-end latency ({plant_file or 'bundled plant'}), {recording} played for "
              f"{samples / rate + SETTLE:g} s, the first {SETTLE:g} s not counted")
        print(f"  poses received      {result.all.size}")
    else:
        result = measure(samples, rate, domain_id, solver, plant_file)
        print(f"winch_monitor end-to-end latency ({solver} solver, {plant_file or 'bundled plant'}), {samples} "
              f"samples at {rate:g} Hz, lowering {LOWERING_SPEED} m/s, sync drift {SYNC_AMPLITUDE * 1e3:g} mm, "
              f"jitter {ENCODER_NOISE * 1e3:g} mm, load pins {PIN_NOISE:g} N")
        print(f"  poses received      {result.all.size} of {samples}")
    print(f"  all samples         {percentiles(result.all)}")
    print(f"  taut set unchanged  {percentiles(result.steady)}")
    print(f"  taut set changed    {percentiles(result.changed)}")
    print(f"  node CPU share      {100.0 * result.cpu / result.wall:.1f} % of one core ({result.cpu:.2f} s CPU in "
          f"{result.wall:.2f} s)")
    for name, value in result.node.items():
        print(f"  in the node: {name}: {value}")
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=2000)
    parser.add_argument("--rate", type=float, default=50.0, help="samples per second")
    parser.add_argument("--domain-id", type=int, help="ROS domain (default: one no test run holds)")
    parser.add_argument("--solver", default="energy", choices=("energy", "traversal"))
    parser.add_argument("--plant-file", type=Path, help="plant YAML for the node (default: the bundled plant)")
    parser.add_argument("--recording", type=Path, help="play this bag's inputs instead of a lowering "
                        "(--samples / --rate seconds of it, after the node's start)")
    args = parser.parse_args(argv)
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    if args.domain_id is not None:
        return run(args.samples, args.rate, args.domain_id, args.solver, args.plant_file, args.recording)
    with leased_domain() as domain:
        return run(args.samples, args.rate, domain, args.solver, args.plant_file, args.recording)


if __name__ == "__main__":
    sys.exit(main())
