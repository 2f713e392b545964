"""Benchmark: samples/s of the estimator fusing lengths, load pins, inclinometer and depth, per sample
(warm-started, as live) and batched (as replay), against seed 002's traversal per sample on the same
lengths (figures are ratios within one run)."""
from __future__ import annotations

import time

import numpy as np

from ..model import observations as obs
from ..model.batched import solve_batch
from ..model.estimation import estimate, estimate_batch
from ..model.geometry import roll_pitch_yaw
from ..model.plant import load_plant
from ..model.solve import solve
from .solvers import lowering_samples

ENCODER, PIN, TILT, DEPTH = 1e-3, 150.0, np.radians(0.01), 5e-3


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


def per_sample_rate(run, count: int) -> float:
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
    one = [[r.with_value(float(r.value[k])) for r in readings] for k in range(count)]
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
    print(f"  {'':<32}{'samples/s':>10}{'ms/sample':>11}{'vs traversal':>14}")
    for name, rate in rates.items():
        print(f"  {name:<32}{rate:10.0f}{1e3 / rate:11.3f}{rate / base:13.1f}x")


if __name__ == "__main__":
    main()
