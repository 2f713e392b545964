"""The batched solver gives the per-sample solver's answers, and batched replay the per-sample replay's outputs.

Same status and taut set, tensions within 1 N and poses within 1 mm, on a lowering with
drifting winches (taut sets changing along it) and on random lengths of every state;
replay through the lookahead pipeline writes the same messages as the per-sample
pipeline (numbers to 1e-9 relative; only the iteration counts may differ).
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from cable_winch_monitor.bagio.reader import BagReader
from cable_winch_monitor.bench.solvers import lowering_samples
from cable_winch_monitor.model.batched import solve_batch
from cable_winch_monitor.model.energy import solve_energy
from cable_winch_monitor.model.result import SolveStatus, check_physics
from cable_winch_monitor.paths import demo_bag
from cable_winch_monitor.replay import replay
from test_solver_agreement import random_lengths

TOLERANCE = 1e-9


def per_sample(plant, lengths, warm: bool):
    solutions, previous = [], None
    for row in lengths:
        solution = solve_energy(plant, row, warm_start=previous if warm else None)
        solutions.append(solution)
        previous = solution if solution.ok else previous
    return solutions


def assert_same(plant, batch, solutions):
    for i, want in enumerate(solutions):
        got = batch.solution(i)
        assert got.status is want.status, i
        assert got.taut_set == want.taut_set, i
        if want.tensions is not None:
            assert np.abs(got.tensions - want.tensions).max() < 1.0, i
        if want.ok:
            assert np.abs(got.position - want.position).max() < 1e-3, i
            assert np.abs(got.points_b - want.points_b).max() < 1e-3, i
            assert check_physics(plant, got).passes(), i


def test_lowering_same_as_warm_started_solver(plant):
    lengths = lowering_samples(3000)
    batch = solve_batch(plant, lengths)
    solutions = per_sample(plant, lengths, warm=True)
    assert len({s.taut_set for s in solutions}) >= 2  # the taut set changes along the lowering
    assert_same(plant, batch, solutions)
    assert len(batch.fallback) <= 3  # the batched path does the work


def test_random_lengths_same_as_cold_solver(plant):
    lengths = random_lengths(600, seed=66)
    solutions = per_sample(plant, lengths, warm=False)
    assert {s.status for s in solutions} >= {SolveStatus.SOLVED, SolveStatus.SINGLE_CABLE_INDETERMINATE}
    assert_same(plant, solve_batch(plant, lengths), solutions)


def test_bad_rows_and_warm_start(plant):
    lengths = lowering_samples(50)
    lengths[[3, 40]] = [[np.nan, 60, 60, 60], [-1.0, 70, 70, 70]]
    warm = solve_energy(plant, lengths[0])
    batch = solve_batch(plant, lengths[1:], warm_start=warm)
    assert batch.status[2] == batch.status[39] == SolveStatus.INVALID_INPUT.value
    assert batch.ok.sum() == 47
    assert_same(plant, batch, [solve_energy(plant, row, warm_start=warm) for row in lengths[1:]])


@pytest.mark.timeout(60)
def same_message(got, want, path=""):
    """Field by field; floats to TOLERANCE relative; the solver's iteration count may differ."""
    if dataclasses.is_dataclass(want):
        for f in dataclasses.fields(want):
            if f.name != "iterations":
                same_message(getattr(got, f.name), getattr(want, f.name), f"{path}.{f.name}")
    elif isinstance(want, (list, tuple, np.ndarray)) and not isinstance(want, str):
        assert len(got) == len(want), path
        for k, (g, w) in enumerate(zip(got, want)):
            same_message(g, w, f"{path}[{k}]")
    elif isinstance(want, float):
        assert (np.isnan(got) and np.isnan(want)) or abs(got - want) <= TOLERANCE * max(1.0, abs(want)), path
    else:
        assert got == want, path


def test_batched_replay_same_as_per_sample(tmp_path):
    batched = replay(demo_bag(), tmp_path / "batched", progress=False)
    single = replay(demo_bag(), tmp_path / "single", progress=False, batched=False)
    def counts(summary):
        return summary.format().split("\n", 1)[1].split("written:")[0]

    assert counts(batched) == counts(single)
    got, want = list(BagReader(tmp_path / "batched")), list(BagReader(tmp_path / "single"))
    assert len(got) == len(want) > 9000
    for g, w in zip(got, want):
        assert (g.topic, g.log_time) == (w.topic, w.log_time)
        same_message(g.message, w.message, g.topic)
