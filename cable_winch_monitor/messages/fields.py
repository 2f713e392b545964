"""The monitor's messages as plain field values: one mapping for every adapter.

Inputs are read by attribute (rclpy and rosbags messages have the same field names);
outputs are nested dicts in the layout of the message definitions (msg_defs/msg and the
standard types), with a stamp given as (sec, nanosec) so that it is copied exactly. The
live node and bag replay each turn these values into their own message objects, so the
two cannot disagree about what goes where.
"""
from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ..channels import BUILTIN_CHANNELS, JOINT_STATE, WINCH_TOPICS, ChannelRegistry
from ..effects import PlantModel
from ..model.estimator import Estimate
from ..model.plantfile.plant import CABLE_NAMES
from ..model.statics.result import Solution, SolveStatus
from ..monitor.alarm import Alarm
from ..monitor.inputs import JointSample
from ..monitor.judged import ModelView
from ..monitor.residuals import Residuals
from ..monitor.tracking import ParameterView

FRAME = "shaft"
NAN = float("nan")
Stamp = tuple[int, int]
Fields = dict[str, Any]

# TensionDistribution.STATUS_* (msg_defs/msg/TensionDistribution.msg)
STATUS_NUMBERS = {SolveStatus.SOLVED: 0, SolveStatus.SINGLE_CABLE_INDETERMINATE: 1, SolveStatus.NO_EQUILIBRIUM: 2,
                  SolveStatus.INVALID_INPUT: 3, SolveStatus.SOLVER_FAILED: 4}


def input_topics(model: PlantModel | None = None) -> dict[str, str]:
    """Every topic the monitor of a plant model reads, with its message type: the winches, every channel's
    topic (interface.md: inclinometer, depth gauge, ...; a user's declared sensors) and the extra inputs of
    the plant's effects; without a model, the built-in channels'."""
    channels, inputs = (BUILTIN_CHANNELS, ()) if model is None else (model.channels, model.inputs)
    return {**{topic: JOINT_STATE for topic in WINCH_TOPICS}, **channels.topic_types(),
            **{spec.topic: spec.msgtype for spec in inputs}}


def seconds(stamp: Any) -> float:
    """A builtin_interfaces/Time in seconds."""
    return stamp.sec + stamp.nanosec * 1e-9


def message_seconds(msg: Any, receive_ns: int) -> float:
    """A message's time [s]: its header stamp, or when it has no header (std_msgs/Float64, ...) the time
    it was received (a bag's log time) [ns]."""
    header = getattr(msg, "header", None)
    return seconds(header.stamp) if header is not None else receive_ns * 1e-9


def message_stamp(msg: Any, receive_ns: int) -> Stamp:
    """`message_seconds` as (sec, nanosec): the stamp of the outputs made from the message."""
    return stamp_of(msg) if getattr(msg, "header", None) is not None else divmod(receive_ns, 1_000_000_000)


def stamp_of(msg: Any) -> Stamp:
    """(sec, nanosec) of a message's header stamp."""
    return int(msg.header.stamp.sec), int(msg.header.stamp.nanosec)


def stamp_ns(stamp: Stamp) -> int:
    return stamp[0] * 1_000_000_000 + stamp[1]


def joint_sample(msg: Any, topic: str, received: float = NAN) -> JointSample:
    """A sensor_msgs/JointState as plain values (arrays are passed through, not copied), arrived at
    `received` [s] (NaN: not known)."""
    return JointSample(seconds(msg.header.stamp), msg.name, msg.position, msg.velocity, msg.effort, topic, received)


def header(stamp: Stamp, frame_id: str = FRAME) -> Fields:
    return {"stamp": {"sec": stamp[0], "nanosec": stamp[1]}, "frame_id": frame_id}


def point(xyz: np.ndarray | None) -> Fields:
    if xyz is None:
        return {"x": NAN, "y": NAN, "z": NAN}
    x, y, z = xyz.tolist()
    return {"x": x, "y": y, "z": z}


def larger(a: float, b: float) -> float:
    """np.fmax of two floats (the larger; the other where one is NaN) without numpy's call."""
    return b if a != a or b > a else a


def _floats(values: np.ndarray | None) -> list[float]:
    """Four per-cable values as floats (NaN when the solve has none)."""
    return [NAN] * 4 if values is None else values.tolist()


def pose(solution: Solution) -> Fields:
    """geometry_msgs/Pose of `platform` in `shaft` (NaN position, identity orientation without a pose)."""
    q = solution.quaternion
    return pose_of(point(solution.position), (0.0, 0.0, 0.0, 1.0) if q is None else q.tolist())


