"""Benchmark: replay throughput on a 10,000-sample bag (config/scenarios/benchmark.yaml).

The bag is simulated into a temporary directory, then replayed by the CLI in a child
process so that its peak RSS is the replay's alone. A quarter-length bag is replayed
too: equal peak RSS for both shows that replay streams (memory independent of length).
"""
from __future__ import annotations

import compileall
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from ..sim.scenario import load_scenario, scenario_path
from ..sim.simulate import simulate

CLI = Path(sys.executable).parent / "cable-winch-monitor"


def byte_compile_package() -> None:
    """Byte-compile the package, as pip does when it installs one, so that a child's start-up is timed as
    an installed package's: where PYTHONDONTWRITEBYTECODE is set, a module edited since the set-up would
    be compiled again at every start (the whole package: 70 ms)."""
    compileall.compile_dir(Path(__file__).resolve().parents[1], quiet=1)


def replay_child(bag: Path, out: Path, plant_file: Path | None = None) -> tuple[int, float, float, float, float]:
    """Samples, wall time [s], peak RSS [MiB] of `cable-winch-monitor replay` (on `plant_file`, else the
    bundled plant) in a child process, the replay's own wall time [s] (without interpreter start-up), and
    the CPU time [s] of the child and its estimating process."""
    started = time.perf_counter()
    config = ["--config", str(plant_file)] if plant_file else []
    child = subprocess.Popen([str(CLI), "replay", str(bag), "--out", str(out), "--quiet", *config],
                             stdout=subprocess.PIPE, text=True)
    assert child.stdout is not None  # piped
    stdout = child.stdout.read()
    _, status, usage = os.wait4(child.pid, 0)  # the rusage of this child alone
    wall = time.perf_counter() - started
    child.stdout.close()
    child.returncode = os.waitstatus_to_exitcode(status)
    if child.returncode != 0:
        raise RuntimeError(f"replay of {bag} failed:\n{stdout}")
    samples_line = re.search(r"^samples: (\d+)", stdout, re.M)
    wall_line = re.search(r"^wall time ([\d.]+) s", stdout, re.M)
    if samples_line is None or wall_line is None:
        raise RuntimeError(f"replay of {bag} printed no sample count or wall time:\n{stdout}")
    samples, replay_wall = int(samples_line.group(1)), float(wall_line.group(1))
    return samples, wall, usage.ru_maxrss / 1024.0, replay_wall, usage.ru_utime + usage.ru_stime


def main() -> None:
    byte_compile_package()
    with tempfile.TemporaryDirectory() as tmp:
        directory = Path(tmp)
        rows = []
        for name, duration in (("short", 250.0), ("full", 1000.0)):
            config = load_scenario(scenario_path("benchmark"), [f"duration={duration}"])
            started = time.perf_counter()
            result = simulate(config, directory / name)
            simulated = time.perf_counter() - started
            size = sum(f.stat().st_size for f in (directory / name).glob("*.mcap")) / 2 ** 20
            samples, wall, rss, replay_wall, _ = replay_child(directory / name, directory / f"{name}_out")
            rows.append((name, sum(result.messages.values()), size, simulated, samples, replay_wall, wall, rss))
    print("replay throughput (cable-winch-monitor replay: estimating in a second process where the plant fuses; "
          "seed-002 plant, energy solver)")
    print(f"{'bag':<8}{'messages':>10}{'MiB':>7}{'simulate [s]':>14}{'samples':>9}{'replay [s]':>12}"
          f"{'samples/s':>11}{'with start-up [s]':>19}{'peak RSS [MiB]':>16}")
    for name, messages, size, simulated, samples, replay_wall, wall, rss in rows:
        print(f"{name:<8}{messages:>10}{size:>7.1f}{simulated:>14.1f}{samples:>9}{replay_wall:>12.2f}"
              f"{samples / replay_wall:>11.0f}{wall:>19.2f}{rss:>16.1f}")


if __name__ == "__main__":
    main()
