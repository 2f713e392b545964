"""Fleet jobs: one job per bag of a folder, on local worker processes or a Dask cluster.

A mine keeps recordings of many shafts; each bag is independent, so a folder is replayed
(or diagnosed) bag by bag in parallel and the per-bag rows gather into one table with a
total. The per-bag job is pluggable: `replay_job` is the replay; a diagnose job is any
picklable callable (bag, out) -> row. With `--scheduler` every worker must see the bags
and the output folder at the same paths (a shared file system).
"""
from __future__ import annotations

import functools
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Sequence

from .bagio.reader import BagError
from .model.plant import Plant
from .monitor.alarm import AlarmLevel

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


def _replay_row(bag: Path, out: Path, plant: Plant | None, solver: str, staleness: float) -> Row:
    from .replay import replay

    try:
        summary = replay(bag, out, plant, solver, staleness, progress=False)
    except BagError as error:
        return {"bag": bag.name, "error": str(error)}
    stats = summary.stats
    return {"bag": bag.name, "samples": summary.samples, "solved": stats.solved, "failures": stats.failures,
            **{level.name: stats.levels[level.name] for level in AlarmLevel},
            "written": sum(summary.written.values()), "complete": summary.complete, "wall [s]": summary.wall}


def replay_job(plant: Plant | None = None, solver: str = "energy", staleness: float = 0.5) -> Job:
    """The per-bag replay as a picklable job."""
    return functools.partial(_replay_row, plant=plant, solver=solver, staleness=staleness)


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
        columns = {key for row in self.rows for key in row}
        return {"bag": "total", **{key: sum(row.get(key, 0) for row in self.rows) for key in columns
                                   if all(isinstance(row.get(key, 0), (int, float)) for row in self.rows)}}

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
        rate = self.samples / self.wall if self.wall > 0 else float("nan")
        lines.append(f"{len(self.rows)} bag(s) on {self.workers}: wall time {self.wall:.2f} s, {rate:.0f} samples/s")
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
        with ProcessPoolExecutor(max_workers=workers) as pool:
            rows = list(pool.map(job, bags, targets))
        where = f"{workers} worker processes"
    else:
        rows = [job(bag, target) for bag, target in zip(bags, targets)]
        where = "1 process"
    return FleetSummary(rows, time.perf_counter() - started, where)
