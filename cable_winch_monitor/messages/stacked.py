"""A run of samples' outputs encoded together: the pose, /tf, tension distribution, alarm, model error, residuals.

Each message of a run whose strings are as long in bytes (and whose sequences are as long) is a
copy of one template's bytes with its numbers and strings written in as numpy columns
(`bagio.cdr.StackedEncoder`, one per such shape, kept). The messages are laid out as
`fields.pose_stamped`, `frames.platform_tf`, `fields.tension_distribution`,
`fields.collision_alarm`, `fields.model_error` and `fields.model_residuals` lay out one sample's,
which the node's few samples and its service take (`records.sample_records`: numpy's calls cost
more than they save on a run of fewer than `records.STACKED_FROM`); `test/messages/test_stacked.py`
and `test/replay/test_replay_bytes.py` hold the two to the same bytes, and to rosbags'. Replay
encodes its windows so: the second process's stages on recording (d) take 7 % less time than a
message at a time, the first process (a window's residuals) 9 % less CPU.
"""
from __future__ import annotations

from collections.abc import Callable, Hashable, Sequence
from functools import cache, lru_cache
from typing import Any

import numpy as np

from ..bagio.cdr import FieldPath, StackedEncoder
from ..channels import ChannelRegistry
from ..model.estimator import Estimate
from ..model.plantfile.plant import CABLE_NAMES
from ..model.statics.geometry import quaternions_from_rotations
from ..model.statics.result import Solution
from ..monitor.alarm import SYNC_PAIR_NAMES, Alarms
from ..monitor.judged import ModelViews
from ..monitor.residuals import Residuals
from . import fields, frames
from .outputs import ALARM, MODEL_ERROR, OUTPUT_TYPES, POSE, RESIDUALS, TENSION, TF, Record

NAN = float("nan")
STAMP: tuple[FieldPath, ...] = (("header", "stamp", "sec"), ("header", "stamp", "nanosec"))


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
    pose = (*STAMP, *(("pose", "position", a) for a in "xyz"), *(("pose", "orientation", a) for a in "xyzw"))
    tf = tuple(("transforms", 0, *path) for path in (
        *STAMP, *(("transform", "translation", a) for a in "xyz"), *(("transform", "rotation", a) for a in "xyzw")))
    return (StackedEncoder(OUTPUT_TYPES[POSE], fields.pose_stamped(*at_rest), pose),
            StackedEncoder(OUTPUT_TYPES[TF], frames.platform_tf(*at_rest), tf))


def tension_records(stamps: Sequence[fields.Stamp], solutions: Sequence[Solution],
                    estimates: Sequence[Estimate | None], channels: ChannelRegistry) -> list[Record]:
    """Each sample's tension distribution (its fused estimate's sensors used, those of `channels`)."""
    fused = [estimate if estimate is not None and estimate.fused else None for estimate in estimates]
    states = [solution.tension_state.encode() for solution in solutions]
    methods = [solution.method.encode() for solution in solutions]
    encoded: dict[tuple[str, ...], tuple[bytes, ...]] = {}  # the sensors of each set of channels used (a few sets)
    for estimate in fused:
        if estimate is not None and estimate.used not in encoded:
            encoded[estimate.used] = tuple(name.encode() for name in channels.sensors_used(estimate.used))
    used = [() if estimate is None else encoded[estimate.used] for estimate in fused]
    shapes = [(len(state), len(method), tuple(map(len, names)), estimate is not None)
              for state, method, names, estimate in zip(states, methods, used, fused)]
    stamp = np.array(stamps, dtype=np.int64).reshape(-1, 2)
    lengths = _rows([solution.lengths for solution in solutions])
    spans = _rows([solution.spans for solution in solutions])
    tensions = _rows([solution.tensions for solution in solutions])
    taut = np.array([[i in s.taut_set for i in (1, 2, 3, 4)] for s in solutions], dtype=bool).reshape(-1, 4)
    status = np.array([fields.STATUS_NUMBERS[s.status] for s in solutions], dtype=np.uint8)
    balance = np.array([fields.larger(float(s.force_residual), float(s.moment_residual)) for s in solutions])
    iterations = np.array([int(s.iterations) for s in solutions], dtype=np.int64)
    corrections = _rows([None if estimate is None else estimate.corrections_sigma for estimate in fused])

    def columns(shape: Any, rows: list[int]) -> list[Any]:
        cables = [column[rows, i] for i in range(4) for column in (lengths, spans, tensions, taut)]
        return [stamp[rows, 0], stamp[rows, 1], status[rows], [states[k] for k in rows], *cables, balance[rows],
                [methods[k] for k in rows], iterations[rows], *([used[k][j] for k in rows] for j in range(len(shape[2]))),
                *(corrections[rows, i] for i in range(4 if shape[3] else 0))]

    return _encoded(TENSION, shapes, tension_encoder, columns)


