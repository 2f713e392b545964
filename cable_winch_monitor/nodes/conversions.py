"""rclpy messages from the monitor's plain field values, and the service's request and answer.

What goes into which field is decided once, in messages/fields.py (shared with bag
replay); this module only turns those nested values into rclpy message objects.
"""
from __future__ import annotations

import importlib
from collections.abc import Mapping, Sequence
from functools import cache
from typing import Any

from rosidl_parser.definition import AbstractNestedType, NamespacedType

from cable_winch_monitor_msgs.srv import CheckCableLengths

from ..messages import fields
from ..model.plantfile.plant import CABLE_NAMES
from ..model.statics.result import Solution
from ..monitor.alarm import Alarm


@cache
def _message_fields(kind: type) -> dict[str, tuple[type, bool]]:
    """Fields of a message type that hold messages: name -> (message type, is a sequence)."""
    nested = {}
    # a rosidl-generated message class: its field listing is made at build time, out of mypy's sight
    for name, slot in zip(kind.get_fields_and_field_types(), kind.SLOT_TYPES):  # type: ignore[attr-defined]
        sequence = isinstance(slot, AbstractNestedType)
        base = slot.value_type if sequence else slot
        if isinstance(base, NamespacedType):
            nested[name] = (getattr(importlib.import_module(".".join(base.namespaces)), base.name), sequence)
    return nested


def build(kind: type, values: Mapping[str, Any]) -> Any:
    """A message of type `kind` from nested field values (messages.fields layout)."""
    nested = _message_fields(kind)
    arguments = {}
    for name, value in values.items():
        if name in nested:
            inner, sequence = nested[name]
            value = [build(inner, item) for item in value] if sequence else build(inner, value)
        arguments[name] = value
    return kind(**arguments)


def requested_lengths(names: Sequence[str], lengths: Sequence[float]) -> tuple[list[float] | None, str]:
    """Service request -> lengths of cable_1..cable_4, or None and why the request is malformed.

    Values are passed on unchecked (NaN, negative): the solver's validation words those.
    """
    if not names:
        if len(lengths) != len(CABLE_NAMES):
            return None, f"need {len(CABLE_NAMES)} lengths (cable_1..cable_4 in order), got {len(lengths)}"
        return [float(v) for v in lengths], ""
    if len(names) != len(lengths):
        return None, f"{len(names)} names but {len(lengths)} lengths"
    if sorted(names) != sorted(CABLE_NAMES):
        return None, f"names must be each of {', '.join(CABLE_NAMES)} once, got {', '.join(names)}"
    by_name = dict(zip(names, lengths))
    return [float(by_name[name]) for name in CABLE_NAMES], ""


def check_response(stamp: fields.Stamp, solution: Solution, alarm: Alarm) -> CheckCableLengths.Response:
    """The service's answer: accepted only for a determinate pose (SOLVED)."""
    return build(CheckCableLengths.Response, {
        "accepted": solution.ok, "message": f"{solution.tension_state}: {solution.message}",
        "pose": fields.pose(solution), "tension": fields.tension_distribution(stamp, solution),
        "alarm": fields.collision_alarm(stamp, alarm)})


def rejected_response(message: str) -> CheckCableLengths.Response:
    return CheckCableLengths.Response(accepted=False, message=message)


def message_class(msgtype: str) -> type:
    """The rclpy message class of a type name such as "sensor_msgs/msg/Temperature"."""
    package, kind, name = msgtype.split("/")
    return getattr(importlib.import_module(f"{package}.{kind}"), name)
