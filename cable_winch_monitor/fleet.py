"""Fleet jobs: one job per bag of a folder, on local worker processes or a Dask cluster.

A mine keeps recordings of many shafts; each bag is independent, so a folder is replayed
(or diagnosed) bag by bag in parallel and the per-bag rows gather into one table with a
total. The per-bag job is pluggable: `replay_job` and `diagnose_job` are the two the CLI
runs; any picklable callable (bag, out) -> row will do. With `--scheduler` every worker
must see the bags and the output folder at the same paths (a shared file system).
"""
from __future__ import annotations

import functools
import json
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .bagio.reader import BagError
from .messages.scene import REPLAY_RATE
from .model.plantfile.plant import Plant
from .monitor.alarm import AlarmLevel
from .monitor.sensors import READING_LAG

Row = dict[str, Any]            # one bag's result: column -> value (numbers are summed in the total)
Job = Callable[[Path, Path], Row]


def is_bag(path: Path) -> bool:
    """A rosbag2 directory (metadata.yaml or .mcap files) or a bare .mcap file."""
    return path.suffix == ".mcap" and path.is_file() or path.is_dir() and (
        (path / "metadata.yaml").is_file() or any(path.glob("*.mcap")))


def is_fleet(path: str | Path) -> bool:
    """A folder that is not itself a bag but holds bags."""
    folder = Path(path)
    return folder.is_dir() and not is_bag(folder) and bool(find_bags(folder))


def find_bags(folder: str | Path) -> list[Path]:
    """The bags directly inside `folder`, by name."""
    return sorted(p for p in Path(folder).iterdir() if is_bag(p))


def _replay_row(bag: Path, out: Path, plant: Plant | None, solver: str, staleness: float, scene_rate: float,
                lag: float) -> Row:
    from .replay import replay

    try:
        summary = replay(bag, out, plant, solver, staleness, progress=False, scene_rate=scene_rate,
                         second_process=False, lag=lag)  # the fleet's workers share the cores
    except BagError as error:
        return {"bag": bag.name, "error": str(error)}
    stats = summary.stats
    return {"bag": bag.name, "samples": summary.samples, "solved": stats.solved, "failures": stats.failures,
            **{level.name: stats.levels[level.name] for level in AlarmLevel},
            "written": sum(summary.written.values()), "complete": summary.complete, "wall [s]": summary.wall,
            **({"error": summary.refused} if summary.refused else {})}


def replay_job(plant: Plant | None = None, solver: str = "energy", staleness: float = 0.5,
               scene_rate: float = REPLAY_RATE, lag: float = READING_LAG) -> Job:
    """The per-bag replay as a picklable job."""
    return functools.partial(_replay_row, plant=plant, solver=solver, staleness=staleness, scene_rate=scene_rate,
                             lag=lag)


def _diagnose_row(bag: Path, out: Path, plant: Plant | None, candidates: list[str] | None,
                  budget: float | None) -> Row:
    from .analysis.diagnose import diagnose_bag
    from .analysis.report import diagnose_json

    started = time.perf_counter()
    try:
        result, data = diagnose_bag(bag, plant, candidates, budget)
    except BagError as error:
        return {"bag": bag.name, "error": str(error)}
    report = out.with_name(out.name + ".json")
    report.write_text(json.dumps(diagnose_json(result, str(bag), len(data)), indent=2, default=float))
    return {"bag": bag.name, "rows": len(data), "score": result.ladder[0].score_heldout,
            "score after": result.ladder[-1].score_heldout,
            "found": ", ".join(n for n in result.selected if result.found(n)) or "-",
            "partly explain": ", ".join(result.selected) if result.partial else "-",
            "report": report.name, "wall [s]": time.perf_counter() - started}


def diagnose_job(plant: Plant | None = None, candidates: list[str] | None = None, budget: float | None = None) -> Job:
    """The per-bag diagnose as a picklable job, each bag within `budget` seconds (None: no limit): a row with
    the measurement rows, the held-out score before and after the effects it found, and the full result
    (interface.md) in `<out folder>/<bag>.json`. A worker loads the user modules the plant names
    (`effect_modules`, absolute paths) as its model is made."""
    return functools.partial(_diagnose_row, plant=plant, candidates=candidates, budget=budget)


@dataclass
class FleetSummary:
    """Rows per bag in folder order, and the wall time of the whole run."""

    rows: list[Row]
    wall: float
    workers: str

    @property
    def samples(self) -> int:
        return sum(row.get("samples", 0) for row in self.rows)

    @property
    def ok(self) -> bool:
        return all(not row.get("error") and row.get("complete", True) for row in self.rows)

    def total(self) -> Row:
        """Counts (integers) and durations ("[s]" columns) summed; scores and text are not totals."""
        columns = {key for row in self.rows for key in row}
        return {"bag": "total", **{key: sum(row.get(key, 0) for row in self.rows) for key in columns
                                   if all(isinstance(row.get(key, 0), int) or key.endswith("[s]")
                                          and isinstance(row.get(key, 0), float) for row in self.rows)}}

    def format(self) -> str:
        columns = list(dict.fromkeys(key for row in self.rows for key in row if key != "error"))
        table = [*self.rows, self.total()]

        def cell(value: Any) -> str:
            return f"{value:.2f}" if isinstance(value, float) else "" if value is None else str(value)

        width = {c: max(len(c), *(len(cell(row.get(c))) for row in table)) for c in columns}
        lines = ["  ".join(f"{c:<{width[c]}}" if c == "bag" else f"{c:>{width[c]}}" for c in columns)]
        for row in table:
            lines.append("  ".join(f"{cell(row.get(c)):<{width[c]}}" if c == "bag" else f"{cell(row.get(c)):>{width[c]}}"
                                   for c in columns))
        lines += [f"  error {row['bag']}: {row['error']}" for row in self.rows if row.get("error")]
        rate = f", {self.samples / self.wall:.0f} samples/s" if self.samples and self.wall > 0 else ""
        lines.append(f"{len(self.rows)} bag(s) on {self.workers}: wall time {self.wall:.2f} s{rate}")
        return "\n".join(lines)


def run_fleet(bags: Sequence[Path], out_dir: str | Path, job: Job, workers: int = 1,
              scheduler: str | None = None) -> FleetSummary:
    """Run `job(bag, out_dir / bag.stem)` for every bag, on `workers` processes or the Dask `scheduler`."""
    out = Path(out_dir)
    if out.exists():
        raise BagError(f"{out} exists already: give a new output folder (bags are never overwritten)")
    out.mkdir(parents=True)
    targets = [out / bag.stem for bag in bags]
    started = time.perf_counter()
    if scheduler:
        from distributed import Client

        with Client(scheduler) as client:
            rows = client.gather(client.map(job, list(bags), targets, pure=False))
        where = f"Dask cluster {scheduler}"
    elif workers > 1:
        from concurrent.futures import ProcessPoolExecutor  # only a fleet with workers starts processes

        with ProcessPoolExecutor(max_workers=workers) as pool:
            rows = list(pool.map(job, bags, targets))
        where = f"{workers} worker processes"
    else:
        rows = [job(bag, target) for bag, target in zip(bags, targets)]
        where = "1 process"
    return FleetSummary(rows, time.perf_counter() - started, where)
