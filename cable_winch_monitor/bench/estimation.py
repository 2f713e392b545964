"""Benchmark: samples/s of the estimator fusing lengths, load pins, inclinometer and depth, per sample
(warm-started, as live) and batched (as replay), and of the monitor pipeline around it -- replay's
read-ahead windows and the live node's one message at a time (with its 99th percentile) -- against
seed 002's traversal per sample on the same lengths (figures are ratios within one run)."""
from __future__ import annotations

import time
from collections.abc import Callable
from types import SimpleNamespace
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from .. import channels
from ..messages import fields
from ..model.estimator import estimate, estimate_batch
from ..model.estimator import observations as obs
from ..model.plantfile.plant import CABLE_NAMES, load_plant
from ..model.solvers.batched import solve_batch
from ..model.solvers.solve import solve
from ..model.statics.geometry import roll_pitch_yaw
from ..monitor.pipeline import MonitorPipeline
from ..replay.windows import WindowScheduler
from .solvers import lowering_samples

ENCODER, PIN, TILT, DEPTH = 1e-3, 150.0, np.radians(0.01), 5e-3
SPEED = 1.0  # [m/s] the pipeline's lowering (the monitor refuses payout speeds beyond the plant's limit)


def fused_samples(plant, count: int, seed: int = 8) -> tuple[np.ndarray, list[obs.Observation]]:
    """Reported lengths of a lowering and the sensors' readings of its equilibria, with realistic noise
    (depth at one sample in five, as a 2 Hz gauge beside 10 Hz winches)."""
    rng = np.random.default_rng(seed)
    lengths = lowering_samples(count)
    truth = solve_batch(plant, lengths)
    angles = np.array([roll_pitch_yaw(r)[:2] for r in truth.rotation])
    depth = np.where(np.arange(count) % 5 == 0, truth.position[:, 2] + rng.normal(0.0, DEPTH, count), np.nan)
    readings = [obs.load_pin(i, truth.tensions[:, i] + rng.normal(0.0, PIN, count), PIN) for i in range(4)]
    readings += [obs.roll(angles[:, 0] + rng.normal(0.0, TILT, count), TILT),
                 obs.pitch(angles[:, 1] + rng.normal(0.0, TILT, count), TILT), obs.position_component(2, depth, DEPTH)]
    return lengths + rng.normal(0.0, ENCODER, lengths.shape), readings


def _header(t: float) -> SimpleNamespace:
    sec = int(t)
    return SimpleNamespace(stamp=SimpleNamespace(sec=sec, nanosec=int(round((t - sec) * 1e9))), frame_id="shaft")


def bag_items(lengths: np.ndarray, readings: list[obs.Observation]) -> list[SimpleNamespace]:
    """The samples as bag messages in log order, stamped as a lowering at SPEED: a merged winch message
    with its load pins, the inclinometer 35 ms after it, the depth gauge where it read."""
    values = {r.name: np.asarray(r.value, dtype=float) for r in readings}
    period = max(float(np.ptp(lengths.mean(axis=1))) / max(len(lengths) - 1, 1) / SPEED, 0.02)  # lowered at SPEED
    speeds = np.gradient(lengths.mean(axis=1)) / period
    items = []
    for k, row in enumerate(lengths):
        t = 10.0 + period * k
        efforts = [float(values[name][k]) for name in channels.TENSION_CHANNELS]
        winch = SimpleNamespace(header=_header(t), name=list(CABLE_NAMES), position=row.tolist(),
                                velocity=[float(speeds[k])] * 4,
                                effort=efforts)
        items.append(SimpleNamespace(topic="/winch/joint_states", msgtype=channels.JOINT_STATE, message=winch,
                                     log_time=int(t * 1e9)))
        x, y, z, w = Rotation.from_euler("xyz", [values["roll"][k], values["pitch"][k], 0.0]).as_quat()
        imu = SimpleNamespace(header=_header(t + 0.035), orientation=SimpleNamespace(x=x, y=y, z=z, w=w))
        items.append(SimpleNamespace(topic="/platform/imu", msgtype=channels.IMU, message=imu,
                                     log_time=int((t + 0.035) * 1e9)))
        if np.isfinite(values["depth"][k]):
            late = float(values["depth"][k]) - speeds[k] * 0.035  # the platform went on down for 35 ms
            point = SimpleNamespace(x=float("nan"), y=float("nan"), z=late)
            items.append(SimpleNamespace(topic="/platform/position", msgtype=channels.POINT,
                                         log_time=int((t + 0.035) * 1e9),
                                         message=SimpleNamespace(header=_header(t + 0.035), point=point)))
    return items


