"""Live-node test harness: the winch_monitor in its own process, a client node in the test process.

Both talk over real DDS on loopback (ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST) in a
domain id of their own, taken with a lock file so that concurrent test runs on this
machine never share one. Every wait is bounded and fails with a message saying what
was awaited and what the node printed.
"""
from __future__ import annotations

import fcntl
import os
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import rclpy
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PointStamped, PoseStamped
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Imu, JointState

from cable_winch_monitor.bench.node_latency import stop as stop_node
from cable_winch_monitor.model.plantfile.plant import CABLE_NAMES
from cable_winch_monitor_msgs.msg import CollisionAlarm, ModelResiduals, TensionDistribution
from cable_winch_monitor_msgs.srv import CheckCableLengths

ROOT = Path(__file__).resolve().parents[2]
NODE_EXECUTABLE = Path(sys.executable).parent / "winch_monitor"
PARAMS_FILE = ROOT / "config" / "winch_monitor.yaml"
DOMAIN_POOL = [d for d in range(40, 100) if d != 87]  # 87: the Makefile's own domain
START_TIMEOUT = 20.0
WAIT_TIMEOUT = 5.0
DEEP_QOS = QoSProfile(reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST, depth=2000)
OUTPUTS = {"pose": (PoseStamped, "/platform/pose"), "tension": (TensionDistribution, "/cables/tension"),
           "alarm": (CollisionAlarm, "/platform/collision_alarm"), "residuals": (ModelResiduals, "/model/residuals"),
           "diagnostics": (DiagnosticArray, "/diagnostics")}

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"


class DomainLease:
    """A ROS_DOMAIN_ID no other process using this harness holds (flock on a file in /tmp)."""

    def __init__(self) -> None:
        for domain in DOMAIN_POOL:
            handle = open(Path(tempfile.gettempdir()) / f"cable_winch_monitor.domain_{domain}.lock", "w")
            try:
                fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                handle.close()
                continue
            self.domain_id, self._handle = domain, handle
            return
        raise RuntimeError(f"every ROS domain id in {DOMAIN_POOL[0]}..{DOMAIN_POOL[-1]} is taken by another test run")

    def release(self) -> None:
        self._handle.close()


def ros_env(domain_id: int) -> dict[str, str]:
    """The environment of a node process: loopback discovery, its own domain, logs under build/."""
    env = dict(os.environ)
    env.update(ROS_DOMAIN_ID=str(domain_id), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
               RMW_IMPLEMENTATION=env.get("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp"),
               ROS_LOG_DIR=env.get("ROS_LOG_DIR", str(ROOT / "build" / "ros_log")), PYTHONUNBUFFERED="1")
    return env


def node_command(params: dict[str, Any] | None = None, params_file: Path | None = PARAMS_FILE) -> list[str]:
    """The node's command line: the parameter file and `params` as ROS arguments (none if neither)."""
    ros_args = ["--params-file", str(params_file)] if params_file is not None else []
    for name, value in (params or {}).items():
        ros_args += ["-p", f"{name}:={value}"]
    return [str(NODE_EXECUTABLE)] + (["--ros-args", *ros_args] if ros_args else [])


def run_node_to_exit(domain_id: int, params: dict[str, Any], timeout: float = 30.0) -> subprocess.CompletedProcess:
    """Run the node expecting it to stop by itself (a start-up error)."""
    return subprocess.run(node_command(params), env=ros_env(domain_id), capture_output=True, text=True,
                          timeout=timeout)


class NodeProcess:
    """`winch_monitor` running in its own process; its output goes to a log file."""

    def __init__(self, domain_id: int, params: dict[str, Any] | None = None, params_file: Path | None = PARAMS_FILE):
        self.log = tempfile.NamedTemporaryFile("w+", prefix="winch_monitor_", suffix=".log")
        self.process = subprocess.Popen(node_command(params, params_file), env=ros_env(domain_id), stdout=self.log,
                                        stderr=subprocess.STDOUT, text=True)

    @property
    def pid(self) -> int:
        return self.process.pid

    def output(self) -> str:
        self.log.flush()
        return Path(self.log.name).read_text()

    def assert_alive(self) -> None:
        code = self.process.poll()
        assert code is None, f"winch_monitor exited with {code}; its output:\n{self.output()[-3000:]}"

    def stop(self) -> int:
        """SIGINT, as Ctrl-C would; the exit code (killed after 10 s, its threads' stacks printed first, as the
        bench stops its nodes: pytest shows what a fixture's teardown printed where it fails)."""
        if self.process.poll() is None:
            stop_node(self.process, Path(self.log.name))
        self.log.close()
        return self.process.returncode


class StampClock:
    """Increasing header stamps near the wall clock (1 ms apart at least), kept in nanoseconds."""

    def __init__(self) -> None:
        self.last_ns = time.time_ns()

    def next(self, advance: float = 0.0) -> Time:
        """A stamp after every earlier one, `advance` seconds later than the last at least."""
        self.last_ns = max(time.time_ns(), self.last_ns + 1_000_000 + int(advance * 1e9))
        return stamp_from_ns(self.last_ns)

    def catch_up(self) -> None:
        """Wait until the wall clock has passed the last stamp, so that stamps advanced from here on stay
        within the node's `stamp_ahead` window however far earlier tests ran ahead."""
        time.sleep(max(0.0, (self.last_ns - time.time_ns()) * 1e-9))


