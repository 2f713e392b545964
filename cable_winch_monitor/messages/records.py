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

from ..bagio.cdr import Encoder, encoder, fixed_encoder
from ..bagio.typestore import knows, typestore
from ..channels import ChannelRegistry
from ..monitor.pipeline import MonitorOutput
from ..monitor.residuals import Residuals
from . import fields, frames, stacked
from .outputs import (
    ALARM,
    DIAGNOSTICS,
    MODEL_ERROR,
    OUTLINE,
    OUTPUT_TYPES,
    PARAMETERS,
    POSE,
    RESIDUALS,
    SCENE,
    TENSION,
    TF,
    TF_STATIC,
    Record,
)
from .scene import SceneBuilder, SceneState, scene_encoder

NUMPY_TYPES = {"bool": np.bool_, "byte": np.uint8, "char": np.uint8, "octet": np.uint8}

STACKED_FROM = 10  # samples in a run from which they are encoded together (bench.twins: below, a message at a time is faster)
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
    """/model/residuals for one message's or sample's residuals (none if there are none): a message at a time, by
    the compiled encoder (numpy's calls for one, `stacked.residual_records`, cost three times as much); replay
    encodes a window's samples' together."""
    return [] if residuals is None else [_record(RESIDUALS, fields.model_residuals(stamp, residuals))]


def output_records(stamp: fields.Stamp, output: MonitorOutput, channels: ChannelRegistry) -> list[Record]:
    """What the live node publishes for one solved sample, in its order: its `solved_records`, then its residuals
    (if any)."""
    return solved_records([stamp], [output], channels)[0] + residual_records(stamp, output.residuals)


def solved_records(stamps: Sequence[fields.Stamp], outputs: Sequence[MonitorOutput],
                   channels: ChannelRegistry) -> list[list[Record]]:
    """Each solved sample's outputs but its residuals (header stamps `stamps`), in the node's order: pose and /tf
    (only if solved), tension distribution (the sensors of `channels`), collision alarm, the model's error (where
    the sample was estimated), the tracked plant parameters (at the first sample of each second of stamps). A run
    of STACKED_FROM samples or more is encoded together (`run_records`), fewer a message at a time
    (`sample_records`: the node's sample, or the few it takes together)."""
    if len(outputs) < STACKED_FROM:
        return [sample_records(stamp, output, channels) for stamp, output in zip(stamps, outputs)]
    return run_records(stamps, outputs, channels)


def run_records(stamps: Sequence[fields.Stamp], outputs: Sequence[MonitorOutput],
                channels: ChannelRegistry) -> list[list[Record]]:
    """`solved_records` of a run of samples, encoded together but the tracked parameters (stacked.py)."""
    posed = [k for k, output in enumerate(outputs) if output.solution.ok]
    estimated = [k for k, output in enumerate(outputs) if output.model is not None]
    out: list[list[Record]] = [[] for _ in outputs]
    for k, records in zip(posed, stacked.pose_records([stamps[k] for k in posed], [outputs[k].solution for k in posed])):
        out[k] = records
    for records, tension, alarm in zip(out, stacked.tension_records(stamps, outputs, channels),
                                       stacked.alarm_records(stamps, outputs)):
        records += (tension, alarm)
    errors = stacked.model_error_records([stamps[k] for k in estimated], [outputs[k] for k in estimated])
    for k, error in zip(estimated, errors):
        out[k] += [error, *_parameters(stamps[k], outputs[k])]
    return out


def sample_records(stamp: fields.Stamp, output: MonitorOutput, channels: ChannelRegistry) -> list[Record]:
    """`solved_records` of one sample, a message at a time: each laid out by `fields` and `frames`, encoded by
    the compiled encoders (a tenth of the stacked encoders' numpy calls for one sample: bench.twins)."""
    solution = output.solution
    records = []
    if solution.ok:
        assert solution.position is not None and solution.quaternion is not None  # solved: a pose
        position, quaternion = solution.position.tolist(), solution.quaternion.tolist()
        records += [_record(POSE, fields.pose_stamped(stamp, position, quaternion)),
                    _record(TF, frames.platform_tf(stamp, position, quaternion))]
    records += [_record(TENSION, fields.tension_distribution(stamp, solution, output.estimate, channels)),
                _record(ALARM, fields.collision_alarm(stamp, output.alarm))]
    if output.model is not None:
        records += [_record(MODEL_ERROR, fields.model_error(stamp, output)), *_parameters(stamp, output)]
    return records


def _parameters(stamp: fields.Stamp, output: MonitorOutput) -> list[Record]:
    """The tracked plant parameters where the sample publishes them."""
    view = output.model
    if view is None or not view.parameters_due or view.parameters is None:
        return []
    return [_record(PARAMETERS, fields.model_parameters(stamp, view.parameters))]


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