def pipeline_rates(plant, items: list[SimpleNamespace], count: int) -> tuple[float, float, float]:
    """Samples/s of replay's window scheduler, of the live path one message at a time, and the live
    path's 99th percentile per winch message [ms]."""
    start = time.perf_counter()
    for _ in WindowScheduler(plant).run(items):
        pass
    replay_rate = count / (time.perf_counter() - start)
    live, times = MonitorPipeline(plant), []
    start = time.perf_counter()
    for entry in items:
        msg = entry.message
        if entry.msgtype == channels.JOINT_STATE:
            begun = time.perf_counter()
            live.on_joint_state(fields.joint_sample(msg, entry.topic))
            times.append(time.perf_counter() - begun)
        else:
            live.on_measurement(entry.topic, fields.seconds(msg.header.stamp), msg)
    live_rate = count / (time.perf_counter() - start)
    return replay_rate, live_rate, float(np.percentile(times, 99)) * 1e3


def per_sample_rate(run: Callable[[int, Any], Any], count: int) -> float:
    """Samples/s of run(k, previous) over samples 0..count-1 (the best of three passes)."""
    best = np.inf
    for _ in range(3):
        previous, start = None, time.perf_counter()
        for k in range(count):
            previous = run(k, previous)
        best = min(best, time.perf_counter() - start)
    return count / best


def main() -> None:
    plant = load_plant()
    count = 2000
    lengths, readings = fused_samples(plant, count)
    one = [[r.with_value(float(np.asarray(r.value)[k])) for r in readings] for k in range(count)]  # (count,) each
    few = 300
    rates = {
        "traversal (seed 002)": per_sample_rate(lambda k, _: solve(plant, lengths[k], "traversal"), few),
        "energy, warm (lengths only)": per_sample_rate(
            lambda k, p: solve(plant, lengths[k], "energy", warm_start=p), few),
        "estimate, warm (fused)": per_sample_rate(
            lambda k, p: estimate(plant, lengths[k], one[k], ENCODER, warm_start=p), few),
        "estimate, warm (lengths only)": per_sample_rate(
            lambda k, p: estimate(plant, lengths[k], (), ENCODER, warm_start=p), few),
    }
    best = np.inf
    for _ in range(3):
        start = time.perf_counter()
        batch = estimate_batch(plant, lengths, readings, ENCODER)
        best = min(best, time.perf_counter() - start)
    rates["estimate, batched (fused)"] = count / best
    fused = np.mean([len(e.used) > 0 for e in batch.estimates()])
    base = rates["traversal (seed 002)"]
    print(f"lowering 50-550 m, {count} samples: encoders 1 mm, load pins 150 N, inclinometer 0.01 deg, "
          f"depth 5 mm at 2 Hz; one core; fused {fused:.0%} of the batch")
    noisy = plant.with_changes(noise={**plant.noise, "length": ENCODER, "tension": PIN, "roll": TILT, "pitch": TILT,
                                      "depth": DEPTH})
    replay_rate, live_rate, p99 = pipeline_rates(noisy, bag_items(lengths, readings), count)
    rates["pipeline: replay windows (fused)"] = replay_rate
    rates["pipeline: live, per message (fused)"] = live_rate
    print(f"  {'':<36}{'samples/s':>10}{'ms/sample':>11}{'vs traversal':>14}")
    for name, rate in rates.items():
        print(f"  {name:<36}{rate:10.0f}{1e3 / rate:11.3f}{rate / base:13.1f}x")
    print(f"  live path 99th percentile per winch message: {p99:.2f} ms (50 Hz leaves 20 ms)")


if __name__ == "__main__":
    main()
