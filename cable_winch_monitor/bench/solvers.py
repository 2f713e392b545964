"""Benchmark: time per sample of the traversal, the cold energy solve and the warm-started
energy solve along a lowering, on the same samples (figures are ratios within one run)."""
from __future__ import annotations

import time

import numpy as np

from ..model.plant import load_plant
from ..model.solve import solve


def lowering_samples(count: int, seed: int = 6) -> np.ndarray:
    """Cable lengths of a lowering from 50 to 550 m with slowly drifting synchronisation errors."""
    rng = np.random.default_rng(seed)
    payout = np.linspace(50.0, 550.0, count)
    drift = np.cumsum(rng.normal(0.0, 0.002, (count, 4)), axis=0)
    return payout[:, None] + 0.05 * np.tanh(drift / 0.05)


def per_sample_ms(run) -> float:
    start = time.perf_counter()
    count = run()
    return (time.perf_counter() - start) / count * 1e3


def main() -> None:
    plant = load_plant()
    samples = lowering_samples(1000)

    def traversal() -> int:
        for lengths in samples:
            solve(plant, lengths, "traversal")
        return len(samples)

    def cold() -> int:
        for lengths in samples:
            solve(plant, lengths, "energy")
        return len(samples)

    def warm() -> int:
        previous = None
        for lengths in samples:
            previous = solve(plant, lengths, "energy", warm_start=previous)
        return len(samples)

    figures = {"traversal (seed 002)": per_sample_ms(traversal), "energy, cold": per_sample_ms(cold),
               "energy, warm-started": per_sample_ms(warm)}
    base = figures["traversal (seed 002)"]
    print(f"{len(samples)} samples of a 50-550 m lowering, one core")
    for name, ms in figures.items():
        print(f"  {name:<24}{ms:8.3f} ms/sample  {1e3 / ms:9.0f} samples/s  {base / ms:6.1f}x traversal")


if __name__ == "__main__":
    main()
