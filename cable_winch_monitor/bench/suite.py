"""`cable-winch-monitor bench`: every performance figure in one run, on the same samples, as ratios.

Solvers (seed 002's traversal, the monitor's warm-started per-sample solve, the batched
solver) on one set of lowering samples; replay of a 10,000-sample bag end to end; peak
memory replaying a large bag (copies of the 10,000-sample stream with shifted stamps,
written in a temporary directory; 1 GiB is the acceptance run, smaller by default);
fleet replay on 1 and 2 workers; diagnose of a 20-minute bag when a diagnose job is given.
"""
from __future__ import annotations

import math
import shutil
import struct
import tempfile
import time
from pathlib import Path
from typing import Any, Callable

import numpy as np

from ..bagio.reader import BagReader
from ..bagio.writer import BagWriter
from ..fleet import find_bags, replay_job, run_fleet
from ..model.batched import solve_batch
from ..model.plant import Plant, load_plant
from ..model.solve import solve
from ..bagio.fields import input_topics
from ..sim.scenario import load_scenario, scenario_path
from ..sim.simulate import simulate
from .replay_throughput import replay_child
from .solvers import lowering_samples, timed

Diagnose = Callable[[Path], Any]  # a 20-minute bag -> anything; timed
REPLAY_RUNS = 3


def write_copies(source: Path, out: Path, megabytes: float) -> int:
    """A bag of about `megabytes` MiB at `out`: the input messages of `source` repeated, each copy's
    header stamps and log times shifted past the previous copy's. Returns the number of copies."""
    messages = [(m.topic, m.msgtype, m.log_time, m.data) for m in BagReader(source, input_topics())]
    size = sum(f.stat().st_size for f in source.glob("*.mcap"))
    copies = max(1, math.ceil(megabytes * 2 ** 20 / size))
    shift = math.ceil((messages[-1][2] - messages[0][2]) / 1e9) + 1  # [s]
    with BagWriter(out) as writer:
        for k in range(copies):
            for topic, msgtype, log_time, data in messages:
                sec = struct.unpack_from("<i", data, 4)[0] + k * shift  # header.stamp.sec, little-endian CDR
                writer.write_raw(topic, msgtype, log_time + k * shift * 10 ** 9,
                                 data[:4] + struct.pack("<i", sec) + data[8:])
    return copies


def solver_rows(plant: Plant, count: int) -> tuple[list[tuple[str, str, str, str]], float]:
    """Traversal, warm-started per-sample and batched solves of the same lowering samples; the rows
    and the traversal's time per sample [ms], the baseline of every ratio."""
    samples = lowering_samples(count)
    traversal = timed(lambda lengths, _: solve(plant, lengths, "traversal"), samples).mean()
    warm_solutions: list[Any] = []

    def warm(lengths: np.ndarray, previous: Any) -> Any:
        warm_solutions.append(solve(plant, lengths, "energy", warm_start=previous))
        return warm_solutions[-1]

    warm_ms = timed(warm, samples).mean()
    runs = []
    for _ in range(5):
        started = time.perf_counter()
        batch = solve_batch(plant, samples)
        runs.append((time.perf_counter() - started) * 1e3 / count)
    batched = min(runs)
    same_taut = all(np.array_equal(s.taut, batch.taut[i]) for i, s in enumerate(warm_solutions))
    tension_gap = max(float(np.abs(s.tensions - batch.tensions[i]).max()) for i, s in enumerate(warm_solutions))
    return [
        ("traversal (seed 002), per sample", f"{traversal:.3f} ms", f"{1e3 / traversal:,.0f}/s", "1.0x"),
        ("energy warm-started, per sample", f"{warm_ms:.3f} ms", f"{1e3 / warm_ms:,.0f}/s", f"{traversal / warm_ms:.1f}x"),
        ("batched solver", f"{batched:.4f} ms", f"{1e3 / batched:,.0f}/s",
         f"{traversal / batched:.0f}x  (>= 20,000/s, >= 100x)"),
        ("  batched vs warm: taut sets", "identical" if same_taut else "DIFFER", f"max |d tau| {tension_gap:.2e} N",
         f"{len(batch.fallback)} per-sample fallbacks"),
    ], traversal


