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
from ..monitor.judged import Judged, MonitorOutput
from ..monitor.residuals import Residuals
from ..monitor.tracking import ParameterView
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
    """What the live node publishes for one solved sample, in its order: its `sample_records`, then its residuals
    (if any)."""
    return sample_records(stamp, output, channels) + residual_records(stamp, output.residuals)


def solved_records(stamps: Sequence[fields.Stamp], judged: Judged, channels: ChannelRegistry) -> list[list[Record]]:
    """Each sample's outputs of a judged run but its residuals (header stamps `stamps`), in the node's order: pose
    and /tf (only if solved), tension distribution (the sensors of `channels`), collision alarm, the model's error
    (where the sample was estimated), the tracked plant parameters (at the first sample of each second of
    stamps). A run of STACKED_FROM samples or more is encoded together (`run_records`), fewer a message at a time
    (`sample_records`)."""
    if len(judged) < STACKED_FROM:
        return [sample_records(stamp, judged.output(k), channels) for k, stamp in enumerate(stamps)]
    return run_records(stamps, judged, channels)


def run_records(stamps: Sequence[fields.Stamp], judged: Judged, channels: ChannelRegistry) -> list[list[Record]]:
    """`solved_records` of a run of samples, encoded together from its columns but the tracked parameters
    (stacked.py)."""
    solved = judged.solved
    solutions = solved.solutions
    posed = [k for k, solution in enumerate(solutions) if solution.ok]
    out: list[list[Record]] = [[] for _ in solutions]
    for k, records in zip(posed, stacked.pose_records([stamps[k] for k in posed], [solutions[k] for k in posed])):
        out[k] = records
    for records, tension, alarm in zip(out, stacked.tension_records(stamps, solutions, solved.estimates, channels),
                                       stacked.alarm_records(stamps, judged.alarms)):
        records += (tension, alarm)
    views = solved.views
    if views is not None:
        errors = stacked.model_error_records(stamps, views, [basis.text for basis in judged.bases], solved.estimates)
        for records, stamp, error, parameters, due in zip(out, stamps, errors, views.parameters, views.parameters_due):
            records += [error, *_parameters(stamp, parameters if due else None)]
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
    view = output.model
    if view is not None:
        basis = output.basis.text if output.basis is not None else ""
        records += [_record(MODEL_ERROR, fields.model_error(stamp, view, output.estimate, basis)),
                    *_parameters(stamp, view.parameters if view.parameters_due else None)]
    return records


def _parameters(stamp: fields.Stamp, parameters: ParameterView | None) -> list[Record]:
    """The tracked plant parameters where the sample publishes them (None: it does not)."""
    return [] if parameters is None else [_record(PARAMETERS, fields.model_parameters(stamp, parameters))]


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
