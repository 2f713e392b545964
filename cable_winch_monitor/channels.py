"""Every measured channel, declared once: name, unit, noise key, where it is read, how the model predicts it.

compare, diagnose, fit, the monitor's residuals (`/model/residuals`), the live node and
replay take the channel list of their plant model (`PlantModel.channels`, a ChannelRegistry).
The built-in channels are the load pins (one per cable, read with the winch's joint state),
the inclinometer's roll and pitch and the depth gauge (x, y where measured). A sensor the
package does not know is one more declaration, made in a user's effect module; it joins the
registry of every model whose plant file names the module:

    declare(Channel("cage_load", "N", "cage_load", ("/cage/load",), "std_msgs/msg/Float64", "data",
                    predict=lambda solution, plant, conditions: ...))

A channel may give the derivative of its stacked prediction (`gradient_states`); the
estimator differentiates the others numerically.

Its noise comes from the plant file's `noise:` section under the channel's noise key.
Extra inputs (`Input`) are topics an effect reads besides the channels: a shaft
temperature, a motor current; their values reach the effect in `Conditions.inputs`.
"""
from __future__ import annotations

import math
import re
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np

from .model.conditions import Conditions
from .model.estimator.observations import STATE_SIZE, States, pitch_gradient, pitch_of, roll_gradient, roll_of, unit_gradient
from .model.plantfile.plant import CABLE_NAMES, Plant
from .model.statics.geometry import roll_pitch_of_quaternion, roll_pitch_yaw
from .model.statics.result import Solution

JOINT_STATE, IMU, POINT = "sensor_msgs/msg/JointState", "sensor_msgs/msg/Imu", "geometry_msgs/msg/PointStamped"
WINCH_TOPICS = ("/winch/joint_states", *(f"/winch_{i}/joint_states" for i in range(1, 5)))  # interface.md
LENGTH_NOISE = "length"  # the noise key of the encoders: the lengths are measurements too (effects.estimate)
Prediction = Callable[[Solution, Plant, Conditions], float]
StatesPrediction = Callable[[States], np.ndarray]
StatesGradient = Callable[[States], np.ndarray]  # (n, 10): d prediction / d (position, rotation vector, tensions)
NAN = float("nan")


class ChannelError(ValueError):
    """A channel or input declaration is wrong, or a field cannot be read; the message names it."""


_PATH = re.compile(r"^[A-Za-z_]\w*(\[\d+\])?(\.[A-Za-z_]\w*(\[\d+\])?)*$")


def field_reader(path: str) -> Callable[[Any], float]:
    """A function reading the number at a dotted field path ("point.z", "position[2]", "temperature")
    of a message (rclpy or rosbags: the attribute names are the same); NaN where it is not a number."""
    if not _PATH.match(path):
        raise ChannelError(f"field {path!r} is not a dotted field path such as 'temperature' or 'point.z'")
    steps = [(name, int(index[1:-1]) if index else None) for name, index in re.findall(r"(\w+)(\[\d+\])?", path)]

    def read(message: Any) -> float:
        value = message
        try:
            for name, index in steps:
                value = getattr(value, name)
                if index is not None:
                    value = value[index]
            return float(value)
        except (AttributeError, IndexError, TypeError, ValueError):
            return NAN
    return read


@dataclass(frozen=True)
class Input:
    """An extra input an effect reads: a numeric field of a topic, e.g. Input("temperature",
    "/shaft/temperature", "temperature", "sensor_msgs/msg/Temperature")."""

    name: str
    topic: str
    field: str
    msgtype: str

    @property
    def key(self) -> str:
        """How the value is keyed in Conditions.inputs and named in reports: "topic.field"."""
        return f"{self.topic}.{self.field}"

    def read(self, message: Any) -> float:
        return field_reader(self.field)(message)


@dataclass(frozen=True)
class Channel:
    """One measured number: its name, unit, noise key in the plant file, the topics and message type
    it is read from, the field (in words), how to read it from a message (None: the winch merger
    reads it, aligned with the cable lengths) and how the model predicts it: for one solved state, and
    optionally for stacked states at once (`predict_states`; without it each state is predicted alone)
    with its derivative in the state coordinates (`gradient_states`, observations.Observation's;
    without it the estimator takes forward differences of the model's predictions)."""

    name: str
    unit: str
    noise_key: str
    topics: tuple[str, ...]
    msgtype: str
    field: str
    predict: Prediction
    read: Callable[[Any], float] | None = None
    predict_states: StatesPrediction | None = None
    gradient_states: StatesGradient | None = None

    def __post_init__(self) -> None:
        if self.read is None and self.msgtype != JOINT_STATE:
            object.__setattr__(self, "read", field_reader(self.field))


