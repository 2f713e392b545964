"""What the plant's sensors report of the true state: noisy readings at their own, unaligned rates.

- winch encoders and load pins: sensor_msgs/JointState at 10 Hz, on /winch/joint_states
  or one topic per winch; position = paid-out length (1 mm), velocity = payout speed,
  effort = what the load pin at the head sheave reads (150 N);
- inclinometer: sensor_msgs/Imu, roll and pitch (0.01 deg; yaw not measured: covariance
  huge), by default one reading per winch sample, stamped 30-40 ms after it;
- depth gauge: geometry_msgs/PointStamped with z only (x, y NaN), 5 mm at 2 Hz; or a motion
  capture of the platform's position (x, y and z: `position.horizontal`);
- shaft air thermometer: sensor_msgs/Temperature on /shaft/temperature, 0.1 K at 1 Hz.
Every other stream starts at a random phase and has timing jitter, so no two are aligned.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..channels import IMU, JOINT_STATE, POINT, TENSION_CHANNELS
from ..messages.fields import Stamp, header
from ..model.plantfile.plant import CABLE_NAMES
from .attitude import quaternion_from_roll_pitch
from .faults import SensorFaults

NAN = float("nan")
UNKNOWN = -1.0  # covariance[0] of a quantity that is not measured (sensor_msgs convention)
YAW_VARIANCE = 1.0e6  # [rad^2] the inclinometer does not measure yaw
TEMPERATURE = "sensor_msgs/msg/Temperature"


@dataclass(frozen=True)
class Stream:
    """One sensor's messages: topic, type, the cables it reports (joint states) and its sample times [s]."""

    name: str
    topic: str
    msgtype: str
    times: np.ndarray
    cables: tuple[int, ...] = ()


def sample_times(rate: float, duration: float, jitter: float, rng: np.random.Generator) -> np.ndarray:
    """Times in [0, duration) at `rate` from a random phase, with jitter (kept below 0.4 periods: in order)."""
    period = 1.0 / rate
    count = int(np.ceil(duration * rate)) + 1
    times = rng.uniform(0.0, period) + period * np.arange(count)
    times += np.clip(rng.normal(0.0, jitter, count), -0.4 * period, 0.4 * period)
    return times[(times >= 0.0) & (times < duration)]


def lagging_times(times: np.ndarray, low: float, high: float, duration: float,
                  rng: np.random.Generator) -> np.ndarray:
    """One time `low`..`high` [s] after each of `times`, within [0, duration)."""
    lagged = times + rng.uniform(low, high, len(times))
    return lagged[lagged < duration]


def sensor_streams(sensors: Mapping[str, Any], duration: float, rng: np.random.Generator) -> list[Stream]:
    """The enabled streams of the scenario's `sensors` section."""
    joints, jitter = sensors["joint_states"], sensors["jitter"]
    if joints["per_winch"]:
        streams = [Stream(f"winch_{i + 1}", f"/winch_{i + 1}/joint_states", JOINT_STATE,
                          sample_times(joints["rate"], duration, jitter, rng), (i,)) for i in range(4)]
    else:
        streams = [Stream("joint_states", "/winch/joint_states", JOINT_STATE,
                          sample_times(joints["rate"], duration, jitter, rng), tuple(range(4)))]
    imu = sensors["imu"]
    if imu["enabled"]:
        times = sample_times(imu["rate"], duration, jitter, rng) if imu["rate"] is not None else \
            lagging_times(streams[0].times, imu["lag_min"], imu["lag_max"], duration, rng)
        streams.append(Stream("imu", "/platform/imu", IMU, times))
    for name, topic, msgtype in (("position", "/platform/position", POINT),
                                 ("temperature", "/shaft/temperature", TEMPERATURE)):
        if sensors[name]["enabled"]:
            streams.append(Stream(name, topic, msgtype, sample_times(sensors[name]["rate"], duration, jitter, rng)))
    return streams