@lru_cache(maxsize=256)
def tension_encoder(shape: tuple[int, int, tuple[int, ...], bool]) -> StackedEncoder:
    """Tension distributions whose tension state, solver and sensors used are as long in bytes as `shape` says,
    with a fused estimate's length corrections where it says so."""
    state, method, used, fused = shape
    template = {"header": fields.header((0, 0)), "status": 0, "tension_state": "a" * state,
                "cables": [{"name": name, "length": 0.0, "span": 0.0, "tension": 0.0, "taut": False}
                           for name in CABLE_NAMES],
                "equilibrium_residual": 0.0, "solver": "a" * method, "iterations": 0,
                "sensors_used": ["a" * size for size in used], "length_corrections_sigma": [0.0] * (4 if fused else 0)}
    paths = [*STAMP, ("status",), ("tension_state",),
             *(("cables", i, name) for i in range(4) for name in ("length", "span", "tension", "taut")),
             ("equilibrium_residual",), ("solver",), ("iterations",), *(("sensors_used", j) for j in range(len(used))),
             *(("length_corrections_sigma", i) for i in range(4 if fused else 0))]
    return StackedEncoder(OUTPUT_TYPES[TENSION], template, paths)


def alarm_records(stamps: Sequence[fields.Stamp], alarms: Alarms) -> list[Record]:
    """Each sample's collision alarm."""
    clearances = alarms.clearances
    names = [b"" if c is None else c.point_name.encode() for c in clearances]
    reasons = [reason.encode() for reason in alarms.reasons]
    shapes = [(len(name), len(reason), SYNC_PAIR_NAMES) for name, reason in zip(names, reasons)]
    stamp = np.array(stamps, dtype=np.int64).reshape(-1, 2)
    level = np.array(alarms.levels, dtype=np.uint8)
    value = np.array([NAN if c is None else float(c.value) for c in clearances])
    platform = _rows([None if c is None else c.point_platform for c in clearances], 3)
    shaft = _rows([None if c is None else c.point_shaft for c in clearances], 3)
    errors = np.asarray(alarms.sync_errors, dtype=float).reshape(len(names), len(SYNC_PAIR_NAMES))

    def columns(shape: Any, rows: list[int]) -> list[Any]:
        return [stamp[rows, 0], stamp[rows, 1], level[rows], value[rows], [names[k] for k in rows],
                *(platform[rows, i] for i in range(3)), *(shaft[rows, i] for i in range(3)), *errors[rows].T,
                [reasons[k] for k in rows]]

    return _encoded(ALARM, shapes, alarm_encoder, columns)


@lru_cache(maxsize=256)
def alarm_encoder(shape: tuple[int, int, tuple[str, ...]]) -> StackedEncoder:
    """Collision alarms whose closest point's name and reason are as long in bytes as `shape` says, with its
    sync error pairs."""
    name, reason, pairs = shape
    template = {"header": fields.header((0, 0)), "level": 0, "clearance": 0.0, "closest_point_name": "a" * name,
                "closest_point_platform": fields.point(None), "closest_point_shaft": fields.point(None),
                "sync_error_pairs": list(pairs), "sync_errors": [0.0] * len(pairs), "reason": "a" * reason}
    paths = [*STAMP, ("level",), ("clearance",), ("closest_point_name",),
             *(("closest_point_platform", a) for a in "xyz"), *(("closest_point_shaft", a) for a in "xyz"),
             *(("sync_errors", i) for i in range(len(pairs))), ("reason",)]
    return StackedEncoder(OUTPUT_TYPES[ALARM], template, paths)


MODEL_ERROR_ROWS = ("length_error", "length_error_sigma", "length_correction", "tension_error", "tension_error_sigma")


