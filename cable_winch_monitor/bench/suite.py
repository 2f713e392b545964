"""`cable-winch-monitor bench`: every performance figure in one run, on two plants, as ratios.

Each figure is measured twice in the same run: on the rigid default plant and on a
realistic one (elastic ropes with their weight, sheave friction: bench/plants.py). The
baseline of every ratio is seed 002's traversal, one solve per sample, timed in the same
run on the same lowering samples. Figures: the per-sample solve warm-started along the
lowering (the node's), the batched solver (replay's and the analysis'), replay of a
10,000-sample bag end to end (each plant replays a recording of its own physics, with
the sensors at site noise: the fused estimate is what replay publishes) and, beside them, the
acceptance's site recordings (a)-(d), whose plant files are wrong the way a site's are (elastic ropes
replayed with the bundled rigid plant, with EA 10 % high; encoder errors the file does not know) or
right, with their safety outputs judged against the simulator's truth, peak memory replaying a large bag (copies of the
10,000-sample stream with shifted stamps; 1 GiB is the acceptance run, smaller by
default), fleet replay on 1 and 2 workers, diagnose of a 20-minute bag when a diagnose
job is given, and the live node's latency at 50 Hz when ROS 2 is available (on each plant's
lowering, and on recording (a) at 50 Hz with every sensor). Recording (a) is replayed and fed to the node
again with a plant file that tracks its parameters live (EA 10 % high, TRACKED: bench/plants.py), and with
the same file tracking nothing: the two differ by what tracking costs, the rigid row by what the elastic
model costs. The laboratory robot's recording (`bags/lab_robot`: swivel pulleys, every sample's geometry
depending on its pose) is replayed with its plant file, where the checkout has it.
"""
from __future__ import annotations

import math
import shutil
import struct
import tempfile
import time
from collections.abc import Callable, Mapping
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from ..bagio.reader import BagReader
from ..bagio.writer import BagWriter
from ..effects import PlantModel
from ..fleet import find_bags, replay_job, run_fleet
from ..messages.fields import input_topics
from ..model.plantfile.plant import Plant, load_plant
from ..model.solvers.solve import solve
from ..paths import lab_bag, lab_plant_file
from ..sim.scenario import load_scenario, scenario_path
from ..sim.simulate import simulate
from .plants import (
    REALISTIC_EFFECTS,
    SITE_CASES,
    SITE_EA,
    SiteCase,
    plant_file,
    realistic,
    realistic_plant_file,
    tracking_plant_file,
)
from .replay_throughput import byte_compile_package, replay_child
from .safety import score
from .solvers import lowering_samples, timed

Diagnose = Callable[[Path, Plant], Any]  # a 20-minute bag and the plant -> anything; timed
Row = tuple[str, str, str, str]          # figure, value, detail, ratio to the baseline
REPLAY_RUNS = 3
REPLAY_TARGET = 5000                     # [samples/s] with start-up, the site recordings'
LAB_TARGET = 1000                        # [samples/s] with start-up, the lab robot's swivel pulleys
NODE_SAMPLES = 1500                      # 30 s at 50 Hz per plant
NODE_RATE = 50.0
NODE_SECONDS = 30.0                      # [s] of the site recording whose latencies count (after the node's start)
TRACKING_EA = 1.1 * SITE_EA  # [N] the data sheet's stiffness in the plant file that tracks recording (a)'s parameters


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


def recordings(directory: Path) -> dict[str, Path]:
    """The 10,000-sample benchmark recording on each plant, its truth that plant's physics: rigid ropes
    for the rigid plant; elastic ropes with their weight and sheave friction for the realistic one (each
    plant replays what its model explains, as a fitted plant file does at site; sensors at site noise)."""
    truths: dict[str, dict[str, Any]] = {"rigid": {"ropes": {"model": "rigid"}, "effects": {}},
              "realistic": {"ropes": {"model": "elastic", "EA": REALISTIC_EFFECTS["rope_elasticity"]["EA"]},
                            "effects": {name: values for name, values in REALISTIC_EFFECTS.items()
                                        if name != "rope_elasticity"}}}
    out = {}
    for label, truth in truths.items():
        scenario = {**load_scenario(scenario_path("benchmark")), **truth}
        out[label] = directory / f"bench10k_{label}"
        simulate(scenario, out[label])
    return out


def solver_rows(plant: Plant, count: int) -> tuple[list[Row], float]:
    """The baseline -- seed 002's traversal, per sample on the rigid plant -- and its time per sample [ms]."""
    traversal = timed(lambda lengths, _: solve(plant, lengths, "traversal"), lowering_samples(count)).mean()
    return [("traversal (seed 002), per sample", f"{traversal:.3f} ms", f"{1e3 / traversal:,.0f}/s",
             "1.0x  (the baseline)")], traversal


