"""The batched solver gives the per-sample solver's answers, and batched replay the per-sample replay's outputs.

Same status and taut set, tensions within 1 N and poses within 1 mm, on a lowering with
drifting winches (taut sets changing along it) and on random lengths of every state;
replay through its window scheduler writes the same messages as the per-sample
pipeline (numbers to 1e-6 relative, the fused estimate's convergence; only the iteration counts may
differ).
"""
from __future__ import annotations

import dataclasses

import numpy as np
from batch_checks import assert_same, per_sample
from lengths import random_lengths
from simbags import simulated

from cable_winch_monitor.bagio.reader import BagReader
from cable_winch_monitor.bench.plants import realistic
from cable_winch_monitor.bench.solvers import lowering_samples
from cable_winch_monitor.messages.outputs import DIAGNOSTICS, MODEL_ERROR, RESIDUALS, TENSION
from cable_winch_monitor.model.plantfile.plant import load_plant
from cable_winch_monitor.model.solvers.batched import _solve_checked_chunk, empty_batch, solve_batch, solve_chunks
from cable_winch_monitor.model.solvers.energy import solve_energy
from cable_winch_monitor.model.statics.result import SolveStatus
from cable_winch_monitor.paths import demo_bag, lab_plant_file
from cable_winch_monitor.replay import replay

TOLERANCE = 1e-6  # relative: the fused estimate converges to this (model.fusion.STEP_TOL), warm or batched
PRINTED = 1e-5    # relative: a number printed to six digits
# Absolute [N, m] where forces are compared: the model's error is learnt from a window's estimates, whose last
# digits move it, and so the next windows' tensions, by fractions of a millinewton (a load pin's noise: 150 N)
FLOORS = {MODEL_ERROR: 1e-2, RESIDUALS: 1e-2, TENSION: 1e-2, DIAGNOSTICS: 1e-2}


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


def same_message(got, want, path="", floor=0.0):
    """Field by field; floats to TOLERANCE relative (or `floor` absolute); the solver's iteration count may differ."""
    if dataclasses.is_dataclass(want):
        for f in dataclasses.fields(want):
            if f.name != "iterations":
                same_message(getattr(got, f.name), getattr(want, f.name), f"{path}.{f.name}", floor)
    elif isinstance(want, (list, tuple, np.ndarray)) and not isinstance(want, str):
        assert len(got) == len(want), path
        for k, (g, w) in enumerate(zip(got, want)):
            same_message(g, w, f"{path}[{k}]", floor)
    elif isinstance(want, float):
        allowed = max(TOLERANCE * max(1.0, abs(want)), floor)
        assert (np.isnan(got) and np.isnan(want)) or abs(got - want) <= allowed, path
    elif isinstance(want, str) and _number(want) is not None and _number(got) is not None:
        # a number /diagnostics prints to 6 digits: the last may round either way
        got_, want_ = _number(got), _number(want)
        assert (np.isnan(got_) and np.isnan(want_)) or \
            abs(got_ - want_) <= max(PRINTED * max(1.0, abs(want_)), floor), path
    else:
        assert got == want, path


def _number(text: str) -> float | None:
    try:
        return float(text)
    except ValueError:
        return None


def assert_same_replay(bag, directory, plant=None, least=0, floor=0.0):
    batched = replay(bag, directory / "batched", plant, progress=False)
    single = replay(bag, directory / "single", plant, progress=False, batched=False)

    def counts(summary):
        return summary.format().split("\n", 1)[1].split("written:")[0]

    assert counts(batched) == counts(single)
    got, want = list(BagReader(directory / "batched")), list(BagReader(directory / "single"))
    assert len(got) == len(want) > least
    for g, w in zip(got, want):
        assert (g.topic, g.log_time) == (w.topic, w.log_time)
        same_message(g.message, w.message, g.topic, max(floor, FLOORS.get(g.topic, 0.0)))


def test_batched_replay_same_as_per_sample(tmp_path):
    """The bundled recording, a window at a time or one sample at a time: the same estimates to the
    estimator's convergence, 1e-5 absolute (N, m, rad) where the relative test of a small difference of
    forces (a load pin's residual of a few newtons out of tens of kilonewtons) is too tight."""
    assert_same_replay(demo_bag(), tmp_path, least=9000, floor=1e-5)


def test_batched_replay_on_the_realistic_plant_same_as_per_sample(tmp_path, plant):
    """Elastic ropes with their weight and sheave friction: solved batched, the node's outputs.

    The elastic solver stops at a force balance of 1e-11 of the weight (1 uN here), so two
    converged answers from different starts differ by micronewtons and nanometres: to 1e-5
    absolute (N, m, rad) where the relative test of a small difference of forces is too tight.
    """
    bag = simulated(tmp_path, "benchmark", "duration=60.0")
    assert_same_replay(bag, tmp_path, realistic(plant), least=1500, floor=1e-5)


