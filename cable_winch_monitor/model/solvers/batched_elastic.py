"""Many equilibria on elastic ropes at once: `elastic._newton` on every row of a chunk, in C.

With elastic ropes the equilibrium is the zero of the force and moment balance on the
platform's six coordinates alone (no taut set to choose: a rope pulls where it is
stretched). A chunk of samples starts from the previous chunk's last solution, lowered
by the change of the mean rope length (warm start along the trajectory; not following it,
every sample from the seed); every sample takes the per-sample solver's Newton steps, with
the same step limits and convergence tests, its (6, 6) Jacobian in closed form, row by
row in C (`compiled.elastic_newton_rows`), so that its bits do not depend on the rows
solved with it. A sample that does not converge (or whose system is
singular, or whose input is bad) is handed to `solve_elastic`, warm-started from its
predecessor (not following: from the seed). The answers are the same.
"""
from __future__ import annotations

import numpy as np

from ..plantfile.plant import Plant
from ..statics.result import Solution, SolveStatus
from . import compiled
from .batched import BatchSolution, empty_batch, solve_chunks
from .elastic import MAX_STEPS, METHOD, ROUNDING_TOL, TOL, solve_elastic

STRIDE = 16       # rows solved from the chunk's seed first; each other row starts from the one before it
STEP_TURN = 0.05  # [rad] largest rotation of one Newton step (and 0.05 moment scales of travel), as elastic._newton


def solve_batch_elastic(plant: Plant, lengths: np.ndarray, axial_stiffness: object,
                        warm_start: Solution | None = None, loads: np.ndarray | None = None,
                        follow: bool = True) -> BatchSolution:
    """Equilibria on ropes of axial stiffness EA [N] (scalar or 4) for the rows of the unstretched
    `lengths` (N, 4), in order along a trajectory, under `loads` ((N, 6), (6,) or None: gravity), each start
    from the warm start (`batched.solve_chunks`, `follow`: not following, every row from the seed itself);
    never raises."""
    out = empty_batch(plant, lengths, loads, METHOD)
    out.stretch = np.full((len(out), 4), np.nan)
    ea = np.broadcast_to(np.asarray(axial_stiffness, dtype=float), (4,))
    usable = bool(np.all(np.isfinite(ea)) and np.all(ea > 0.0))  # else every row gets solve_elastic's error

    def solve_chunk(rows: np.ndarray, seed: Solution) -> None:
        if usable:
            _solve_chunk(plant, out, rows, ea, seed, STRIDE if follow else 1)

    solve_chunks(out, warm_start, solve_chunk,
                 lambda i, warm: solve_elastic(plant, out.lengths[i], ea, warm_start=warm, load=out.loads[i]), follow)
    return out


def _solve_chunk(plant: Plant, out: BatchSolution, rows: np.ndarray, ea: np.ndarray, seed: Solution,
                 stride: int) -> None:
    """Every `stride`-th row of the chunk from the seed's pose, then each other row from the solved row
    before it (closer: fewer Newton steps); converged rows are stored in `out`."""
    assert seed.rotation is not None and seed.position is not None  # `solve_chunks` seeds with a solved sample
    coarse = np.arange(0, rows.size, stride)
    _newton(plant, out, rows[coarse], ea, np.broadcast_to(seed.rotation, (coarse.size, 3, 3)),
            np.broadcast_to(seed.position, (coarse.size, 3)), np.full(coarse.size, seed.lengths.mean()))
    fine = np.flatnonzero(np.arange(rows.size) % stride)  # the rows between (np.setdiff1d's, without numpy.ma)
    start = rows[fine - fine % stride]
    start = np.where(out.ok[start], start, -1)  # -1: the seed (stored in an extra row below)
    rotation = np.concatenate([out.rotation, seed.rotation[None]])[start]
    position = np.concatenate([out.position, seed.position[None]])[start]
    mean = np.append(out.lengths.mean(axis=1), seed.lengths.mean())[start]
    _newton(plant, out, rows[fine], ea, rotation, position, mean)


def _newton(plant: Plant, out: BatchSolution, rows: np.ndarray, ea: np.ndarray, rotation: np.ndarray,
            position: np.ndarray, start_mean: np.ndarray) -> None:
    """`elastic._newton` on `rows` from the given poses, lowered by the change of the mean rope length
    from `start_mean`, row by row in C (`compiled.elastic_newton_rows`); converged rows are stored in `out`."""
    lengths, load = out.lengths[rows], np.ascontiguousarray(out.loads[rows])
    count = rows.size
    rotation = np.array(rotation, order="C")
    position = np.ascontiguousarray(position + np.outer(start_mean - lengths.mean(axis=1), [0.0, 0.0, 1.0]))
    tensions, stretch = np.empty((count, 4)), np.empty((count, 4))
    steps, done = np.zeros(count, np.int64), np.zeros(count, np.uint8)
    compiled.elastic_newton_rows(lengths, rotation, position, load, ea / lengths, np.linalg.norm(load[:, :3], axis=1),
                                 plant.attachments, plant.cog, plant.anchors, plant.moment_scale, MAX_STEPS, TOL,
                                 ROUNDING_TOL, STEP_TURN, tensions, stretch, steps, done)
    solved = np.flatnonzero(done)
    _store(out, rows[solved], rotation[solved], position[solved], tensions[solved], stretch[solved], steps[solved])


def _store(out: BatchSolution, rows: np.ndarray, rotation: np.ndarray, position: np.ndarray, tensions: np.ndarray,
           stretch: np.ndarray, steps: np.ndarray) -> None:
    """Record converged samples as `elastic._newton` does (a rope is taut where it pulls); a platform on
    fewer than two ropes (its turn about the rope is free) is left to the per-sample solver."""
    assert out.stretch is not None  # the elastic batch keeps its stretch (`solve_batch_elastic`)
    held = np.count_nonzero(tensions > 0.0, axis=1) >= 2
    rows, rotation, position, tensions, stretch, steps = (rows[held], rotation[held], position[held], tensions[held],
                                                          stretch[held], steps[held])
    out.status[rows] = SolveStatus.SOLVED.value
    out.taut[rows] = tensions > 0.0
    out.tensions[rows] = tensions
    out.rotation[rows] = rotation
    out.position[rows] = position
    out.stretch[rows] = stretch
    out.iterations[rows] = steps