def model_rows(plant: Plant, label: str, count: int, traversal_ms: float) -> list[Row]:
    """The node's per-sample solve warm-started along the lowering, and the batched solver on the same
    samples (best of five runs), with their agreement: on `plant` with its effects."""
    model = PlantModel.from_plant(plant)
    samples = lowering_samples(count)
    warm_solutions: list[Any] = []

    def warm(lengths: np.ndarray, previous: Any) -> Any:
        warm_solutions.append(model.solve(lengths, warm_start=previous))
        return warm_solutions[-1]

    warm_ms = timed(warm, samples).mean()
    runs = []
    for _ in range(5):
        started = time.perf_counter()
        batch = model.solve_true_batch(samples)
        runs.append((time.perf_counter() - started) * 1e3 / count)
    batched = min(runs)
    same_taut = all(np.array_equal(s.taut, batch.taut[i]) for i, s in enumerate(warm_solutions))
    tension_gap = max(float(np.abs(s.tensions - batch.tensions[i]).max()) for i, s in enumerate(warm_solutions))
    pose_gap = max(float(np.abs(s.position - batch.position[i]).max()) for i, s in enumerate(warm_solutions))
    return [
        (f"per-sample solve, warm-started [{label}]", f"{warm_ms:.3f} ms", f"{1e3 / warm_ms:,.0f}/s",
         f"{traversal_ms / warm_ms:.1f}x"),
        (f"batched solver [{label}]", f"{batched:.4f} ms", f"{1e3 / batched:,.0f}/s",
         f"{traversal_ms / batched:.0f}x  (>= 20,000/s)"),
        (f"  batched vs per-sample [{label}]", "identical taut sets" if same_taut else "taut sets DIFFER",
         f"max |d tau| {tension_gap:.1e} N, |d p| {pose_gap:.1e} m", f"{len(batch.fallback)} per-sample fallbacks"),
    ]


