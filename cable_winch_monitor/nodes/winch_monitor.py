"""The live monitor node: winch joint states in; pose, /tf, tensions, alarm, residuals, the 3-D scene and
diagnostics out.

A thin adapter around the monitor (held by the live scheduler): every callback converts a message and hands
it to the monitor; winch messages are merged in the callback and the complete samples waiting
are solved together, in order, by a worker thread (live.scheduler), so that a burst never
queues more than the backlog. Outputs are stamped with the input's own stamp. Callbacks never raise: bad input
is counted (diagnostics), logged with a throttle and skipped.
"""
from __future__ import annotations

import faulthandler
import functools
import importlib
import signal
import sys
import threading
from collections.abc import Callable
from typing import Any, cast

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped
from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor
from rclpy.clock import Clock, ClockType, JumpThreshold, ROSClock, TimeJump
from rclpy.duration import Duration
from rclpy.event_handler import PublisherEventCallbacks
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.subscription import Subscription
from sensor_msgs.msg import JointState
from tf2_msgs.msg import TFMessage
from visualization_msgs.msg import MarkerArray

from cable_winch_monitor_msgs.msg import CollisionAlarm, ModelError, ModelParameters, ModelResiduals, TensionDistribution
from cable_winch_monitor_msgs.srv import CheckCableLengths, WritePlantFile

from ..channels import WINCH_TOPICS, Input
from ..effects import EffectError
from ..live.scheduler import BACKLOG, LiveScheduler
from ..messages import fields, frames, outputs, records
from ..messages.scene import LIVE_RATE, SceneBuilder, SceneState, SceneThrottle
from ..model.plantfile.plant import PlantConfigError, load_plant
from ..model.solvers.solve import METHODS
from ..monitor.diagnostics import DiagnosticsReporter
from ..monitor.inputs import StampWindow
from ..monitor.judged import MonitorOutput
from ..monitor.pipeline import CompleteSample
from ..monitor.residuals import Residuals
from ..monitor.sensors import READING_LAG
from ..monitor.waiting import READING_WAIT
from .conversions import build, check_response, message_class, rejected_response, requested_lengths
from .winch_input import WinchInput, waiting

