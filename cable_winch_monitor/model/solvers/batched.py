"""Many equilibria at once: Newton on the KKT conditions, row by row in C.

Replay and fitting solve thousands of samples whose answers are known to the monitor's
per-sample solver (`energy.py`); here the same KKT system, force and moment balance
about C and |A_i B_i| = l_i on the taut cables, is solved for a whole chunk of samples
in one call (`compiled.active_set_rows`), each row on its own so that its bits do not
depend on the rows solved with it. A chunk starts from the previous chunk's last
solution (warm start along the trajectory). The taut set is changed by the per-sample
solver's rules; a sample that does not settle on an admissible set of two or three taut
cables from there is tried again in the batch from where the per-sample solver starts
cold (the level pose), and one that does not settle then either (four taut, single cable,
bad input) is handed to `solve_energy`, warm-started from its predecessor; so is a sample
whose batched answer fails the physics check. The answers are the same.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..paper.equal_lengths import level_pose
from ..plantfile.plant import Plant
from ..statics import load as loads_
from ..statics.geometry import attachment_points, structure_matrix
from ..statics.result import Solution, SolveStatus, check_physics_rows, passing_rows, solved, solved_rows
from ..statics.tensions import balance_tensions
from . import compiled
from .energy import (
    ACTIVE_BAND,
    ACTIVE_SET_ROUNDS,
    MAX_TURN,
    METHOD,
    NEWTON_MAX_STEPS,
    NEWTON_TOL,
    SLACK_TOL,
    TENSION_TOL,
    solve_energy,
)

CHUNK = 1024              # samples solved together from one warm start
AT_LENGTH = 1e-9           # relative: a slack rope this close to its length still fits a four-taut answer
BITS = 1 << np.arange(4)   # a taut set's code: bit i for rope i (the estimator's search codes sets so too)


@dataclass
class BatchSolution:
    """Equilibria of N samples as arrays; `solution(i)` gives sample i as a `Solution`.

    Rows solved by the per-sample fallback keep their `Solution` in `fallback` (a
    single-cable state, a failure, four taut cables); their arrays hold what it says.
    """

    plant: Plant
    lengths: np.ndarray                 # (N, 4) [m]
    loads: np.ndarray                   # (N, 6) external wrench of each sample (model.load)
    status: np.ndarray                  # (N,) SolveStatus values
    taut: np.ndarray                    # (N, 4) bool
    tensions: np.ndarray                # (N, 4) [N]
    rotation: np.ndarray                # (N, 3, 3)
    position: np.ndarray                # (N, 3) [m]
    iterations: np.ndarray              # (N,) Newton steps
    fallback: dict[int, Solution] = field(default_factory=dict)
    method: str = METHOD                # the per-sample solver whose answers these are
    stretch: np.ndarray | None = None   # (N, 4) [m] elastic ropes' stretch (the elastic solver's extra)

    def __len__(self) -> int:
        return len(self.lengths)

    @property
    def ok(self) -> np.ndarray:
        return self.status == SolveStatus.SOLVED.value

    def solution(self, i: int) -> Solution:
        """Sample i as the per-sample solver's result type."""
        if i in self.fallback:
            return self.fallback[i]
        return solved(self.plant, self.method, self.lengths[i], self.rotation[i], self.position[i], self.tensions[i],
                      self.taut[i], int(self.iterations[i]), load=self.loads[i], **self._extras(i))

    def solutions(self) -> list[Solution]:
        """Every sample as a `Solution`; the solved rows are filled in together (`solved_rows`)."""
        rows = np.array([i for i in range(len(self)) if i not in self.fallback], dtype=int)
        out = dict(self.fallback)
        solutions = solved_rows(self.plant, self.method, self.lengths[rows], self.rotation[rows], self.position[rows],
                                self.tensions[rows], self.taut[rows], self.iterations[rows], loads=self.loads[rows])
        for i, solution in zip(rows.tolist(), solutions):
            solution.extras.update(self._extras(i))
            out[i] = solution
        return [out[i] for i in range(len(self))]

    def _extras(self, i: int) -> dict[str, Any]:
        return {} if self.stretch is None else {"stretch": self.stretch[i]}


