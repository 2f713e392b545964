"""The live monitor node: winch joint states in; pose, tensions, alarm, residuals and diagnostics out.

A thin adapter around MonitorPipeline: every callback converts a message, calls the
pipeline and publishes what it returns, stamped with the input's own stamp. Callbacks
never raise: bad input is counted (diagnostics), logged with a throttle and skipped.
"""
from __future__ import annotations

import importlib
import sys
from typing import Any, Callable, Sequence

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped
from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState

from cable_winch_monitor_msgs.msg import CollisionAlarm, ModelResiduals, TensionDistribution
from cable_winch_monitor_msgs.srv import CheckCableLengths

from .. import channels
from ..bagio import fields
from ..channels import WINCH_TOPICS, Input
from ..effects import EffectError
from ..model.plant import PlantConfigError, load_plant
from ..model.solve import METHODS
from ..monitor.pipeline import MonitorOutput, MonitorPipeline
from ..monitor.residuals import Residuals
from .conversions import build, check_response, message_class, rejected_response, requested_lengths
from .diagnostics import DiagnosticsReporter

NODE_NAME = "winch_monitor"
MERGED_TOPIC = "/winch/joint_states"
DEFAULT_WINCH_TOPICS = [f"/winch_{i}/joint_states" for i in range(1, 5)]
# Reliable and one second deep at 1 kHz: a burst is queued and worked off, not dropped unseen.
# (The node handles about 1,000 samples/s on an idle core; with a queue of 50 a one-second
# burst of 1,000 lost 40-50 % of its messages once the CPU was shared.)
SENSOR_QOS = QoSProfile(reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST, depth=1000)
OUTPUT_QOS = QoSProfile(reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST, depth=10)
LOG_THROTTLE = 5.0  # [s] between log lines about rejected input


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
    ("diagnostics_period", 1.0, ParameterDescriptor(
        description="[s] period of /diagnostics (at most 1 s)", floating_point_range=_range(0.01, 1.0),
        read_only=True)),
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
        self.pipeline = MonitorPipeline(plant, value("solver"), value("staleness"))
        importlib.import_module("scipy.optimize")  # the solvers' fallback, loaded now rather than at a sample
        self.reporter = DiagnosticsReporter(hardware_id=plant.name)
        self._rejections_logged = 0

        self.pose_pub = self.create_publisher(PoseStamped, "/platform/pose", OUTPUT_QOS)
        self.tension_pub = self.create_publisher(TensionDistribution, "/cables/tension", OUTPUT_QOS)
        self.alarm_pub = self.create_publisher(CollisionAlarm, "/platform/collision_alarm", OUTPUT_QOS)
        self.residuals_pub = self.create_publisher(ModelResiduals, "/model/residuals", OUTPUT_QOS)
        self.diagnostics_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)

        for topic in dict.fromkeys([MERGED_TOPIC, *value("winch_topics")]):
            self.create_subscription(JointState, topic, self._guarded(topic, self._on_joint_state, topic), SENSOR_QOS)
        for topic, msgtype in channels.topic_types().items():  # inclinometer, depth gauge, declared sensors
            if topic not in WINCH_TOPICS:
                self.create_subscription(message_class(msgtype), topic,
                                         self._guarded(topic, self._on_measurement, topic), SENSOR_QOS)
        for spec in self.pipeline.model.inputs:  # what the plant's effects read (a shaft temperature)
            self.create_subscription(message_class(spec.msgtype), spec.topic,
                                     self._guarded(spec.topic, self._on_input, spec), SENSOR_QOS)
        self.create_service(CheckCableLengths, "~/check_cable_lengths", self._check_cable_lengths)
        self.create_timer(value("diagnostics_period"), self._guarded("diagnostics", self._publish_diagnostics))
        self.get_logger().info(f"monitoring plant '{plant.name}' with the {self.pipeline.solver} solver")

    def _parameter(self, name: str) -> Any:
        return self.get_parameter(name).value

    def _now(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def _guarded(self, where: str, handler: Callable[..., None], *args: Any) -> Callable[..., None]:
        """A callback that reports and swallows any exception, so that one bad message cannot stop the node."""
        def callback(*message: Any) -> None:
            try:
                handler(*message, *args)
            except Exception as error:  # noqa: BLE001 - the node must keep running
                self.reporter.note_callback_error(where, error)
                self.get_logger().error(f"{where}: {type(error).__name__}: {error}", throttle_duration_sec=LOG_THROTTLE)
            self._log_rejections()
        return callback

    def _log_rejections(self) -> None:
        total = sum(self.pipeline.stats.rejected.values())
        if total > self._rejections_logged:
            self._rejections_logged = total
            self.get_logger().warning(f"input rejected ({total} so far): {self.pipeline.stats.last_rejection}",
                                      throttle_duration_sec=LOG_THROTTLE)

    def _on_joint_state(self, msg: JointState, topic: str) -> None:
        before = list(self.pipeline.merger.readings)
        output = self.pipeline.on_joint_state(fields.joint_sample(msg, topic))
        accepted = [i for i, reading in enumerate(self.pipeline.merger.readings) if reading is not before[i]]
        self.reporter.note_readings(accepted, self._now())
        if output is not None:
            self._publish(fields.stamp_of(msg), output)

    def _publish(self, stamp: fields.Stamp, output: MonitorOutput) -> None:
        if output.solution.ok:  # never a pose that was not solved
            self.pose_pub.publish(build(PoseStamped, fields.pose_stamped(stamp, output.solution)))
        self.tension_pub.publish(build(TensionDistribution, fields.tension_distribution(stamp, output.solution)))
        self.alarm_pub.publish(build(CollisionAlarm, fields.collision_alarm(stamp, output.alarm)))
        self._publish_residuals(stamp, output.residuals)

    def _publish_residuals(self, stamp: fields.Stamp, residuals: Residuals | None) -> None:
        if residuals is not None:
            self.reporter.note_residuals(residuals)
            self.residuals_pub.publish(build(ModelResiduals, fields.model_residuals(stamp, residuals)))

    def _on_measurement(self, msg: Any, topic: str) -> None:
        now = self.get_clock().now().nanoseconds
        residuals = self.pipeline.on_measurement(topic, fields.message_seconds(msg, now), msg)
        stamp = fields.stamp_of(msg) if hasattr(msg, "header") else divmod(now, 1_000_000_000)
        self._publish_residuals(stamp, residuals)

    def _on_input(self, msg: Any, spec: Input) -> None:
        self.pipeline.on_input(spec, fields.message_seconds(msg, self.get_clock().now().nanoseconds), msg)

    def _publish_diagnostics(self) -> None:
        now = self.get_clock().now()
        self.diagnostics_pub.publish(self.reporter.build(self.pipeline, now.nanoseconds * 1e-9, now.to_msg()))

    def _check_cable_lengths(self, request: CheckCableLengths.Request,
                             response: CheckCableLengths.Response) -> CheckCableLengths.Response:
        try:
            lengths, error = requested_lengths(request.names, request.lengths)
            if lengths is None:
                return rejected_response(f"invalid request: {error}")
            solution, _, alarm = self.pipeline.evaluate(lengths)
            now = self.get_clock().now().to_msg()
            return check_response((now.sec, now.nanosec), solution, alarm)
        except Exception as error:  # noqa: BLE001 - answer, do not crash the service
            self.reporter.note_callback_error("~/check_cable_lengths", error)
            self.get_logger().error(f"check_cable_lengths: {type(error).__name__}: {error}")
            return rejected_response(f"internal error: {type(error).__name__}: {error}")


def main(args: Sequence[str] | None = None) -> int:
    """Entry point `winch_monitor`: ROS arguments (--ros-args -p ..., --params-file) are honoured."""
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