def stamp_from_ns(ns: int) -> Time:
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def stamp_key(stamp: Time) -> tuple[int, int]:
    return stamp.sec, stamp.nanosec


def stamped(stamp: Time) -> Callable[[Any], bool]:
    """A predicate: the message's header carries `stamp`."""
    key = stamp_key(stamp)
    return lambda msg: stamp_key(msg.header.stamp) == key


class Collector:
    """Messages of one topic as they arrive, with their arrival time (perf_counter)."""

    def __init__(self) -> None:
        self.messages: list[tuple[float, Any]] = []
        self.condition = threading.Condition()

    def __call__(self, msg: Any) -> None:
        with self.condition:
            self.messages.append((time.perf_counter(), msg))
            self.condition.notify_all()

    def count(self) -> int:
        with self.condition:
            return len(self.messages)

    def wait_for(self, predicate: Callable[[Any], bool], what: str, timeout: float = WAIT_TIMEOUT,
                 start: int = 0) -> Any:
        """The first message from index `start` on that satisfies `predicate`."""
        deadline = time.monotonic() + timeout
        index = start
        with self.condition:
            while True:
                for _, msg in self.messages[index:]:
                    if predicate(msg):
                        return msg
                index = len(self.messages)
                remaining = deadline - time.monotonic()
                if remaining <= 0.0:
                    raise AssertionError(f"no {what} within {timeout:.1f} s ({len(self.messages)} messages seen)")
                self.condition.wait(remaining)

    def with_stamp(self, stamp: Time) -> list[Any]:
        key = stamp_key(stamp)
        with self.condition:
            return [msg for _, msg in self.messages if stamp_key(msg.header.stamp) == key]


@dataclass
class SampleOutputs:
    """What the node published for one input stamp."""

    tension: TensionDistribution
    alarm: CollisionAlarm
    pose: PoseStamped | None


def diagnostic_statuses(array: DiagnosticArray) -> dict[str, tuple[int, str, dict[str, str]]]:
    """name -> (level, message, key/values) of a DiagnosticArray."""
    return {s.name: (s.level[0] if isinstance(s.level, bytes) else int(s.level), s.message,
                     {kv.key: kv.value for kv in s.values}) for s in array.status}