def solve_batch(plant: Plant, lengths: np.ndarray, warm_start: Solution | None = None,
                loads: np.ndarray | None = None, follow: bool = True) -> BatchSolution:
    """Equilibria for the rows of `lengths` (N, 4), in order along a trajectory, under `loads` (one
    wrench per row (N, 6), one for all (6,), or None: gravity), each start from the warm start
    (`solve_chunks`, `follow`); never raises."""
    out = empty_batch(plant, lengths, loads)
    solve_chunks(out, warm_start, lambda rows, seed: _solve_checked_chunk(plant, out, rows, seed),
                 lambda i, warm: solve_energy(plant, out.lengths[i], warm_start=warm, load=out.loads[i]), follow,
                 lambda rows: _solve_checked_level_chunk(plant, out, rows))
    return out


def empty_batch(plant: Plant, lengths: np.ndarray, loads: np.ndarray | None, method: str = METHOD) -> BatchSolution:
    """A batch of the rows of `lengths` (N, 4) under `loads` (model.load.loads_for), nothing solved yet."""
    lengths = np.asarray(lengths, dtype=float).reshape(-1, 4)
    count = len(lengths)
    return BatchSolution(plant, lengths, loads_.loads_for(plant, loads, count),
                         np.full(count, SolveStatus.SOLVER_FAILED.value, dtype=object), np.zeros((count, 4), bool),
                         np.full((count, 4), np.nan), np.full((count, 3, 3), np.nan), np.full((count, 3), np.nan),
                         np.zeros(count, int), method=method)


ChunkSolver = Callable[[np.ndarray, Solution], None]   # (valid rows of a chunk, seed) -> rows solved in `out`
ColdSolver = Callable[[np.ndarray], None]               # (rows the seed left) -> rows solved in `out`, cold
SampleSolver = Callable[[int, "Solution | None"], Solution]  # (row, warm start) -> the per-sample solver's answer


def solve_chunks(out: BatchSolution, warm_start: Solution | None, solve_chunk: ChunkSolver,
                 solve_one: SampleSolver, follow: bool = True, solve_cold: ColdSolver | None = None) -> None:
    """Chunk by chunk along the trajectory: the valid rows batched from a seed, those it left batched cold
    (`solve_cold`, where given: a platform that moved far from the seed), the rest by the per-sample
    solver. Following (`follow`), each chunk's seed is the previous chunk's last solution (the first
    chunk's `warm_start`, or its first row solved alone) and a row left to the per-sample solver starts
    from the last row solved before it. Not following, every row starts from `warm_start` (without one:
    the first row that the per-sample solver solves cold), so that a row's answer does not depend on which
    rows are solved with it: the live node, which solves its samples as they come, and replay, which
    solves a window of them at once, give the same bits."""
    lengths, count = out.lengths, len(out.lengths)
    seed = warm_start if warm_start is not None and warm_start.ok else None
    for start in range(0, count, CHUNK):
        rows = np.arange(start, min(start + CHUNK, count))
        usable = np.isfinite(lengths[rows]) & (lengths[rows] > 0.0) & (lengths[rows] <= out.plant.max_payout)
        valid = rows[np.all(usable, axis=1)
                     & np.all(np.isfinite(out.loads[rows]), axis=1) & (out.loads[rows, 2] < 0.0)]
        alone = np.zeros(0, int)  # not following: the rows solved alone, cold, up to the first that solved
        if seed is None and valid.size:
            if follow:
                seed = _fallback(out, int(valid[0]), None, solve_one)
            else:
                seed, alone, valid = _first_solved(out, valid, solve_one)
        if seed is not None and seed.ok:
            with np.errstate(all="ignore"):
                solve_chunk(valid, seed)
            left = valid[out.status[valid] != SolveStatus.SOLVED.value]
            if solve_cold is not None and left.size:
                with np.errstate(all="ignore"):
                    solve_cold(left)
        for i in rows[(out.status[rows] != SolveStatus.SOLVED.value) & ~np.isin(rows, alone)]:
            _fallback(out, int(i), _previous(out, int(i), seed) if follow else seed, solve_one)
        last = rows[out.ok[rows]]
        seed = out.solution(int(last[-1])) if follow and last.size else seed


def _first_solved(out: BatchSolution, valid: np.ndarray, solve_one: SampleSolver) \
        -> tuple[Solution | None, np.ndarray, np.ndarray]:
    """The valid rows solved alone, cold, in order until one solves: its solution (None if none did), the rows
    so solved, and the valid rows after them."""
    for k, i in enumerate(valid.tolist()):
        solution = _fallback(out, i, None, solve_one)
        if solution.ok:
            return solution, valid[:k + 1], valid[k + 1:]
    return None, valid, valid[:0]


