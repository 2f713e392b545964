"""Benchmark: time per sample of the traversal, the cold energy solve and the warm-started
energy solve along a lowering, on the same samples (figures are ratios within one run)."""
from __future__ import annotations

import time

import numpy as np

from ..model.plantfile.plant import load_plant
from ..model.solvers.solve import solve


def lowering_samples(count: int, seed: int = 6) -> np.ndarray:
    """Cable lengths of a lowering from 50 to 550 m with slowly drifting synchronisation errors."""
    rng = np.random.default_rng(seed)
    payout = np.linspace(50.0, 550.0, count)
    drift = np.cumsum(rng.normal(0.0, 0.002, (count, 4)), axis=0)
    return payout[:, None] + 0.05 * np.tanh(drift / 0.05)


def timed(solve_one, samples: np.ndarray) -> np.ndarray:
    """Wall time [ms] of each call solve_one(lengths, previous_solution)."""
    times, previous = np.empty(len(samples)), None
    for k, lengths in enumerate(samples):
        start = time.perf_counter()
        previous = solve_one(lengths, previous)
        times[k] = (time.perf_counter() - start) * 1e3
    return times


def main() -> None:
    plant = load_plant()
    samples = lowering_samples(1000)

    runs = {
        "traversal (seed 002)": lambda lengths, _: solve(plant, lengths, "traversal"),
        "energy, cold": lambda lengths, _: solve(plant, lengths, "energy"),
        "energy, warm-started": lambda lengths, previous: solve(plant, lengths, "energy", warm_start=previous),
    }
    figures = {name: timed(run, samples) for name, run in runs.items()}
    base = figures["traversal (seed 002)"].mean()
    print(f"{len(samples)} samples of a 50-550 m lowering, one core")
    print(f"  {'solver':<24}{'mean ms':>9}{'p99 ms':>9}{'samples/s':>11}{'vs traversal':>14}")
    for name, ms in figures.items():
        print(f"  {name:<24}{ms.mean():9.3f}{np.percentile(ms, 99):9.3f}{1e3 / ms.mean():11.0f}"
              f"{base / ms.mean():13.1f}x")


if __name__ == "__main__":
    main()