def model_error_records(stamps: Sequence[fields.Stamp], views: ModelViews, bases: Sequence[str],
                        estimates: Sequence[Estimate | None]) -> list[Record]:
    """The model's error at each estimated sample: its view (`views`), what its alarm is based on (`bases`), its
    estimate's length corrections."""
    texts = [basis.encode() for basis in bases]
    rejected = [tuple(sensor.encode() for sensor in sensors) for sensors in views.rejected]
    left_out = [tuple(sensor.encode() for sensor in sensors) for sensors in views.left_out]
    shapes = [(len(basis), tuple(map(len, r)), tuple(map(len, o))) for basis, r, o in zip(texts, rejected, left_out)]
    stamp = np.array(stamps, dtype=np.int64).reshape(-1, 2)
    values = {"length_error": _columns(views.length_error), "length_error_sigma": _columns(views.length_sigma),
              "length_correction": _rows([None if e is None else e.corrections for e in estimates]),
              "tension_error": _columns(views.pin_error), "tension_error_sigma": _columns(views.pin_sigma)}
    clearance = np.array([NAN if c is None else float(c.value) for c in views.clearances])

    def columns(shape: Any, rows: list[int]) -> list[Any]:
        return [stamp[rows, 0], stamp[rows, 1], *(values[name][rows, i] for name in MODEL_ERROR_ROWS for i in range(4)),
                clearance[rows], [texts[k] for k in rows], *([rejected[k][j] for k in rows] for j in range(len(shape[1]))),
                *([left_out[k][j] for k in rows] for j in range(len(shape[2])))]

    return _encoded(MODEL_ERROR, shapes, model_error_encoder, columns)


@lru_cache(maxsize=256)
def model_error_encoder(shape: tuple[int, tuple[int, ...], tuple[int, ...]]) -> StackedEncoder:
    """The model's errors whose basis and sensors rejected and left out are as long in bytes as `shape` says."""
    basis, rejected, left_out = shape
    template = {"header": fields.header((0, 0)), "cables": list(CABLE_NAMES),
                **{name: [0.0] * 4 for name in MODEL_ERROR_ROWS}, "model_clearance": 0.0, "basis": "a" * basis,
                "sensors_rejected": ["a" * size for size in rejected], "sensors_left_out": ["a" * size for size in left_out]}
    paths = [*STAMP, *((name, i) for name in MODEL_ERROR_ROWS for i in range(4)), ("model_clearance",), ("basis",),
             *(("sensors_rejected", j) for j in range(len(rejected))),
             *(("sensors_left_out", j) for j in range(len(left_out)))]
    return StackedEncoder(OUTPUT_TYPES[MODEL_ERROR], template, paths)


RESIDUAL_ROWS = ("measured", "predicted", "residuals", "noise")


def residual_records(stamps: Sequence[fields.Stamp], residuals: Sequence[Residuals]) -> list[Record]:
    """The residuals of each message or sample (header stamps `stamps`)."""
    shapes = [r.channels for r in residuals]
    stamp = np.array(stamps, dtype=np.int64).reshape(-1, 2)

    def columns(shape: Any, rows: list[int]) -> list[Any]:
        measured = np.array([residuals[k].measured for k in rows], dtype=float).reshape(len(rows), len(shape))
        predicted = np.array([residuals[k].predicted for k in rows], dtype=float).reshape(len(rows), len(shape))
        noise = np.array([residuals[k].noise for k in rows], dtype=float).reshape(len(rows), len(shape))
        return [stamp[rows, 0], stamp[rows, 1], *measured.T, *predicted.T, *(measured - predicted).T, *noise.T]

    return _encoded(RESIDUALS, shapes, residuals_encoder, columns)


@lru_cache(maxsize=256)
def residuals_encoder(channels: tuple[str, ...]) -> StackedEncoder:
    """The residuals of the channels `channels`."""
    count = len(channels)
    template = {"header": fields.header((0, 0)), "channels": list(channels),
                **{name: [0.0] * count for name in RESIDUAL_ROWS}}
    paths = [*STAMP, *((name, i) for name in RESIDUAL_ROWS for i in range(count))]
    return StackedEncoder(OUTPUT_TYPES[RESIDUALS], template, paths)


def _rows(values: Sequence[Any], width: int = 4) -> np.ndarray:
    """(n, width) floats of per-sample arrays, NaN where a sample has none (None)."""
    missing = (NAN,) * width
    return np.array([missing if v is None else v for v in values], dtype=float).reshape(-1, width)


def _columns(values: np.ndarray) -> np.ndarray:
    """(n, 4) floats of a run's column."""
    return np.asarray(values, dtype=float).reshape(-1, 4)


def _encoded(topic: str, shapes: Sequence[Hashable], encoder_of: Callable[[Any], StackedEncoder],
             columns_of: Callable[[Any, list[int]], list[Any]]) -> list[Record]:
    """The messages of `topic`, one a sample: the samples of each shape encoded together by its encoder, from
    their columns."""
    groups: dict[Hashable, list[int]] = {}
    for k, shape in enumerate(shapes):
        groups.setdefault(shape, []).append(k)
    out: list[Record | None] = [None] * len(shapes)
    msgtype = OUTPUT_TYPES[topic]
    for shape, rows in groups.items():
        for k, data in zip(rows, encoder_of(shape).encode(*columns_of(shape, rows))):
            out[k] = (topic, msgtype, data)
    return out  # type: ignore[return-value]  # every sample is in one shape's rows