def _tension(cable: int) -> Prediction:
    def predict(solution: Solution, plant: Plant, conditions: Conditions) -> float:
        assert solution.tensions is not None  # predicted for a solved state
        return float(solution.tensions[cable])
    return predict


def _roll_pitch(which: int) -> Callable[[Any], float]:
    def read(message: Any) -> float:
        q = message.orientation
        return _inclination((q.x, q.y, q.z, q.w))[which]
    return read


@lru_cache(maxsize=2)  # the roll and the pitch channel read each message in turn: its angles are worked out once
def _inclination(quaternion: tuple[float, float, float, float]) -> tuple[float, float]:
    """Roll and pitch [rad] of an inclinometer's orientation (NaN where it holds none)."""
    if not all(math.isfinite(v) for v in quaternion) or math.hypot(*quaternion) < 1e-9:
        return NAN, NAN  # not an orientation
    return roll_pitch_of_quaternion(quaternion)


def _position(axis: int) -> Prediction:
    def predict(solution: Solution, plant: Plant, conditions: Conditions) -> float:
        assert solution.position is not None  # predicted for a solved state
        return float(solution.position[axis])
    return predict


def _attitude(which: int) -> Prediction:
    """Roll (0) or pitch (1) of a solved state [rad]."""
    def predict(solution: Solution, plant: Plant, conditions: Conditions) -> float:
        assert solution.rotation is not None  # predicted for a solved state
        return roll_pitch_yaw(solution.rotation)[which]
    return predict


def _tension_states(cable: int) -> StatesPrediction:
    return lambda states: states.tensions[:, cable]


def _position_states(axis: int) -> StatesPrediction:
    return lambda states: states.position[:, axis]


def _coordinate_gradient(column: int) -> StatesGradient:
    """The derivative of a channel that is state coordinate `column` itself."""
    return lambda states: unit_gradient(len(states), column)


TENSION_CHANNELS = tuple(f"tension_{name}" for name in CABLE_NAMES)  # the load pins, one per cable
BUILTIN = (
    *(Channel(name, "N", "tension", WINCH_TOPICS, JOINT_STATE, f"effort[{cable}]", _tension(i),
              predict_states=_tension_states(i), gradient_states=_coordinate_gradient(6 + i))
      for i, (name, cable) in enumerate(zip(TENSION_CHANNELS, CABLE_NAMES))),
    Channel("roll", "rad", "roll", ("/platform/imu",), IMU, "orientation (roll)",
            _attitude(0), _roll_pitch(0), roll_of, roll_gradient),
    Channel("pitch", "rad", "pitch", ("/platform/imu",), IMU, "orientation (pitch)",
            _attitude(1), _roll_pitch(1), pitch_of, pitch_gradient),
    *(Channel(name, "m", name, ("/platform/position",), POINT, f"point.{axis}", _position(k),
              predict_states=_position_states(k), gradient_states=_coordinate_gradient(k))
      for k, (name, axis) in enumerate(zip(("x", "y", "depth"), "xyz"))),
)


_BUILTIN_BY_NAME = {c.name: c for c in BUILTIN}


def _checked(channel: Channel) -> Channel:
    if not channel.topics or not all(t.startswith("/") for t in channel.topics):
        raise ChannelError(f"channel '{channel.name}': topics must be absolute ROS topic names, got {channel.topics}")
    return channel