class TestClient:
    """A client node in its own rclpy context: publishes inputs, collects every output, calls the service."""

    __test__ = False  # not a pytest class

    def __init__(self, domain_id: int, node: NodeProcess | None = None):
        self.node_process = node
        self.context = Context()
        rclpy.init(context=self.context, domain_id=domain_id)
        self.node = rclpy.create_node("winch_monitor_test_client", context=self.context)
        self.collectors = {key: Collector() for key in OUTPUTS}
        self.subscriptions = [self.node.create_subscription(kind, topic, self.collectors[key], DEEP_QOS)
                              for key, (kind, topic) in OUTPUTS.items()]
        self.winch = self._publisher(JointState, "/winch/joint_states")
        self.winches = [self._publisher(JointState, f"/winch_{i}/joint_states") for i in range(1, 5)]
        self.imu = self._publisher(Imu, "/platform/imu")
        self.position = self._publisher(PointStamped, "/platform/position")
        self.service = self.node.create_client(CheckCableLengths, "/winch_monitor/check_cable_lengths")
        self.stamps = StampClock()
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.thread = threading.Thread(target=self.executor.spin, daemon=True)
        self.thread.start()

    def _publisher(self, kind: type, topic: str) -> Any:
        return self.node.create_publisher(kind, topic, DEEP_QOS)

    def _fail(self, message: str) -> None:
        log = self.node_process.output()[-3000:] if self.node_process else ""
        raise AssertionError(f"{message}\nnode output:\n{log}")

    def wait_until_connected(self, timeout: float = START_TIMEOUT, warm_up: bool = True) -> None:
        """Every publisher and subscription matched and the service up, then (`warm_up`) one sample
        of four equal lengths round-trips; without it, a short settle instead."""
        deadline = time.monotonic() + timeout
        publishers = [self.winch, *self.winches, self.imu, self.position]
        while time.monotonic() < deadline:
            if self.node_process:
                self.node_process.assert_alive()
            if (all(p.get_subscription_count() > 0 for p in publishers)
                    and all(s.get_publisher_count() > 0 for s in self.subscriptions)
                    and self.service.service_is_ready()):
                break
            time.sleep(0.05)
        else:
            self._fail(f"winch_monitor did not match the test client within {timeout:.0f} s")
        if not warm_up:
            time.sleep(0.3)
            return
        while time.monotonic() < deadline:  # matched both ways once a sample comes back
            stamp = self.publish((20.0, 20.0, 20.0, 20.0))
            try:
                self.collectors["alarm"].wait_for(stamped(stamp), "warm-up alarm", timeout=0.5)
                return
            except AssertionError:
                continue
        self._fail("no output for a warm-up sample")

    def publish(self, lengths: Sequence[float], names: Sequence[str] = CABLE_NAMES, stamp: Time | None = None,
                efforts: Sequence[float] = (), topic: int | None = None) -> Time:
        """One JointState on /winch/joint_states (or /winch_<topic>/joint_states); its stamp."""
        stamp = stamp or self.stamps.next()
        msg = JointState(name=list(names), position=[float(v) for v in lengths], effort=[float(v) for v in efforts])
        msg.header.stamp, msg.header.frame_id = stamp, "shaft"
        (self.winch if topic is None else self.winches[topic - 1]).publish(msg)
        return stamp

    def publish_imu(self, quaternion_xyzw: Sequence[float], stamp: Time) -> None:
        msg = Imu()
        msg.header.stamp, msg.header.frame_id = stamp, "platform"
        q = msg.orientation
        q.x, q.y, q.z, q.w = (float(v) for v in quaternion_xyzw)
        msg.orientation_covariance[8] = -1.0  # yaw is not measured
        self.imu.publish(msg)

    def publish_position(self, xyz: Sequence[float], stamp: Time) -> None:
        msg = PointStamped()
        msg.header.stamp, msg.header.frame_id = stamp, "shaft"
        msg.point.x, msg.point.y, msg.point.z = (float(v) for v in xyz)
        self.position.publish(msg)

    def outputs(self, stamp: Time, pose: bool, timeout: float = WAIT_TIMEOUT) -> SampleOutputs:
        """Tension and alarm of one input stamp, and its pose if `pose` (a pose is expected)."""
        key = stamp_key(stamp)
        tension = self.collectors["tension"].wait_for(stamped(stamp), f"/cables/tension for stamp {key}", timeout)
        alarm = self.collectors["alarm"].wait_for(stamped(stamp), f"/platform/collision_alarm for stamp {key}",
                                                  timeout)
        found = self.collectors["pose"].wait_for(stamped(stamp), f"/platform/pose for stamp {key}", timeout) \
            if pose else None
        return SampleOutputs(tension, alarm, found)

    def outputs_with_stamp(self, stamp: Time) -> dict[str, list[Any]]:
        """Everything received so far on the stamped output topics for one input stamp."""
        return {key: self.collectors[key].with_stamp(stamp) for key in ("pose", "tension", "alarm", "residuals")}

    def solve(self, lengths: Sequence[float], pose: bool = True, **kwargs: Any) -> SampleOutputs:
        """Publish one sample and wait for what the node makes of it."""
        return self.outputs(self.publish(lengths, **kwargs), pose)

    def diagnostics(self, predicate: Callable[[dict], bool], what: str, timeout: float = WAIT_TIMEOUT) -> dict:
        """The parsed statuses of the first /diagnostics published from now on that satisfy `predicate`."""
        collector = self.collectors["diagnostics"]
        msg = collector.wait_for(lambda m: predicate(diagnostic_statuses(m)), f"/diagnostics with {what}", timeout,
                                 start=collector.count())
        return diagnostic_statuses(msg)

    def call(self, lengths: Sequence[float], names: Sequence[str] = (),
             timeout: float = WAIT_TIMEOUT) -> CheckCableLengths.Response:
        future = self.service.call_async(CheckCableLengths.Request(names=list(names),
                                                                   lengths=[float(v) for v in lengths]))
        done = threading.Event()
        future.add_done_callback(lambda _: done.set())
        if not done.wait(timeout):
            self._fail(f"~/check_cable_lengths gave no answer within {timeout:.0f} s")
        return future.result()

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)
        self.thread.join(timeout=5.0)


class LiveNode:
    """A node process and a connected client sharing one leased domain (a fixture's value)."""

    def __init__(self, params: dict[str, Any] | None = None, warm_up: bool = True,
                 params_file: Path | None = PARAMS_FILE):
        self.lease = DomainLease()
        self.process = NodeProcess(self.lease.domain_id, params, params_file)
        self.client = TestClient(self.lease.domain_id, self.process)
        try:
            self.client.wait_until_connected(warm_up=warm_up)
        except BaseException:
            self.close()
            raise

    def close(self) -> int:
        self.client.close()
        code = self.process.stop()
        self.lease.release()
        return code


INPUTS_STATUS = "winch_monitor: inputs"
WINCH_TOPIC = "/winch/joint_states"


def input_value(statuses: dict, key: str, default: str = "0") -> str:
    """One key of the inputs status of parsed /diagnostics."""
    return statuses[INPUTS_STATUS][2].get(key, default)


def rejected_count(statuses: dict, reason: str, topic: str = WINCH_TOPIC) -> int:
    """How many readings of `topic` the node has rejected for `reason` (e.g. 'bad length')."""
    return int(input_value(statuses, f"rejected {topic}: {reason}"))
