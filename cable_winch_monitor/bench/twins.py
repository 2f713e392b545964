"""Benchmark: what a per-sample twin of a stacked stage saves the live node on one new sample -- the twin
against the stacked form asked for that same sample, on the same samples.

- Equilibrium: `solve` (the per-sample energy solve, warm-started) against `solve_batch` of one row
  warm-started the same way. The node takes the stacked form (its Newton is compiled, and its bits do
  not depend on the rows solved with it); the per-sample solver stays for what the stacked one
  leaves (a cold start, a single-cable state, four taut ropes), not for speed.
- Encoding: one sample's outputs (pose, /tf, tension distribution, alarm, the model's error) a message at
  a time (`records.sample_records`: `fields`' layouts, the compiled encoders) against the stacked
  encoders on a run of one (`records.run_records`). The twin stays for speed: the node's samples come
  one or a few at a time (`records.STACKED_FROM`).

Each pair is held to the same answers by a test (test/model/test_batched.py,
test/messages/test_stacked.py). Figures are ratios within one run, the best of three passes. Run

    .venv/bin/python -m cable_winch_monitor.bench.twins
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..messages import records
from ..model.plantfile.plant import CABLE_NAMES, Plant, load_plant
from ..model.solvers.batched import solve_batch
from ..model.solvers.solve import solve
from ..model.statics.result import Solution
from ..monitor.inputs import JointSample
from ..monitor.pipeline import MonitorPipeline
from .estimation import per_sample_rate
from .solvers import lowering_samples

RATE = 10.0  # [Hz] the winches
STEPS = 12_500  # samples of the 500 m lowering: 4 cm a sample, 0.4 m/s at RATE


def per_sample(run: Callable[[int, object], object], count: int) -> float:
    """Microseconds per call of run(k, previous) over samples 0..count-1, the best of three passes."""
    return 1e6 / per_sample_rate(run, count)


def solver_costs(plant, lengths: np.ndarray) -> tuple[float, float]:
    """[us] a sample's equilibrium live, warm-started from the previous one: per sample, and as a batch of one."""
    def warm(previous: object) -> Solution | None:
        return previous if isinstance(previous, Solution) else None

    one = per_sample(lambda k, previous: solve(plant, lengths[k], "energy", warm_start=warm(previous)), len(lengths))
    batch = per_sample(lambda k, previous: solve_batch(plant, lengths[k][None], warm_start=warm(previous)).solution(0),
                       len(lengths))
    return one, batch


def encoding_costs(plant: Plant, lengths: np.ndarray) -> tuple[float, float]:
    """[us] one sample's outputs encoded, the lengths estimated with 1 mm encoders: a message at a time, and
    by the stacked encoders as a run of one."""
    monitor = MonitorPipeline(plant.with_changes(noise={**plant.noise, "length": 1e-3}))
    runs = []  # each sample judged alone, as the node's come
    for k, row in enumerate(lengths):
        complete = monitor.merge_winch(JointSample(100.0 + k / RATE, CABLE_NAMES, row.tolist()))
        if complete is not None:
            sample = monitor.read_sensors(complete)
            runs.append(monitor.judge_samples([sample], monitor.solve_samples([sample], monitor.conditions([sample]))))
    outputs = [run.output(0) for run in runs]
    channels, stamp = monitor.model.channels, (100, 0)
    return (per_sample(lambda k, _: records.sample_records(stamp, outputs[k], channels), len(runs)),
            per_sample(lambda k, _: records.run_records([stamp], runs[k], channels), len(runs)))


def main() -> None:
    plant = load_plant()
    lengths = lowering_samples(STEPS)[:1000]
    rows = {"equilibrium (energy, warm-started)": solver_costs(plant, lengths[:300]),
            "outputs encoded (pose, /tf, tension, alarm, model error)": encoding_costs(plant, lengths[:300])}
    print("one new sample of a lowering from 50 m at 0.4 m/s, winches at 10 Hz, as the live node meets it; one core")
    print(f"  {'stage':<58}{'twin us':>9}{'stacked us':>12}{'stacked/twin':>14}")
    for name, (twin, stacked) in rows.items():
        print(f"  {name:<58}{twin:9.1f}{stacked:12.1f}{stacked / twin:13.1f}x")


if __name__ == "__main__":
    main()