def replay_rows(directory: Path, large_mb: float, fleet_bags: int, diagnose: Diagnose | None,
                traversal_ms: float) -> list[tuple[str, str, str, str]]:
    """Replay, large-bag memory, fleet and diagnose figures on bags simulated into `directory`.

    The 10,000-sample replay runs three times (the best is the machine's speed without other
    load, the median what to expect); its cost per sample is compared with one traversal solve.
    """
    bag = directory / "bench10k"
    simulate(load_scenario(scenario_path("benchmark")), bag)
    runs = sorted((replay_child(bag, directory / f"bench10k_out{k}") for k in range(REPLAY_RUNS)),
                  key=lambda run: run[3])  # by the replay's own wall time
    samples, process_wall, rss, replay_wall = runs[0]
    median = runs[len(runs) // 2][3]
    per_sample = replay_wall * 1e3 / samples  # [ms]
    rows = [("replay 10,000-sample bag", f"{samples / replay_wall:,.0f} samples/s",
             f"best of {REPLAY_RUNS}: {replay_wall:.2f} s ({process_wall:.2f} s with start-up); median "
             f"{samples / median:,.0f}/s", f"{traversal_ms / per_sample:.0f}x a traversal solve  (>= 5,000/s)"),
            ("  peak RSS", f"{max(run[2] for run in runs):.0f} MiB", "", "")]
    large = directory / "large"
    started = time.perf_counter()
    copies = write_copies(bag, large, large_mb)
    written = time.perf_counter() - started
    size = sum(f.stat().st_size for f in large.glob("*.mcap")) / 2 ** 20
    samples, process_wall, rss, _ = replay_child(large, directory / "large_out")
    rows.append((f"replay {size:,.0f} MiB bag ({copies} copies)", f"{rss:.0f} MiB peak RSS",
                 f"{samples:,} samples in {process_wall:.1f} s (bag written in {written:.1f} s)", "1 GiB: < 400 MB"))
    shutil.rmtree(large)
    shutil.rmtree(directory / "large_out")
    rows += fleet_rows(bag, directory / "fleet", fleet_bags)
    if diagnose is None:
        rows.append(("diagnose 20-minute bag", "not available", "no diagnose job given", ""))
    else:
        twenty = directory / "twenty_minutes"
        simulate(load_scenario(scenario_path("benchmark"), ["duration=1200.0"]), twenty)
        started = time.perf_counter()
        diagnose(twenty)
        rows.append(("diagnose 20-minute bag", f"{time.perf_counter() - started:.2f} s", "", ""))
    return rows


def fleet_rows(bag: Path, folder: Path, count: int) -> list[tuple[str, str, str, str]]:
    """Throughput of fleet replay over `count` copies of `bag` on 1 and on 2 worker processes,
    alternated for REPLAY_RUNS rounds: the best of each (and the median) as for the single replay."""
    bags = folder / "bags"
    for k in range(count):
        shutil.copytree(bag, bags / f"shaft_{k + 1}")
    job = replay_job(load_plant())
    rates: dict[int, list[float]] = {1: [], 2: []}
    for round_ in range(REPLAY_RUNS):
        for workers in (1, 2):
            summary = run_fleet(find_bags(bags), folder / f"out_{workers}_{round_}", job, workers)
            rates[workers].append(summary.samples / summary.wall)
            shutil.rmtree(folder / f"out_{workers}_{round_}")
    best = {workers: max(values) for workers, values in rates.items()}
    median = {workers: sorted(values)[len(values) // 2] for workers, values in rates.items()}
    return [(f"fleet replay, {count} bags, 1 worker", f"{best[1]:,.0f} samples/s",
             f"best of {REPLAY_RUNS}; median {median[1]:,.0f}/s", "1.0x"),
            (f"fleet replay, {count} bags, 2 workers", f"{best[2]:,.0f} samples/s",
             f"best of {REPLAY_RUNS}; median {median[2]:,.0f}/s",
             f"{best[2] / best[1]:.2f}x, medians {median[2] / median[1]:.2f}x  (>= 1.7x)")]


def run_suite(samples: int = 1000, large_mb: float = 64.0, fleet_bags: int = 4,
              diagnose: Diagnose | None = None) -> int:
    """Measure and print every figure; 0."""
    plant = load_plant()
    rows, traversal_ms = solver_rows(plant, samples)
    with tempfile.TemporaryDirectory(prefix="cwm_bench_") as tmp:
        rows += replay_rows(Path(tmp), large_mb, fleet_bags, diagnose, traversal_ms)
    print(f"cable-winch-monitor bench: {samples} samples of a 50-550 m lowering (solvers, one core); "
          "seed-002 plant, energy solver")
    widths = [max(len(row[k]) for row in rows) for k in range(3)]
    for name, value, detail, ratio in rows:
        print(f"  {name:<{widths[0]}}  {value:>{widths[1]}}  {detail:<{widths[2]}}  {ratio}")
    return 0