def replay_speed(bag: Path, directory: Path, label: str, plant_file: Path | None, traversal_ms: float,
                 name: str, target: int = REPLAY_TARGET) -> tuple[Row, list[tuple[int, float, float, float, float]]]:
    """Replay of `bag` end to end, REPLAY_RUNS times into directory/<label>_out<k>: its row (the best, the
    median beside it; the time with the process's start-up as `target` [samples/s] counts it) and the runs."""
    runs = sorted((replay_child(bag, directory / f"{label}_out{k}", plant_file) for k in range(REPLAY_RUNS)),
                  key=lambda run: run[1])  # by the wall time with start-up
    samples, process_wall, _, replay_wall, cpu = runs[0]
    median = runs[len(runs) // 2][1]
    return (f"{name} [{label}]", f"{samples / process_wall:,.0f} samples/s",
            f"best of {REPLAY_RUNS}: {process_wall:.2f} s with start-up ({replay_wall:.2f} s replaying, {cpu:.2f} s "
            f"CPU in two processes); median {samples / median:,.0f}/s",
            f"{traversal_ms * samples / process_wall / 1e3:.0f}x  (>= {target:,}/s)"), runs


def replay_rows(bag: Path, directory: Path, label: str, plant_file: Path | None, large_mb: float,
                traversal_ms: float) -> list[Row]:
    """Replay of `bag` end to end and peak memory on a large bag, on one plant."""
    row, runs = replay_speed(bag, directory, label, plant_file, traversal_ms, "replay 10,000-sample bag")
    rows = [row]
    large = directory / "large"
    started = time.perf_counter()
    copies = write_copies(bag, large, large_mb)
    written = time.perf_counter() - started
    size = sum(f.stat().st_size for f in large.glob("*.mcap")) / 2 ** 20
    large_samples, large_wall, large_rss, _, _ = replay_child(large, directory / f"{label}_large_out", plant_file)
    rows.append((f"  peak RSS: 10,000 samples / {size:,.0f} MiB bag [{label}]",
                 f"{max(run[2] for run in runs):.0f} / {large_rss:.0f} MiB",
                 f"{copies} copies, {large_samples:,} samples in {large_wall:.1f} s (bag written in {written:.1f} s)",
                 f"{large_rss / max(run[2] for run in runs):.2f}x  (flat; 1 GiB: < 400 MB)"))
    shutil.rmtree(large)
    shutil.rmtree(directory / f"{label}_large_out")
    return rows


def site_recordings(directory: Path) -> tuple[dict[str, tuple[Path, Path]], Path]:
    """The acceptance's site recordings (plants.SITE_CASES), each with the plant file it is replayed with:
    (a) elastic ropes (EA 6.8e7 N, 58 N/m) at site noise, lag events that take a deck within the CRITICAL
    margin, with the bundled rigid plant file (its model contradicts the sensors); (b) with EA 10 % high;
    (c) stiff ropes with encoder errors the rigid file does not know; (d) with the true file. Also the
    first NODE_SECONDS of (a) with the winches at NODE_RATE, for the node."""
    bags: dict[str, Path] = {}
    for scenario in dict.fromkeys(case.scenario for case in SITE_CASES):
        bags[scenario] = directory / scenario
        simulate(load_scenario(scenario_path(scenario)), bags[scenario])
    fast = directory / "site_a_fast"
    simulate(load_scenario(scenario_path(SITE_CASES[0].scenario), [f"duration={NODE_SECONDS + 5.0}",
                                                                    f"sensors.joint_states.rate={NODE_RATE}"]), fast)
    return {case.name: (bags[case.scenario], plant_file(directory / f"site_{case.name}.yaml", case.effects))
            for case in SITE_CASES}, fast


def site_rows(bag: Path, plant: Path, directory: Path, traversal_ms: float, case: SiteCase) -> list[Row]:
    """A site recording replayed end to end as the agreeing ones are, and its safety outputs against the
    simulator's truth (not the model's own answer)."""
    label = f"site ({case.name})"
    name = "replay site recording, rigid plant file" if case.name == "a" else f"replay site recording, {case.what}"
    row, runs = replay_speed(bag, directory, label, plant, traversal_ms, name)
    result = score(directory / f"{label}_out0", bag)
    return [row, (f"  safety outputs against the truth [{label}]",
                  f"clearance p99 {1e3 * result.clearance_p99:.1f} mm",
                  f"CRITICAL raised on {100 * result.recall:.1f} % of {result.critical} samples within the margin, "
                  f"{100 * result.false_share:.2f} % false; slack flags right {100 * result.slack_right:.2f} %",
                  "(<= 10 mm, >= 99 %, <= 1 %, >= 99 %)")]


def diagnose_rows(bag: Path, diagnose: Diagnose | None, plants: dict[str, Plant], traversal_ms: float) -> list[Row]:
    """Wall time of diagnosing the same 20-minute bag on each plant."""
    if diagnose is None:
        return [("diagnose 20-minute bag", "not available", "no diagnose job given", "")]
    rows = []
    for label, plant in plants.items():
        started = time.perf_counter()
        diagnose(bag, plant)
        wall = time.perf_counter() - started
        rows.append((f"diagnose 20-minute 10 Hz bag [{label}]", f"{wall:.1f} s", "",
                     f"{wall * 1e3 / traversal_ms:,.0f} traversal solves  (<= 60 s)"))
    return rows


def node_rows(files: dict[str, Path | None], traversal_ms: float,
              recordings: Mapping[str, tuple[Path, Path]] | None = None) -> list[Row]:
    """The live node's publish-to-pose latency at 50 Hz on each plant, and on each site recording (label: its bag
    and plant file) played with every sensor (needs ROS 2: rclpy)."""
    try:
        from .node_latency import SETTLE, leased_domain, measure, measure_recording
    except ImportError as error:
        return [("node latency at 50 Hz", "not available", f"ROS 2 not importable: {error}", "")]
    jobs: list[tuple[str, Callable[[int], Any]]] = [  # (label, domain -> Latency)
        (label, partial(measure, NODE_SAMPLES, NODE_RATE, plant_file=plant_file))
        for label, plant_file in files.items()]
    for label, (bag, plant) in (recordings or {}).items():
        jobs.append((label, partial(measure_recording, bag, plant_file=plant, seconds=NODE_SECONDS + SETTLE)))
    rows = []
    for label, job in jobs:
        try:
            with leased_domain() as domain:
                latency = job(domain)
        except SystemExit as error:  # the node did not come up: the other figures still count
            rows.append((f"node latency at {NODE_RATE:g} Hz [{label}]", "not measured", str(error), ""))
            continue
        p50, p99 = np.percentile(latency.all, [50, 99])
        inside = "; ".join(f"{name.split(' [ms]')[0]} {value}" for name, value in latency.node.items())
        rows.append((f"node latency at {NODE_RATE:g} Hz [{label}]", f"p99 {p99:.2f} ms",
                     f"p50 {p50:.2f} ms, {latency.all.size} poses, node CPU "
                     f"{100.0 * latency.cpu / latency.wall:.0f} % of a core; in the node, its latest samples [ms]: "
                     f"{inside or 'not reported'}", f"{p99 / traversal_ms:.2f}x a traversal solve  (p99 < 10 ms)"))
    return rows


def fleet_rows(bag: Path, folder: Path, count: int, plant: Plant, label: str, traversal_ms: float) -> list[Row]:
    """Throughput of fleet replay over `count` copies of `bag` on 1 and on 2 worker processes,
    alternated for REPLAY_RUNS rounds: the best of each (and the median) as for the single replay."""
    bags = folder / "bags"
    for k in range(count):
        shutil.copytree(bag, bags / f"shaft_{k + 1}")
    job = replay_job(plant)
    rates: dict[int, list[float]] = {1: [], 2: []}
    for round_ in range(REPLAY_RUNS):
        for workers in (1, 2):
            summary = run_fleet(find_bags(bags), folder / f"out_{workers}_{round_}", job, workers)
            rates[workers].append(summary.samples / summary.wall)
            shutil.rmtree(folder / f"out_{workers}_{round_}")
    best = {workers: max(values) for workers, values in rates.items()}
    median = {workers: sorted(values)[len(values) // 2] for workers, values in rates.items()}
    shutil.rmtree(folder)
    return [(f"fleet replay, {count} bags, 1 worker [{label}]", f"{best[1]:,.0f} samples/s",
             f"best of {REPLAY_RUNS}; median {median[1]:,.0f}/s", f"{traversal_ms * best[1] / 1e3:.0f}x"),
            (f"fleet replay, {count} bags, 2 workers [{label}]", f"{best[2]:,.0f} samples/s",
             f"best of {REPLAY_RUNS}; median {median[2]:,.0f}/s; {best[2] / best[1]:.2f}x one worker, medians "
             f"{median[2] / median[1]:.2f}x (>= 1.7x)", f"{traversal_ms * best[2] / 1e3:.0f}x")]


def run_suite(samples: int = 1000, large_mb: float = 64.0, fleet_bags: int = 4,
              diagnose: Diagnose | None = None, node: bool = True) -> int:
    """Measure every figure on both plants, printing each as it is measured (a long run on a busy
    machine keeps what it has), then the table; 0."""
    print(f"cable-winch-monitor bench: {samples} samples of a 50-550 m lowering (solvers, one core), energy solver; "
          "rigid: the seed-002 plant; realistic: the same with elastic ropes (EA 7.5e7 N), their weight (60 N/m) and "
          "sheave friction; ratios to the traversal's time per sample in this run", flush=True)
    rigid = load_plant()
    plants = {"rigid": rigid, "realistic": realistic(rigid)}
    rows, traversal_ms = solver_rows(rigid, samples)
    _progress(rows)
    for label, plant in plants.items():
        rows += _progress(model_rows(plant, label, samples, traversal_ms))
    with tempfile.TemporaryDirectory(prefix="cwm_bench_") as tmp:
        directory = Path(tmp)
        files = {"rigid": None, "realistic": realistic_plant_file(directory)}
        bags = recordings(directory)
        byte_compile_package()
        for label in plants:
            rows += _progress(replay_rows(bags[label], directory, label, files[label], large_mb, traversal_ms))
        sites, site_fast = site_recordings(directory)
        for case in SITE_CASES:
            rows += _progress(site_rows(*sites[case.name], directory, traversal_ms, case))
        site, site_plant = sites["a"]
        tracking = tracking_plant_file(directory / "site_a_tracking.yaml", TRACKING_EA)
        untracked = tracking_plant_file(directory / "site_a_untracked.yaml", TRACKING_EA, track=False)
        rows += _progress([replay_speed(site, directory, "site (a), tracking", tracking, traversal_ms,
                                        "replay site recording, tracking its parameters live")[0],
                           replay_speed(site, directory, "site (a), untracked", untracked, traversal_ms,
                                        "replay site recording, the same plant file tracking nothing")[0]])
        if lab_bag().is_dir():
            rows += _progress([replay_speed(lab_bag(), directory, "lab robot", lab_plant_file(), traversal_ms,
                                            "replay the lab robot's recording, swivel pulleys", LAB_TARGET)[0]])
        if node:
            rows += _progress(node_rows(files, traversal_ms, {"site (a), every sensor": (site_fast, site_plant),
                                                              "site (a), tracking": (site_fast, tracking),
                                                              "site (a), untracked": (site_fast, untracked)}))
        twenty = directory / "twenty_minutes"
        simulate(load_scenario(scenario_path("benchmark"), ["duration=1200.0"]), twenty)
        rows += _progress(diagnose_rows(twenty, diagnose, plants, traversal_ms))
        for label, plant in plants.items():
            rows += _progress(fleet_rows(bags[label], directory / f"fleet_{label}", fleet_bags, plant, label,
                                         traversal_ms))
    widths = [max(len(row[k]) for row in rows) for k in range(3)]
    print()
    for name, value, detail, ratio in rows:
        print(f"  {name:<{widths[0]}}  {value:>{widths[1]}}  {detail:<{widths[2]}}  {ratio}")
    return 0


def _progress(rows: list[Row]) -> list[Row]:
    for row in rows:
        print("  ... " + " | ".join(row), flush=True)
    return rows
