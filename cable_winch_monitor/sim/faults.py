"""Sensor faults a scenario can script: what a broken sensor reports instead of the truth.

Each fault names a sensor -- a load pin (`tension_cable_1` .. `tension_cable_4`), a winch's
drum encoder (`encoder_cable_1` .. `encoder_cable_4`), the inclinometer (`imu`) or the
position gauge (`position`) -- and acts from `start` for `duration` seconds (to the end of
the run without one):

- `stuck`: the sensor keeps reporting the reading it made when the fault began (a frozen
  load pin, a hung driver), to the bit;
- `offset`: it reports the truth plus a constant (`value` [N] or [m]; for the
  inclinometer `roll` and `pitch` [rad]), as a pin knocked off its zero, an encoder that
  slipped on its drum, or an inclinometer knocked off its mounting;
- `silent`: it reports nothing (a load pin's effort or an encoder's position is NaN, the
  other sensors send no message).

The simulator's truth is unaffected: these are the sensors' lies, for the monitor to find.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..channels import TENSION_CHANNELS
from ..model.plantfile.plant import CABLE_NAMES
from .attitude import quaternion_from_roll_pitch
from .keys import ScenarioError, check_item

ENCODERS = tuple(f"encoder_{name}" for name in CABLE_NAMES)
SENSORS = (*TENSION_CHANNELS, *ENCODERS, "imu", "position")
KINDS = ("stuck", "offset", "silent")


@dataclass(frozen=True)
class Fault:
    sensor: str
    kind: str
    start: float
    duration: float = float("inf")
    value: float = 0.0
    roll: float = 0.0
    pitch: float = 0.0

    def active(self, t: float) -> bool:
        return self.start <= t < self.start + self.duration


class SensorFaults:
    """The scripted faults of a run, applied to the sensors' readings (message field values) as they are made."""

    def __init__(self, faults: Sequence[Mapping[str, Any]]):
        self.faults = [Fault(**fault) for fault in faults]
        self.frozen: dict[int, Any] = {}  # fault index -> the reading it froze

    def pin(self, cable: int, t: float, value: float) -> float:
        """What load pin `cable` (0-based) reports at time `t` for the reading `value` [N]."""
        return self._reading(TENSION_CHANNELS[cable], t, value)

    def encoder(self, cable: int, t: float, value: float) -> float:
        """What the encoder of winch `cable` (0-based) reports at time `t` for the reading `value` [m]."""
        return self._reading(ENCODERS[cable], t, value)

    def _reading(self, name: str, t: float, value: float) -> float:
        for k, fault in enumerate(self.faults):
            if fault.sensor == name and fault.active(t):
                value = self._faulty(k, fault, value)
        return value

    def message(self, sensor: str, t: float, fields: dict[str, Any] | None) -> dict[str, Any] | None:
        """What the inclinometer (`imu`) or position gauge reports at time `t` for the message `fields`."""
        for k, fault in enumerate(self.faults):
            if fault.sensor == sensor and fault.active(t) and fields is not None:
                fields = self._faulty(k, fault, fields)
        return fields

    def _faulty(self, k: int, fault: Fault, reading: Any) -> Any:
        if fault.kind == "silent":
            return float("nan") if isinstance(reading, float) else None
        if fault.kind == "stuck":
            return self.frozen.setdefault(k, reading) if isinstance(reading, float) else \
                {**reading, **{key: value for key, value in self.frozen.setdefault(k, reading).items()
                               if key != "header"}}
        if isinstance(reading, float):
            return reading + fault.value
        if fault.sensor == "imu":
            return _tilted(reading, fault.roll, fault.pitch)
        point = dict(reading["point"])
        point["z"] += fault.value
        return {**reading, "point": point}


def _tilted(fields: dict[str, Any], roll: float, pitch: float) -> dict[str, Any]:
    """An inclinometer message reading `roll` and `pitch` [rad] more than `fields` does."""
    q = fields["orientation"]
    x, y, z, w = q["x"], q["y"], q["z"], q["w"]
    read_roll = float(np.arctan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y)))
    read_pitch = float(np.arcsin(np.clip(2.0 * (w * y - z * x), -1.0, 1.0)))
    orientation = dict(zip("xyzw", quaternion_from_roll_pitch(read_roll + roll, read_pitch + pitch)))
    return {**fields, "orientation": orientation}


def check_fault(item: Any, where: str) -> dict[str, Any]:
    """A scenario's `sensors.faults` item, checked (ValueError naming the key)."""
    spec = {"sensor": str, "kind": str, "start": float, "duration": float, "value": float, "roll": float,
            "pitch": float}
    fault = check_item(item, spec, where, {"duration", "value", "roll", "pitch"})
    if fault["sensor"] not in SENSORS:
        raise ScenarioError(f"key '{where}.sensor' must be one of {', '.join(SENSORS)}, got {fault['sensor']!r}")
    if fault["kind"] not in KINDS:
        raise ScenarioError(f"key '{where}.kind' must be one of {', '.join(KINDS)}, got {fault['kind']!r}")
    if fault.get("duration", 1.0) <= 0.0:
        raise ScenarioError(f"key '{where}.duration' must be positive")
    return fault
