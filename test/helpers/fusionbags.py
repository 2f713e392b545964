"""Recordings of a root-found truth (`root_truth`), sensed as the plant's sensors sense it.

Encoders 1 mm, load pins 150 N, inclinometer 0.01 deg stamped 30-40 ms after the winches,
depth gauge 5 mm at 2 Hz; the rigid lowering's lag events slacken a rope and move the
load share. Items are bag messages (topic, msgtype, message, log_time), written to a
real bag by `write_bag`.
"""
from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from types import SimpleNamespace

import numpy as np
from root_truth import elastic_truth, slack_truth, weak_mode_truth
from scipy.spatial.transform import Rotation

from cable_winch_monitor import channels
from cable_winch_monitor.bagio.cdr import encoder
from cable_winch_monitor.bagio.writer import BagWriter
from cable_winch_monitor.messages import fields
from cable_winch_monitor.model.plantfile.plant import CABLE_NAMES

NOISE = {"length": 1e-3, "tension": 150.0, "roll": np.radians(0.01), "pitch": np.radians(0.01), "depth": 5e-3}
RATE, SPEED = 10.0, 0.4  # [Hz] winches, [m/s] lowering


def noisy(plant, **changes):
    return plant.with_changes(noise={**plant.noise, **NOISE, **changes})


def header(t: float) -> SimpleNamespace:
    sec = int(t)
    return SimpleNamespace(stamp=SimpleNamespace(sec=sec, nanosec=int(round((t - sec) * 1e9))), frame_id="shaft")


def item(topic: str, msgtype: str, message: SimpleNamespace, t: float) -> SimpleNamespace:
    return SimpleNamespace(topic=topic, msgtype=msgtype, message=message, log_time=int(round(t * 1e9)))


def lowering_truths(plant, count: int, seed: int, speed: float = SPEED, lags: bool = True) -> list:
    """A lowering from 20 m: four taut ropes sharing the load as the winches' drift has it, and lag
    events where one winch pays out 2-6 cm too much and its rope goes slack."""
    rng = np.random.default_rng(seed)
    truths, offsets, share = [], np.zeros(3), 0.0
    for k in range(count):
        payout = 20.0 + speed * k / RATE
        offsets = np.clip(offsets + rng.normal(0.0, 2e-4, 3), -0.02, 0.02)
        share = float(np.clip(share + rng.normal(0.0, 400.0), -25e3, 25e3))
        lag = lags and (k // 40) % 3 == 1  # every third stretch of 4 s, a lag event
        truth = None
        if lag:
            slack = 1 + (k // 120) % 3  # ropes 2, 3 (rope 1 carries the offset centre of gravity)
            lengths = payout + np.append(offsets, 0.0)
            truth = slack_truth(plant, lengths, slack, 0.02 + 0.04 * ((k % 40) / 40.0))
        if truth is None:
            truth = weak_mode_truth(plant, payout, offsets, share)
        assert truth is not None
        truths.append(truth)
    return truths


def elastic_lowering_truths(plant, count: int, seed: int, start: float, speed: float, ea: float,
                            weight: float) -> list:
    """A lowering from `start` on elastic ropes (EA [N], weight [N/m]) whose winches drift by up to 2 cm."""
    rng = np.random.default_rng(seed)
    truths, offsets = [], np.zeros(4)
    for k in range(count):
        offsets = np.clip(offsets + rng.normal(0.0, 2e-4, 4), -0.02, 0.02)
        truth = elastic_truth(plant, start + speed * k / RATE + offsets, ea, weight)
        assert truth is not None
        truths.append(truth)
    return truths


def sensed(truths, seed: int, pin_fault: tuple[object, int, float] | None = None, fault_until: int | None = None,
           reported: Callable[[np.ndarray], np.ndarray] = lambda lengths: lengths, speed: float = SPEED,
           pins: Callable[[object], np.ndarray] = lambda truth: truth.tensions) -> list[SimpleNamespace]:
    """Bag items of the truths: a merged winch message per sample, the inclinometer 30-40 ms after it,
    the depth gauge at 2 Hz; `pin_fault` (cable or cables, from sample, offset [N]) makes load pins read
    wrong (until sample `fault_until`, if given),
    `reported` is what the encoders report for the true lengths, `pins` what the load pins feel of a
    truth (its rope tensions at the platform, by default)."""
    rng = np.random.default_rng(seed)
    items = []
    for k, truth in enumerate(truths):
        t = 100.0 + k / RATE
        efforts = pins(truth) + rng.normal(0.0, NOISE["tension"], 4)
        if pin_fault is not None and k >= pin_fault[1] and (fault_until is None or k < fault_until):
            efforts[pin_fault[0]] += pin_fault[2]
        winch = SimpleNamespace(header=header(t), name=list(CABLE_NAMES),
                                position=(reported(truth.lengths) + rng.normal(0.0, NOISE["length"], 4)).tolist(),
                                velocity=[speed] * 4, effort=efforts.tolist())
        items.append(item("/winch/joint_states", channels.JOINT_STATE, winch, t))
        late = t + rng.uniform(0.03, 0.04)
        roll = truth.roll + rng.normal(0.0, NOISE["roll"])
        pitch = truth.pitch + rng.normal(0.0, NOISE["pitch"])
        x, y, z, w = Rotation.from_euler("xyz", [roll, pitch, 0.0]).as_quat()
        imu = SimpleNamespace(header=header(late), orientation=SimpleNamespace(x=x, y=y, z=z, w=w))
        items.append(item("/platform/imu", channels.IMU, imu, late))
        if k % 5 == 0:
            depth = truth.position[2] - speed * (late - t) + rng.normal(0.0, NOISE["depth"])
            point = SimpleNamespace(x=float("nan"), y=float("nan"), z=depth)
            items.append(item("/platform/position", channels.POINT, SimpleNamespace(header=header(late), point=point),
                              late))
    return items




def _imu(message: SimpleNamespace) -> dict:
    q = message.orientation
    zero = {"x": 0.0, "y": 0.0, "z": 0.0}
    return {"header": fields.header(fields.stamp_of(message)),
            "orientation": {"x": float(q.x), "y": float(q.y), "z": float(q.z), "w": float(q.w)},
            "orientation_covariance": [0.0] * 9, "angular_velocity": zero, "angular_velocity_covariance": [0.0] * 9,
            "linear_acceleration": zero, "linear_acceleration_covariance": [0.0] * 9}


def _values(entry: SimpleNamespace) -> dict:
    msg = entry.message
    if entry.msgtype == channels.JOINT_STATE:
        return {"header": fields.header(fields.stamp_of(msg)), "name": list(msg.name),
                "position": [float(v) for v in msg.position], "velocity": [float(v) for v in msg.velocity],
                "effort": [float(v) for v in msg.effort]}
    if entry.msgtype == channels.IMU:
        return _imu(msg)
    point = msg.point
    return {"header": fields.header(fields.stamp_of(msg)),
            "point": {"x": float(point.x), "y": float(point.y), "z": float(point.z)}}


def write_bag(items: list[SimpleNamespace], path: Path) -> Path:
    """The items as a real bag (rosbag2, MCAP) at `path`."""
    with BagWriter(path) as writer:
        for entry in items:
            writer.write_raw(entry.topic, entry.msgtype, entry.log_time, encoder(entry.msgtype)(_values(entry)))
    return path