def pose_of(position: Fields, quaternion: Sequence[float]) -> Fields:
    """geometry_msgs/Pose from a Point's fields and a quaternion (x, y, z, w)."""
    x, y, z, w = quaternion
    return {"position": position, "orientation": {"x": x, "y": y, "z": z, "w": w}}


def pose_stamped(stamp: Stamp, position: Sequence[float], quaternion: Sequence[float]) -> Fields:
    """geometry_msgs/PoseStamped of `platform` in `shaft` at `position` [m], turned by `quaternion` (x, y, z, w)."""
    x, y, z = position
    return {"header": header(stamp), "pose": pose_of({"x": x, "y": y, "z": z}, quaternion)}


def tension_distribution(stamp: Stamp, solution: Solution, estimate: Estimate | None = None,
                         channels: ChannelRegistry = BUILTIN_CHANNELS) -> Fields:
    """Per-cable length, span, tension and taut flag, the tension state as a whole, and, for a fused
    `estimate`, the sensors it used (of `channels`, the plant model's) and how far it moved the lengths (in
    sigma)."""
    fused = estimate if estimate is not None and estimate.fused else None
    taut = solution.taut_set
    cables = [{"name": name, "length": length, "span": span, "tension": tension, "taut": (i + 1) in taut}
              for i, (name, length, span, tension) in enumerate(zip(
                  CABLE_NAMES, _floats(solution.lengths), _floats(solution.spans), _floats(solution.tensions)))]
    return {"header": header(stamp), "status": STATUS_NUMBERS[solution.status],
            "tension_state": solution.tension_state, "cables": cables,
            "equilibrium_residual": larger(float(solution.force_residual), float(solution.moment_residual)),
            "solver": solution.method, "iterations": int(solution.iterations),
            "sensors_used": list(channels.sensors_used(fused.used)) if fused is not None else [],
            "length_corrections_sigma": _floats(fused.corrections_sigma) if fused is not None else []}


def collision_alarm(stamp: Stamp, alarm: Alarm) -> Fields:
    clearance = alarm.clearance
    return {"header": header(stamp), "level": int(alarm.level),
            "clearance": NAN if clearance is None else float(clearance.value),
            "closest_point_name": "" if clearance is None else clearance.point_name,
            "closest_point_platform": point(None if clearance is None else clearance.point_platform),
            "closest_point_shaft": point(None if clearance is None else clearance.point_shaft),
            "sync_error_pairs": list(alarm.sync_error_pairs), "sync_errors": alarm.sync_errors.tolist(),
            "reason": alarm.reason}


def model_error(stamp: Stamp, view: ModelView, estimate: Estimate | None, basis: str) -> Fields:
    """The model's estimated error per cable at an estimated sample (the model's `view` of it, its `estimate`),
    what the model alone predicts of the clearance, what the alarm is based on (`basis`) and the sensors left
    out."""
    clearance = view.clearance
    return {"header": header(stamp), "cables": list(CABLE_NAMES), "length_error": _floats(view.length_error),
            "length_error_sigma": _floats(view.length_sigma),
            "length_correction": _floats(estimate.corrections) if estimate is not None else [NAN] * 4,
            "tension_error": _floats(view.pin_error), "tension_error_sigma": _floats(view.pin_sigma),
            "model_clearance": NAN if clearance is None else float(clearance.value),
            "basis": basis,
            "sensors_rejected": list(view.rejected), "sensors_left_out": list(view.left_out)}


def model_parameters(stamp: Stamp, view: ParameterView) -> Fields:
    """The tracked plant parameters: estimate, 1-sigma, in use, the value used, drift."""
    return {"header": header(stamp), "names": list(view.names), "units": list(view.units),
            "values": view.values.tolist(), "sigmas": view.sigmas.tolist(), "in_use": view.in_use.tolist(),
            "values_in_use": view.used.tolist(), "file_values": view.files.tolist(),
            "tolerances": view.tolerances.tolist(), "excited": view.excited.tolist(),
            "drifting": view.drifting.tolist(), "drifting_since": view.since.tolist(), "updated": float(view.stamp)}


def model_residuals(stamp: Stamp, residuals: Residuals) -> Fields:
    return {"header": header(stamp), "channels": list(residuals.channels), "measured": list(residuals.measured),
            "predicted": list(residuals.predicted), "residuals": list(residuals.values), "noise": list(residuals.noise)}