def _solve_checked_chunk(plant: Plant, out: BatchSolution, rows: np.ndarray, seed: Solution) -> None:
    _solve_chunk(plant, out, rows, seed)
    _unsolve_unphysical(plant, out, rows)


def _solve_checked_level_chunk(plant: Plant, out: BatchSolution, rows: np.ndarray) -> None:
    _solve_level_chunk(plant, out, rows)
    _unsolve_unphysical(plant, out, rows)


def _unsolve_unphysical(plant: Plant, out: BatchSolution, rows: np.ndarray) -> None:
    """Batched answers among `rows` that fail the physics check go back to SOLVER_FAILED (the fallback's)."""
    rows = rows[out.ok[rows] & ~np.isin(rows, list(out.fallback))]
    rotation, position = out.rotation[rows], out.position[rows]
    points_b, point_c = attachment_points(plant, rotation, position)
    check = check_physics_rows(plant, out.lengths[rows], points_b, point_c, out.tensions[rows], out.taut[rows],
                               out.loads[rows])
    out.status[rows[~passing_rows(check)]] = SolveStatus.SOLVER_FAILED.value


def _previous(out: BatchSolution, i: int, seed: Solution | None) -> Solution | None:
    """The last solved row before row i (warm start of the fallback, as a monitor's last solved
    sample), else the chunk's seed."""
    before = np.flatnonzero(out.ok[:i])
    return out.solution(int(before[-1])) if before.size else seed


def _fallback(out: BatchSolution, i: int, warm: Solution | None, solve_one: SampleSolver) -> Solution:
    """Row i by the per-sample solver, recorded in `out`."""
    solution = solve_one(i, warm)
    out.fallback[i] = solution
    out.status[i] = solution.status.value
    out.iterations[i] = solution.iterations
    for name in ("taut", "tensions", "rotation", "position"):
        value = getattr(solution, name)
        if value is not None:
            getattr(out, name)[i] = value
    return solution


def _solve_chunk(plant: Plant, out: BatchSolution, rows: np.ndarray, seed: Solution) -> None:
    """Batched Newton on the rows of one chunk, every taut set from the same start pose (as `energy`), the
    search over taut sets row by row in C (`compiled.active_set_rows`): a row's bits do not depend on the
    rows solved with it.

    Next after a set that is not admissible, as `energy._next_active_sets` ranks first: a negative tension
    releases the least loaded cable; an overstretched slack cable is taken up, in exchange for the taut cable
    whose set balances the weight best at this pose (added when fewer than three are taut). Four taut cables
    (nearly singular) and one (the single-cable test) are left to the per-sample solver; a seed with four taut
    starts the search from its three that carry most, so that the rows whose answer has fewer are solved here
    (a sixth of the lab robot's rows went to the per-sample solver, a millisecond each)."""
    assert seed.rotation is not None and seed.taut is not None and seed.tensions is not None  # seeded with a solved sample
    lengths = out.lengths[rows]
    scales = np.linalg.norm(out.loads[rows, :3], axis=1)
    rotation = np.broadcast_to(seed.rotation, (rows.size, 3, 3)).copy()
    position = seed.position + np.outer(seed.lengths.mean() - lengths.mean(axis=1), [0.0, 0.0, 1.0])
    active = np.tile(seed.taut.astype(np.uint8), (rows.size, 1))
    mu = seed.tensions / scales[:, None]
    released = int(np.argmin(seed.tensions)) if seed.taut.all() else -1
    if released >= 0:  # four taut: start from the three that carry most
        active[:, released], mu[:, released] = 0, 0.0
    steps, done = _active_set_rows(plant, lengths, out.loads[rows] / scales[:, None], rotation, position, mu, active)
    if released >= 0:
        done &= ~_at_length(plant, lengths, rotation, position, active, released)
    solved = np.flatnonzero(done)
    _store(out, rows[solved], active[solved].astype(bool), rotation[solved], position[solved], mu[solved],
           steps[solved], scales[solved])