NODE_NAME = "winch_monitor"
MERGED_TOPIC = "/winch/joint_states"
DEFAULT_WINCH_TOPICS = [f"/winch_{i}/joint_states" for i in range(1, 5)]
# Reliable, and 50 ms deep at 1 kHz: a callback takes the whole queue and only merges, the
# solves are the worker's; a queue that overflows drops its oldest samples, counted from the
# sequence gaps (winch_input), never a backlog of stale ones.
SENSOR_QOS = QoSProfile(reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST, depth=50)
OUTPUT_QOS = QoSProfile(reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST, depth=10)
# As tf2's broadcasters: /tf reliable and 100 deep; what never changes (/tf_static, the deck outlines) latched
# (transient local) for late subscribers.
TF_QOS = QoSProfile(reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST, depth=100)
LATCHED_QOS = QoSProfile(reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST, depth=1,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
LOG_THROTTLE = 5.0  # [s] between log lines about rejected input
WORKER_POLL = 0.1  # [s] the solving worker checks this often whether the node is shutting down
# [s] of the steady clock: the executor returns from its wait at least this often, so that a SIGINT whose own
# wake-up of the wait is lost is still taken (Python raises it when the main thread runs again). Under
# use_sim_time, with no /clock coming, nothing else wakes it: a node was seen waiting for ever after a SIGINT.
STOP_WAKE = 1.0
# The publishers go without rclpy's default QoS-event handlers (a warning logged here on an incompatible
# subscriber, which warns on its own side too): each publisher's two are waitables the executor polls at
# every wake, and the twenty cost the node 0.6-0.9 ms of its publish-to-pose latency. The subscriptions
# keep theirs: an input the node cannot receive must be said here.
QUIET = PublisherEventCallbacks(use_default_callbacks=False)


def _range(low: float, high: float) -> list[FloatingPointRange]:
    return [FloatingPointRange(from_value=low, to_value=high)]


# name, default, descriptor; all are read at start-up only.
PARAMETERS: tuple[tuple[str, Any, ParameterDescriptor], ...] = (
    ("plant_file", "", ParameterDescriptor(
        description="plant YAML file (geometry, shaft, outline, alarm margins); '' = the bundled seed-002 plant",
        read_only=True)),
    ("solver", "energy", ParameterDescriptor(
        description="equilibrium solver: 'energy' (warm-started, the default) or 'traversal' (seed 002 as published)",
        additional_constraints="one of: " + ", ".join(METHODS), read_only=True)),
    ("staleness", 0.5, ParameterDescriptor(
        description="[s] a sample is solved only when no cable's latest length is older than this",
        floating_point_range=_range(0.001, 60.0), read_only=True)),
    ("backlog", BACKLOG, ParameterDescriptor(
        description="[s] complete samples waiting while the solver is busy are solved together, in order; one more "
                    "than this (of stamps) behind the newest is skipped",
        floating_point_range=_range(0.0, 10.0), read_only=True)),
    ("reading_wait", READING_WAIT, ParameterDescriptor(
        description="[s] a complete sample waits at most this long for a sensor reading due at its stamp that another "
                    "topic's messages overtook (then it is fused without it)",
        floating_point_range=_range(0.0, 1.0), read_only=True)),
    ("reading_lag", READING_LAG, ParameterDescriptor(
        description="[s] a sample fuses each sensor's latest reading stamped at least this long before it (carried to "
                    "its stamp), so that it need not wait for one another topic's messages may still bring",
        floating_point_range=_range(0.0, 1.0), read_only=True)),
    ("stamp_ahead", StampWindow.ahead, ParameterDescriptor(
        description="[s] a winch stamp later than its arrival on the node clock by more than this is refused",
        floating_point_range=_range(0.001, 1e10), read_only=True)),
    ("stamp_behind", StampWindow.behind, ParameterDescriptor(
        description="[s] a winch stamp earlier than its arrival on the node clock by more than this is refused",
        floating_point_range=_range(0.001, 1e10), read_only=True)),
    ("stamp_skew", StampWindow.skew, ParameterDescriptor(
        description="[s] a winch stamp later than the other reporting winches' newest by more than this is refused",
        floating_point_range=_range(0.001, 1e10), read_only=True)),
    ("diagnostics_period", 1.0, ParameterDescriptor(
        description="[s] period of /diagnostics (at most 1 s)", floating_point_range=_range(0.01, 1.0),
        read_only=True)),
    ("scene_rate", LIVE_RATE, ParameterDescriptor(
        description="[1/s] most 3-D scenes (/platform/scene) per second of sample stamps",
        floating_point_range=_range(0.1, 100.0), read_only=True)),
    ("winch_topics", DEFAULT_WINCH_TOPICS, ParameterDescriptor(
        description=f"per-winch sensor_msgs/JointState topics, merged by cable name with {MERGED_TOPIC}",
        read_only=True)),
)


class WinchMonitorNode(Node):
    """Subscribes the winches and platform sensors, publishes the monitor's outputs."""

    def __init__(self, **kwargs: Any):
        super().__init__(NODE_NAME, **kwargs)
        for name, default, descriptor in PARAMETERS:
            self.declare_parameter(name, default, descriptor)
        value = self._parameter
        plant = load_plant(value("plant_file") or None)  # '' = the bundled plant
        window = StampWindow(value("stamp_ahead"), value("stamp_behind"), value("stamp_skew"))
        self.live = LiveScheduler(plant, value("solver"), value("staleness"), stamp_window=window,
                                  backlog=value("backlog"), wait=value("reading_wait"), lag=value("reading_lag"))
        importlib.import_module("scipy.optimize")  # the solvers' fallback, loaded now rather than at a sample
        self.reporter = DiagnosticsReporter(hardware_id=plant.name)
        self._rejections_logged = 0

        publisher = functools.partial(self.create_publisher, event_callbacks=QUIET)
        self.pose_pub = publisher(PoseStamped, outputs.POSE, OUTPUT_QOS)
        self.tension_pub = publisher(TensionDistribution, outputs.TENSION, OUTPUT_QOS)
        self.alarm_pub = publisher(CollisionAlarm, outputs.ALARM, OUTPUT_QOS)
        self.residuals_pub = publisher(ModelResiduals, outputs.RESIDUALS, OUTPUT_QOS)
        self.model_error_pub = publisher(ModelError, outputs.MODEL_ERROR, OUTPUT_QOS)
        self.parameters_pub = publisher(ModelParameters, outputs.PARAMETERS, OUTPUT_QOS)
        self.diagnostics_pub = publisher(DiagnosticArray, outputs.DIAGNOSTICS, 10)
        self.tf_pub = publisher(TFMessage, outputs.TF, TF_QOS)
        self.scene_pub = publisher(MarkerArray, outputs.SCENE, OUTPUT_QOS)
        self._output_publishers = {outputs.POSE: self.pose_pub, outputs.TF: self.tf_pub,
                                   outputs.TENSION: self.tension_pub, outputs.ALARM: self.alarm_pub,
                                   outputs.RESIDUALS: self.residuals_pub, outputs.MODEL_ERROR: self.model_error_pub,
                                   outputs.PARAMETERS: self.parameters_pub}
        self.scene, self.scene_throttle = SceneBuilder(plant), SceneThrottle(value("scene_rate"))
        self.tf_static_pub = publisher(TFMessage, outputs.TF_STATIC, LATCHED_QOS)
        self.outline_pub = publisher(MarkerArray, outputs.OUTLINE, LATCHED_QOS)
        now = self.get_clock().now().to_msg()
        self.tf_static_pub.publish(build(TFMessage, frames.static_tf((now.sec, now.nanosec), plant)))
        self.outline_pub.publish(build(MarkerArray, self.scene.outline((now.sec, now.nanosec))))

        # The sensors' subscriptions come first: where a reading and a winch message wait together, the executor
        # takes them in this order, and a winch callback empties their queues before it merges (`_read_waiting`),
        # so that a sample has the readings sent before it (as a replay in log order).
        self._readers: list[tuple[Subscription, Callable[[Any], None]]] = []
        for topic, msgtype in self.live.monitor.model.channels.topic_types().items():  # inclinometer, depth, a user's
            if topic not in WINCH_TOPICS:
                handler = self._guarded(topic, self._on_measurement, topic)
                self._readers.append((self.create_subscription(message_class(msgtype), topic, handler, SENSOR_QOS),
                                      handler))
        for spec in self.live.monitor.model.inputs:  # what the plant's effects read (a shaft temperature)
            handler = self._guarded(spec.topic, self._on_input, spec)
            self._readers.append((self.create_subscription(message_class(spec.msgtype), spec.topic, handler,
                                                           SENSOR_QOS), handler))
        self.winch_inputs = [WinchInput(topic) for topic in dict.fromkeys([MERGED_TOPIC, *value("winch_topics")])]
        for winch in self.winch_inputs:
            # rclpy passes the message info to a callback of two parameters (its annotation names one only)
            winch.subscription = self.create_subscription(
                JointState, winch.topic, self._winch_callback(winch), SENSOR_QOS)  # type: ignore[arg-type]
        self.create_service(CheckCableLengths, "~/check_cable_lengths", self._check_cable_lengths)
        self.create_service(WritePlantFile, "~/write_plant_file", self._write_plant_file)
        self.create_timer(value("diagnostics_period"), self._guarded("diagnostics", self._publish_diagnostics))
        self.create_timer(STOP_WAKE, lambda: None, clock=Clock(clock_type=ClockType.STEADY_TIME))
        self._clock_jumps = self.get_clock().create_jump_callback(  # a bag played again (--loop) under sim time
            JumpThreshold(min_forward=None, min_backward=Duration(nanoseconds=-int(value("staleness") * 1e9)),
                          on_clock_change=False), post_callback=self._guarded("clock", self._on_clock_jump))
        self._stopping = threading.Event()
        self._worker = threading.Thread(target=self._work, name="winch_monitor solver", daemon=True)
        self._worker.start()
        self.get_logger().info(f"monitoring plant '{plant.name}' with the {self.live.monitor.solver} solver")

    def destroy_node(self) -> None:
        """Stop the solver thread and the window updates' process; neither keeps the node's exit waiting (an update
        the solver awaits is worked out in the thread, monitor.updates)."""
        self._stopping.set()
        self.live.close()
        self._worker.join(timeout=5.0)
        super().destroy_node()

    def _work(self) -> None:
        """Solve the complete samples waiting whenever there are some, until the node shuts down."""
        while not self._stopping.is_set():
            taken = self.live.take(WORKER_POLL)
            if taken:
                self._guarded("solver", self._solve, taken)()

    def _solve(self, taken: list[tuple[fields.Stamp, CompleteSample]]) -> None:
        for (stamp, _), output in zip(taken, self.live.solve_all([sample for _, sample in taken])):
            self._publish(stamp, output)

    def _parameter(self, name: str) -> Any:
        return self.get_parameter(name).value

    def _now(self) -> float:
        """The node clock [s]; NaN while it has not started (use_sim_time before the first /clock): the
        arrival of a message is then not known, and its stamp is not judged against it."""
        clock = cast(ROSClock, self.get_clock())  # a node's clock is a ROSClock (rclpy's Node.__init__)
        nanoseconds = clock.now().nanoseconds
        return nanoseconds * 1e-9 if nanoseconds or not clock.ros_time_is_active else float("nan")

    def _on_clock_jump(self, jump: TimeJump) -> None:
        """The clock went back by more than the staleness limit (a bag played again): every stamp kept is from a
        future that will not come, and would refuse the new messages as not increasing. Forget them, say so."""
        back = -jump.delta.nanoseconds * 1e-9
        with self.live.lock:
            self.live.restart()
            self.reporter.note_clock_jump(back, self._now())
        self.get_logger().warning(f"clock went back {back:.3f} s: stamp history reset")

    def _guarded(self, where: str, handler: Callable[..., None], *args: Any) -> Callable[..., None]:
        """A callback that reports and swallows any exception, so that one bad message cannot stop the node."""
        def callback(*message: Any) -> None:
            try:
                handler(*message, *args)
            except Exception as error:
                self.reporter.note_callback_error(where, error)
                self.get_logger().error(f"{where}: {type(error).__name__}: {error}", throttle_duration_sec=LOG_THROTTLE)
            self._log_rejections()
        return callback

    def _log_rejections(self) -> None:
        with self.live.lock:
            total = sum(self.live.monitor.stats.rejected.values())
        if total > self._rejections_logged:
            self._rejections_logged = total
            self.get_logger().warning(f"input rejected ({total} so far): {self.live.monitor.stats.last_rejection}",
                                      throttle_duration_sec=LOG_THROTTLE)

    def _winch_callback(self, winch: WinchInput) -> Callable[[JointState, dict], None]:
        guarded = self._guarded(winch.topic, self._on_joint_states, winch)

        def callback(msg: JointState, info: dict) -> None:  # two parameters: rclpy passes the message info
            guarded(msg, info)
        return callback

    def _on_joint_states(self, msg: JointState, info: dict, winch: WinchInput) -> None:
        """Merge this message and every one queued behind it; the worker solves the newest complete sample."""
        messages = winch.drain(msg, info)
        self._read_waiting()
        now = self._now()
        with self.live.lock:
            self.live.unseen = sum(w.unseen for w in self.winch_inputs)
            for message in messages:
                before = list(self.live.monitor.merger.readings)
                self.live.offer(fields.joint_sample(message, winch.topic, now),
                                    fields.stamp_of(message))
                accepted = [i for i, reading in enumerate(self.live.monitor.merger.readings) if reading is not before[i]]
                self.reporter.note_readings(accepted, now)

    def _read_waiting(self) -> None:
        """The sensors' readings waiting in their queues, taken before the winch messages just drained are
        merged: under load the executor hands a winch message over while a reading sent before it waits."""
        for subscription, handler in self._readers:
            for message, _ in waiting(subscription):
                handler(message)

    def _publish(self, stamp: fields.Stamp, output: MonitorOutput) -> None:
        """The sample's outputs as replay records them (messages.records: pose and /tf only if solved), sent as
        their CDR bytes: building rclpy messages instead took four times as long."""
        self._note_residuals(output.residuals)
        self._send(records.output_records(stamp, output, self.live.monitor.model.channels))
        if self.scene_throttle.due(output.stamp):
            self.scene_pub.publish(records.scene_cdr(stamp, self.scene, SceneState.of(output.solution, output.alarm)))

    def _note_residuals(self, residuals: Residuals | None) -> None:
        if residuals is not None:
            with self.live.lock:
                self.reporter.note_residuals(residuals)

    def _send(self, outputs: list[records.Record]) -> None:
        for topic, _, data in outputs:
            self._output_publishers[topic].publish(data)

    def _on_measurement(self, msg: Any, topic: str) -> None:
        now = self.get_clock().now().nanoseconds
        residuals = self.live.on_measurement(topic, fields.message_seconds(msg, now), msg)
        self._note_residuals(residuals)
        self._send(records.residual_records(fields.message_stamp(msg, now), residuals))

    def _on_input(self, msg: Any, spec: Input) -> None:
        with self.live.lock:
            self.live.monitor.on_input(spec, fields.message_seconds(msg, self.get_clock().now().nanoseconds), msg)

    def _publish_diagnostics(self) -> None:
        now = self.get_clock().now()
        stamp = divmod(now.nanoseconds, 1_000_000_000)
        with self.live.lock:
            values = self.reporter.build(self.live.monitor, now.nanoseconds * 1e-9, stamp, self.live.counters())
        self.diagnostics_pub.publish(records.diagnostics_record(values)[2])

    def _check_cable_lengths(self, request: CheckCableLengths.Request,
                             response: CheckCableLengths.Response) -> CheckCableLengths.Response:
        try:
            lengths, error = requested_lengths(request.names, request.lengths)
            if lengths is None:
                return rejected_response(f"invalid request: {error}")
            with self.live.lock:
                solution, _, alarm = self.live.monitor.evaluate(lengths)
            now = self.get_clock().now().to_msg()
            return check_response((now.sec, now.nanosec), solution, alarm)
        except Exception as error:
            self.reporter.note_callback_error("~/check_cable_lengths", error)
            self.get_logger().error(f"check_cable_lengths: {type(error).__name__}: {error}")
            return rejected_response(f"internal error: {type(error).__name__}: {error}")


    def _write_plant_file(self, request: WritePlantFile.Request,
                          response: WritePlantFile.Response) -> WritePlantFile.Response:
        """Write the plant file with the tracked values the model uses now (where the plant file tracks some)."""
        with self.live.lock:
            estimator = self.live.monitor.estimator
        try:
            if estimator is None or estimator.tracker is None:
                raise ValueError("the plant file tracks no parameters (plant.track), or its lengths are taken as exact")
            response.message = estimator.tracker.write(estimator.base, request.path, f"the {NODE_NAME} node's tracked values")
            response.success = True
        except (OSError, ValueError) as error:
            response.success, response.message = False, str(error)
        return response


def main(args: list[str] | None = None) -> int:
    """Entry point `winch_monitor`: ROS arguments (--ros-args -p ..., --params-file) are honoured. SIGUSR1 writes
    every thread's Python stack to the node's stderr, and the node goes on (a node that seems stuck, or does
    not end on SIGINT, tells where it is)."""
    if hasattr(signal, "SIGUSR1"):
        faulthandler.register(signal.SIGUSR1, all_threads=True)
    rclpy.init(args=args)
    try:
        node = WinchMonitorNode()
    except (PlantConfigError, ParameterException, EffectError, ValueError) as error:
        print(f"{NODE_NAME}: error: {error}", file=sys.stderr)
        rclpy.try_shutdown()
        return 2
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
