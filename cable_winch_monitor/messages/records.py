"""The monitor's outputs as CDR bytes, and messages of the type store, from the plain field values of messages.fields.

`build` turns any nested mapping of field values into a message of the type store, and
the output records are those mappings encoded straight to the bytes that serialising
the built message gives (bagio.cdr). This module holds no field mapping of its own:
that lives in messages/fields.py, shared with the live node.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from functools import cache
from typing import Any

import numpy as np
from rosbags.interfaces import Nodetype
from rosbags.typesys.store import Typestore

from ..bagio.cdr import Encoder, StackedEncoder, encoder, fixed_encoder
from ..bagio.typestore import knows, typestore
from ..channels import ChannelRegistry
from ..model.statics.geometry import quaternions_from_rotations
from ..model.statics.result import Solution
from ..monitor.pipeline import MonitorOutput
from ..monitor.residuals import Residuals
from . import fields, frames
from .scene import SceneBuilder, SceneState, scene_encoder

MSGS = "cable_winch_monitor_msgs/msg"
POSE, TENSION, ALARM, RESIDUALS = "/platform/pose", "/cables/tension", "/platform/collision_alarm", "/model/residuals"
MODEL_ERROR, PARAMETERS = "/model/error", "/model/parameters"
TF, TF_STATIC, SCENE, OUTLINE = "/tf", "/tf_static", "/platform/scene", "/platform/outline"
DIAGNOSTICS = "/diagnostics"
OUTPUT_TYPES = {POSE: "geometry_msgs/msg/PoseStamped", TENSION: f"{MSGS}/TensionDistribution",
                ALARM: f"{MSGS}/CollisionAlarm", RESIDUALS: f"{MSGS}/ModelResiduals", MODEL_ERROR: f"{MSGS}/ModelError",
                PARAMETERS: f"{MSGS}/ModelParameters",
                TF: "tf2_msgs/msg/TFMessage", TF_STATIC: "tf2_msgs/msg/TFMessage",
                SCENE: "visualization_msgs/msg/MarkerArray", OUTLINE: "visualization_msgs/msg/MarkerArray",
                DIAGNOSTICS: "diagnostic_msgs/msg/DiagnosticArray"}
NUMPY_TYPES = {"bool": np.bool_, "byte": np.uint8, "char": np.uint8, "octet": np.uint8}

Record = tuple[str, str, bytes]  # topic, message type, CDR bytes
# What every per-sample output has alike: its header in `shaft`, the transform's child `platform`.
SAMPLE_FRAMES = {"std_msgs/msg/Header": {"frame_id": fields.FRAME},
                 "geometry_msgs/msg/TransformStamped": {"child_frame_id": frames.PLATFORM_FRAME}}


def build(msgtype: str, values: Mapping[str, Any], store: Typestore | None = None) -> Any:
    """A message of `msgtype` from a nested mapping with a value for every field."""
    store = store or typestore()
    knows(store, msgtype)
    _, field_defs = store.fielddefs[msgtype]
    try:
        return store.types[msgtype](**{name: _value(kind, values[name], store) for name, kind in field_defs})
    except KeyError as error:
        raise KeyError(f"{msgtype}: no value for field {error}") from None


def _value(kind: tuple[Any, Any], value: Any, store: Typestore) -> Any:
    node, argument = kind
    if node == Nodetype.NAME:
        return build(argument, value, store)
    if node in (Nodetype.ARRAY, Nodetype.SEQUENCE):
        (inner, inner_argument), _ = argument
        if inner == Nodetype.NAME:
            return [build(inner_argument, item, store) for item in value]
        base = inner_argument[0]
        return list(value) if base == "string" else np.asarray(value, dtype=NUMPY_TYPES.get(base, base))
    return value


@cache
def sample_encoder(msgtype: str) -> Encoder:
    """The encoder of a per-sample output, its SAMPLE_FRAMES packed once instead of at every sample."""
    return fixed_encoder(msgtype, SAMPLE_FRAMES)


def _record(topic: str, values: Mapping[str, Any], per_sample: bool = True) -> Record:
    """An output (a per-sample one's frames those of SAMPLE_FRAMES, as `fields` and `frames` give them)."""
    msgtype = OUTPUT_TYPES[topic]
    return topic, msgtype, (sample_encoder if per_sample else encoder)(msgtype)(values)


def residual_records(stamp: fields.Stamp, residuals: Residuals | None) -> list[Record]:
    """/model/residuals for a sample's residuals (none if there are none)."""
    return [] if residuals is None else [_record(RESIDUALS, fields.model_residuals(stamp, residuals))]


def pose_records(stamps: Sequence[fields.Stamp], solutions: Sequence[Solution]) -> list[list[Record]]:
    """The pose and /tf of each solved pose (header stamp `stamps`), encoded together (`pose_encoders`)."""
    if not solutions:
        return []
    stamp = np.array(stamps, dtype=np.int64).reshape(-1, 2)
    position = np.array([s.position for s in solutions])
    quaternion = quaternions_from_rotations(np.array([s.rotation for s in solutions]))
    columns = (stamp[:, 0], stamp[:, 1], *position.T, *quaternion.T)
    pose, tf = pose_encoders()
    return [[(POSE, OUTPUT_TYPES[POSE], p), (TF, OUTPUT_TYPES[TF], t)]
            for p, t in zip(pose.encode(*columns), tf.encode(*columns))]


@cache
def pose_encoders() -> tuple[StackedEncoder, StackedEncoder]:
    """The encoders of a solved pose's PoseStamped and /tf from columns: the header stamp (sec, nanosec), the
    position (x, y, z) [m] and the orientation (x, y, z, w), as `fields.pose_stamped` and `frames.platform_tf`
    lay them out."""
    at_rest = ((0, 0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))
    stamp = (("header", "stamp", "sec"), ("header", "stamp", "nanosec"))
    pose = (*stamp, *(("pose", "position", a) for a in "xyz"), *(("pose", "orientation", a) for a in "xyzw"))
    tf = tuple(("transforms", 0, *path) for path in (
        *stamp, *(("transform", "translation", a) for a in "xyz"), *(("transform", "rotation", a) for a in "xyzw")))
    return (StackedEncoder(OUTPUT_TYPES[POSE], fields.pose_stamped(*at_rest), pose),
            StackedEncoder(OUTPUT_TYPES[TF], frames.platform_tf(*at_rest), tf))


def output_records(stamp: fields.Stamp, output: MonitorOutput, channels: ChannelRegistry) -> list[Record]:
    """What the live node publishes for one solved sample, in its order: its `solved_records`, then its residuals
    (if any)."""
    return solved_records([stamp], [output], channels)[0] + residual_records(stamp, output.residuals)


def solved_records(stamps: Sequence[fields.Stamp], outputs: Sequence[MonitorOutput],
                   channels: ChannelRegistry) -> list[list[Record]]:
    """Each solved sample's outputs but its residuals (header stamps `stamps`), in the node's order: pose and /tf
    (only if solved; those of the run encoded together), tension distribution (the sensors of `channels`),
    collision alarm, the model's error (where the sample was estimated), the tracked plant parameters (at the
    first sample of each second of stamps)."""
    posed = [k for k, output in enumerate(outputs) if output.solution.ok]
    out: list[list[Record]] = [[] for _ in outputs]
    for k, records in zip(posed, pose_records([stamps[k] for k in posed], [outputs[k].solution for k in posed])):
        out[k] = records
    for stamp, output, records in zip(stamps, outputs, out):
        records.append(_record(TENSION, fields.tension_distribution(stamp, output.solution, output.estimate, channels)))
        records.append(_record(ALARM, fields.collision_alarm(stamp, output.alarm)))
        if output.model is not None:
            records.append(_record(MODEL_ERROR, fields.model_error(stamp, output)))
            if output.model.parameters_due and output.model.parameters is not None:
                records.append(_record(PARAMETERS, fields.model_parameters(stamp, output.model.parameters)))
    return out


def diagnostics_record(values: Mapping[str, Any]) -> Record:
    """/diagnostics from the field values monitor.diagnostics builds."""
    return _record(DIAGNOSTICS, values, per_sample=False)


def static_records(stamp: fields.Stamp, builder: SceneBuilder) -> list[Record]:
    """What does not change, once per bag (latched): the head-sheave frames and the deck outlines."""
    return [_record(TF_STATIC, frames.static_tf(stamp, builder.plant), per_sample=False),
            _record(OUTLINE, builder.outline(stamp), per_sample=False)]


def scene_cdr(stamp: fields.Stamp, builder: SceneBuilder, state: SceneState) -> bytes:
    """The 3-D scene of one sample as CDR bytes (the live node publishes these raw: building the rclpy
    MarkerArray instead cost four times as much)."""
    return scene_encoder()(builder.draw(stamp, state))


def scene_records(stamp: fields.Stamp, builder: SceneBuilder, state: SceneState) -> list[Record]:
    """The 3-D scene of one sample."""
    return [(SCENE, OUTPUT_TYPES[SCENE], scene_cdr(stamp, builder, state))]