def _solve_level_chunk(plant: Plant, out: BatchSolution, rows: np.ndarray) -> None:
    """Batched Newton on rows that the seed's search left (the platform moved or turned far from it), each
    from where the per-sample solver starts cold (`energy._level_start`): the level pose at the mean length,
    every rope but the longest taut, their tensions from the balance there. A row whose answer leaves a
    slack rope within ACTIVE_BAND of its length is left to the per-sample solver (its global search decides
    such a set), as are four taut and one. On the lab robot's recording, the rows that leave a window's seed
    a tenth of its length or more took 1-2 ms each in the per-sample solver."""
    lengths = out.lengths[rows]
    load = out.loads[rows]
    scales = np.linalg.norm(load[:, :3], axis=1)
    level, origin = level_pose(plant, 0.0)  # each row's: `origin` lowered by its mean length
    rotation = np.tile(level, (rows.size, 1, 1))
    position = origin - np.outer(lengths.mean(axis=1), [0.0, 0.0, 1.0])
    active = (np.arange(4) != np.argmax(lengths, axis=1)[:, None]).astype(np.uint8)
    structure = structure_matrix(plant, *attachment_points(plant, rotation, position))
    mu = np.zeros((rows.size, 4))
    for k in range(rows.size):
        taut = active[k].astype(bool)
        mu[k, taut] = balance_tensions(structure[k][:, taut], load[k]) / scales[k]
    steps, done = _active_set_rows(plant, lengths, load / scales[:, None], rotation, position, mu, active)
    spans = np.linalg.norm(attachment_points(plant, rotation, position)[0] - plant.anchors, axis=2)
    touching = (lengths - spans < ACTIVE_BAND * np.maximum(1.0, lengths.max(axis=1) * 1e-3)[:, None]) & (active == 0)
    done &= ~touching.any(axis=1)
    solved = np.flatnonzero(done)
    _store(out, rows[solved], active[solved].astype(bool), rotation[solved], position[solved], mu[solved],
           steps[solved], scales[solved])


def _active_set_rows(plant: Plant, lengths: np.ndarray, loads: np.ndarray, rotation: np.ndarray,
                     position: np.ndarray, mu: np.ndarray, active: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """`compiled.active_set_rows` on rows from their starts (rotation, position, mu, active: in place) under
    `loads` per unit of |f|, with the per-sample solver's tolerances and limits: each row's steps and whether
    it settled on an admissible set of two or three taut cables."""
    steps, done = np.zeros(len(lengths), np.int64), np.zeros(len(lengths), np.uint8)
    compiled.active_set_rows(lengths, rotation, position, mu, active, loads, steps, done,
                             plant.attachments, plant.cog, plant.anchors, plant.moment_scale,
                             NEWTON_TOL * np.maximum(1.0, lengths.max(axis=1) * 1e-2), NEWTON_MAX_STEPS,
                             ACTIVE_SET_ROUNDS, MAX_TURN, SLACK_TOL * np.maximum(lengths.max(axis=1), plant.moment_scale),
                             TENSION_TOL, 0.2, 0.2 * plant.moment_scale)
    return steps, done


def _at_length(plant: Plant, lengths: np.ndarray, rotation: np.ndarray, position: np.ndarray, active: np.ndarray,
               rope: int) -> np.ndarray:
    """Rows whose answer leaves `rope` slack at its very length (within AT_LENGTH of it): the seed's four taut
    ropes then still fit, and their tensions are the per-sample solver's to choose (a symmetric plant's four
    taut ropes carry the load in more than one way; the three carrying most is one of them, not its answer)."""
    points_b = position + rotation @ plant.attachments[rope]
    spans = np.linalg.norm(plant.anchors[rope] - points_b, axis=1)
    return (active[:, rope] == 0) & (spans > lengths[:, rope] * (1.0 - AT_LENGTH))


def _store(out: BatchSolution, rows: np.ndarray, active: np.ndarray, rotation: np.ndarray, position: np.ndarray,
           mu: np.ndarray, steps: np.ndarray, scales: np.ndarray) -> None:
    """Record the admissible rows (their taut sets `active`, poses, mu and steps) as `energy._result` does
    (tensions below TENSION_TOL |f| are zero)."""
    tensions = np.where(active, mu, 0.0) * scales[:, None]
    taut = tensions > TENSION_TOL * scales[:, None]
    few = taut.sum(axis=1) < 2  # one taut cable: the single-cable test of the per-sample solver decides
    rows, tensions, taut = rows[~few], tensions[~few], taut[~few]
    out.status[rows] = SolveStatus.SOLVED.value
    out.taut[rows] = taut
    out.tensions[rows] = np.where(taut, tensions, 0.0)
    out.rotation[rows] = rotation[~few]
    out.position[rows] = position[~few]
    out.iterations[rows] = steps[~few]