class ChannelRegistry:
    """The channels a plant model knows: the built-ins, then those its user modules declare (a user's sensors),
    in order, with what every sample asks of them worked out once. Made whole, never changed: a model with
    other modules has a registry of its own (effects.registry.Registry)."""

    def __init__(self, declared: Iterable[Channel] = ()):
        self.channels: dict[str, Channel] = dict(_BUILTIN_BY_NAME)
        for channel in declared:
            known = self.channels.get(channel.name)
            if known is not None and (known.topics, known.msgtype) != (channel.topics, channel.msgtype):
                raise ChannelError(f"channel '{channel.name}' is declared twice, on {known.topics} and "
                                   f"{channel.topics}")
            self.channels[channel.name] = _checked(channel)
        self.user = any(c is not _BUILTIN_BY_NAME.get(name) for name, c in self.channels.items())
        self.sensors = {name: name if name in TENSION_CHANNELS else c.topics[0] for name, c in self.channels.items()}
        self._sensors_used: dict[tuple[str, ...], tuple[str, ...]] = {}
        self.by_topic: dict[str, tuple[Channel, ...]] = {}
        for channel in self.channels.values():
            if channel.read is not None:
                for topic in channel.topics:
                    self.by_topic[topic] = (*self.by_topic.get(topic, ()), channel)

    def declared(self) -> tuple[Channel, ...]:
        """Every channel: the built-ins, then those user modules declared, in order."""
        return tuple(self.channels.values())

    def names(self) -> tuple[str, ...]:
        return tuple(self.channels)

    def get(self, name: str) -> Channel:
        return self.channels[name]

    def sensor_of(self, channel: str) -> str:
        """The sensor a channel belongs to: a load pin is its own, any other channel its topic's instrument (a
        name not declared: its own)."""
        return self.sensors.get(channel, channel)

    def sensors_used(self, used: tuple[str, ...]) -> tuple[str, ...]:
        """The sensors of these channels (an estimate's `used`), in the channels' declared order; worked out
        once for each set of channels (every fused sample asks; a recording uses a few sets)."""
        sensors = self._sensors_used.get(used)
        if sensors is None:
            names = set(used)
            ordered = [name for name in self.channels if name in names] + sorted(names - set(self.channels))
            sensors = self._sensors_used[used] = tuple(dict.fromkeys(map(self.sensor_of, ordered)))
        return sensors

    def noise_keys(self) -> tuple[str, ...]:
        """Every key a plant file's `noise:` section may give: the encoders', then each channel's."""
        return tuple(dict.fromkeys((LENGTH_NOISE, *(c.noise_key for c in self.channels.values()))))

    def topic_types(self) -> dict[str, str]:
        """Every topic a channel is read from, with its message type."""
        return {topic: c.msgtype for c in self.channels.values() for topic in c.topics}

    def on_topic(self, topic: str) -> tuple[Channel, ...]:
        """The channels read from messages of `topic` by their own reader (not the winch merger's)."""
        return self.by_topic.get(topic, ())

    def predicted(self, solution: Solution, plant: Plant, conditions: Conditions) -> dict[str, float]:
        """What every channel reads for a solved state under the plain model (no measurement effects):
        load pins the tension (weightless ropes), the inclinometer the platform's roll and pitch, the
        depth gauge the platform origin."""
        return {name: channel.predict(solution, plant, conditions) for name, channel in self.channels.items()}

    def predicted_states(self, states: States, conditions: Iterable[Conditions]) -> dict[str, np.ndarray]:
        """`predicted` for stacked states (conditions[k] is state k's): arrays (n,), one per channel."""
        out: dict[str, np.ndarray] = {}
        alone = [c for c in self.channels.values() if c.predict_states is None]
        solutions = states.solutions() if alone else []
        for name, channel in self.channels.items():
            if channel.predict_states is not None:
                out[name] = np.array(channel.predict_states(states), dtype=float)
            else:
                out[name] = np.array([channel.predict(s, states.plant, at) for s, at in zip(solutions, conditions)],
                                     float)
        return out

    def differentiable(self) -> bool:
        """Every channel gives the derivative of its stacked prediction (`gradient_states`)."""
        return all(c.gradient_states is not None for c in self.channels.values())

    def gradients_states(self, states: States) -> dict[str, np.ndarray] | None:
        """The derivative (n, 10) of every channel's `predicted_states`, one array per channel; None where a
        channel declares none."""
        out = {}
        for name, channel in self.channels.items():
            if channel.gradient_states is None:
                return None
            out[name] = np.asarray(channel.gradient_states(states), dtype=float).reshape(len(states), STATE_SIZE)
        return out


BUILTIN_CHANNELS = ChannelRegistry()  # the built-ins alone: a plant model without user modules
_importing: list[list[Channel]] = []  # what the user modules being imported declare (`declared_by_import`)


@contextmanager
def declared_by_import() -> Iterator[list[Channel]]:
    """The channels a user module declares while it is imported (effects.registry imports it in this)."""
    declared: list[Channel] = []
    _importing.append(declared)
    try:
        yield declared
    finally:
        _importing.pop()


def declare(channel: Channel) -> Channel:
    """Declare a user's sensor in an effect module: the channel joins the registry of each plant model whose
    file lists the module (`plant.effect_modules`, or --effect-module). A script that builds its own registry
    passes the channel to `ChannelRegistry([...])` instead."""
    if not _importing:
        raise ChannelError(f"channel '{channel.name}': declare() is for an effect module, imported as a plant "
                           "file's effect_modules (or --effect-module) name it; a script makes its own "
                           "registry, ChannelRegistry([channel])")
    _importing[-1].append(_checked(channel))
    return channel