def test_not_following_a_rows_answer_does_not_depend_on_the_rows_solved_with_it(plant):
    """Not following the trajectory, every row starts from the seed (or, without one, from the first row solved
    alone): a row's answer is the same to the last bit solved with the others, in another chunk of them, or
    alone, as the live node and replay must give."""
    lengths = lowering_samples(120, seed=12)  # the winches' drift changes the taut set three times
    seed = solve_energy(plant, lengths[0])
    together = solve_batch(plant, lengths, seed, follow=False)
    assert together.ok.all()
    assert len({tuple(row) for row in together.taut}) >= 3
    for rows in (np.arange(37, 80), np.array([5]), np.array([119])):
        part = solve_batch(plant, lengths[rows], seed, follow=False)
        for k, i in enumerate(rows):
            assert np.array_equal(part.tensions[k], together.tensions[i])
            assert np.array_equal(part.rotation[k], together.rotation[i])
            assert np.array_equal(part.position[k], together.position[i])
    cold = solve_batch(plant, lengths, follow=False)  # the first row solved alone seeds the others
    assert np.array_equal(cold.solution(0).tensions, solve_energy(plant, lengths[0]).tensions)
    later = solve_batch(plant, lengths[1:], cold.solution(0), follow=False)
    assert np.array_equal(later.tensions, cold.tensions[1:]) and np.array_equal(later.position, cold.position[1:])


def test_a_seed_with_four_taut_ropes_starts_the_search_from_its_three_most_loaded(plant):
    """Four taut rigid ropes are nearly singular, and the batched search leaves such a set to the per-sample
    solver. A chunk seeded by a four-taut state (lengths that fit the platform exactly, as the lab robot's
    often do) starts from the three ropes of the seed that carry most: the rows whose answer has three or two
    taut are solved in the batch, with the per-sample solver's answers from the same seed. A row whose
    answer still fits four taut ropes (the seed's own lengths) is the per-sample solver's: the three that
    carry most, with the fourth at its length, also balance the load there, but with other tensions."""
    lengths = lowering_samples(60)
    first = solve_energy(plant, lengths[0])
    fitted = lengths[0].copy()
    fitted[~first.taut] = first.spans[~first.taut]  # the slack rope as long as its span: all four taut
    seed = solve_energy(plant, fitted)
    assert seed.ok and seed.taut.all()
    rows = np.vstack([lengths, fitted])
    batch = solve_batch(plant, rows, seed, follow=False)
    solutions = [solve_energy(plant, row, warm_start=seed) for row in rows]
    assert_same(plant, batch, solutions)
    assert all(len(s.taut_set) in (2, 3) for s in solutions[:-1]) and solutions[-1].taut.all()
    assert list(batch.fallback) == [len(lengths)]  # before: every row per sample


def test_rows_far_from_the_seed_are_solved_in_the_batch_from_their_level_poses():
    """Not following, every row starts from the window's seed; the lab robot's platform moves and turns over a
    window by more than the seed's Newton reaches (a tenth of its length, 0.3 rad). Those rows start again in the
    batch from where the per-sample solver starts cold -- the level pose at their mean length -- and give its
    answers (the per-sample solver keeps the four-taut and one-taut rows, and those with a slack rope at its
    length): the same states as the per-sample solver from the seed or cold, a third of the rows left to it."""
    plant = load_plant(lab_plant_file())
    seed = solve_energy(plant, np.array([1.16, 1.16, 1.18, 1.16]))
    rows = 1.2 + np.random.default_rng(3).uniform(-0.3, 0.5, size=(200, 4))
    batch = solve_batch(plant, rows, seed, follow=False)
    assert_same(plant, batch, [solve_energy(plant, row, warm_start=seed) for row in rows])
    assert_same(plant, batch, [solve_energy(plant, row) for row in rows])
    seeded = empty_batch(plant, rows, None)  # the seed's search alone, then the per-sample solver
    solve_chunks(seeded, seed, lambda part, start: _solve_checked_chunk(plant, seeded, part, start),
                 lambda i, warm: solve_energy(plant, rows[i], warm_start=warm), follow=False)
    assert len(batch.fallback) * 2 < len(seeded.fallback)
    assert {len(batch.solution(i).taut_set) for i in range(len(rows)) if i not in batch.fallback} == {2, 3}