class Sensors:
    """Noisy readings of the true state, as message field values (None: nothing to report)."""

    def __init__(self, sensors: Mapping[str, Any], rng: np.random.Generator, start_time: float = 0.0):
        self.config, self.rng = sensors, rng
        self.faults = SensorFaults(sensors.get("faults", []))
        self.start_time = start_time  # [s] the stamp of the run's t = 0 (the faults' times are the run's)

    def _time(self, stamp: Stamp) -> float:
        return stamp[0] + stamp[1] * 1e-9 - self.start_time

    def _noisy(self, values: float | np.ndarray, sigma: float) -> np.ndarray:
        return np.asarray(values, dtype=float) + self.rng.normal(0.0, sigma, np.shape(values))

    def joint_state(self, stamp: Stamp, stream: Stream, lengths: np.ndarray, speeds: np.ndarray,
                    channels: Mapping[str, float]) -> dict[str, Any]:
        joints = self.config["joint_states"]
        cables = list(stream.cables)
        tensions = np.array([channels.get(TENSION_CHANNELS[i], NAN) for i in cables])
        effort: np.ndarray | list[float] = self._noisy(tensions, joints["tension_noise"]) if joints["effort"] else []
        t = self._time(stamp)
        effort = [self.faults.pin(i, t, float(value)) for i, value in zip(cables, effort)]
        position = self._noisy(lengths[cables], joints["length_noise"])
        return {"header": header(stamp, ""), "name": [CABLE_NAMES[i] for i in cables],
                "position": [self.faults.encoder(i, t, float(value)) for i, value in zip(cables, position)],
                "velocity": self._noisy(speeds[cables], joints["velocity_noise"]) if joints["velocity"] else [],
                "effort": effort}

    def imu(self, stamp: Stamp, channels: Mapping[str, float]) -> dict[str, Any] | None:
        if "roll" not in channels:
            return None
        sigma = self.config["imu"]["noise"]
        roll, pitch = self._noisy(np.array([channels["roll"], channels["pitch"]]), sigma)
        unknown = [UNKNOWN] + [0.0] * 8
        return {"header": header(stamp, "platform"),
                "orientation": dict(zip("xyzw", quaternion_from_roll_pitch(roll, pitch))),
                "orientation_covariance": np.diag([sigma ** 2, sigma ** 2, YAW_VARIANCE]).ravel(),
                "angular_velocity": {"x": 0.0, "y": 0.0, "z": 0.0}, "angular_velocity_covariance": unknown,
                "linear_acceleration": {"x": 0.0, "y": 0.0, "z": 0.0}, "linear_acceleration_covariance": unknown}

    def position(self, stamp: Stamp, channels: Mapping[str, float]) -> dict[str, Any] | None:
        if "depth" not in channels:
            return None
        sensor = self.config["position"]
        if sensor["horizontal"]:
            x, y, z = self._noisy(np.array([channels["x"], channels["y"], channels["depth"]]), sensor["noise"])
            return {"header": header(stamp, "shaft"), "point": {"x": float(x), "y": float(y), "z": float(z)}}
        depth = float(self._noisy(channels["depth"], sensor["noise"]))
        return {"header": header(stamp, "shaft"), "point": {"x": NAN, "y": NAN, "z": depth}}

    def temperature(self, stamp: Stamp, air: float) -> dict[str, Any]:
        sigma = self.config["temperature"]["noise"]
        return {"header": header(stamp, "shaft"), "temperature": float(self._noisy(air, sigma)),
                "variance": sigma ** 2}

    def reading(self, stamp: Stamp, stream: Stream, lengths: np.ndarray, speeds: np.ndarray,
                channels: Mapping[str, float], air: float) -> dict[str, Any] | None:
        """The message fields of one sample of `stream` from the truth's noise-free `channels`
        (None: nothing to report, e.g. no true equilibrium)."""
        if stream.msgtype == JOINT_STATE:
            return self.joint_state(stamp, stream, lengths, speeds, channels)
        if stream.msgtype == TEMPERATURE:
            return self.temperature(stamp, air)
        if stream.msgtype == IMU:
            return self.faults.message("imu", self._time(stamp), self.imu(stamp, channels))
        return self.faults.message("position", self._time(stamp), self.position(stamp, channels))
