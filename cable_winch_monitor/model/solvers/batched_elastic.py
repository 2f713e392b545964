"""Many equilibria on elastic ropes at once: `elastic._newton` on stacked (n, 6, 6) systems.

With elastic ropes the equilibrium is the zero of the force and moment balance on the
platform's six coordinates alone (no taut set to choose: a rope pulls where it is
stretched). A chunk of samples starts from the previous chunk's last solution, lowered
by the change of the mean rope length (warm start along the trajectory; not following it,
every sample from the seed); every sample takes the per-sample solver's Newton steps, with
the same step limits and convergence tests, its (6, 6) Jacobian solved in one
`np.linalg.solve` with the others'. A sample that does not converge (or whose system is
singular, or whose input is bad) is handed to `solve_elastic`, warm-started from its
predecessor (not following: from the seed). The answers are the same.
"""
from __future__ import annotations

import numpy as np

from ..plantfile.plant import Plant
from ..statics.geometry import rotations_from_vectors, skew
from ..statics.result import Solution, SolveStatus
from .batched import BatchSolution, _geometry, empty_batch, solve_chunks
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
    fine = np.setdiff1d(np.arange(rows.size), coarse)
    start = rows[fine - fine % stride]
    start = np.where(out.ok[start], start, -1)  # -1: the seed (stored in an extra row below)
    rotation = np.concatenate([out.rotation, seed.rotation[None]])[start]
    position = np.concatenate([out.position, seed.position[None]])[start]
    mean = np.append(out.lengths.mean(axis=1), seed.lengths.mean())[start]
    _newton(plant, out, rows[fine], ea, rotation, position, mean)


def _newton(plant: Plant, out: BatchSolution, rows: np.ndarray, ea: np.ndarray, rotation: np.ndarray,
            position: np.ndarray, start_mean: np.ndarray) -> None:
    """`elastic._newton` on `rows` from the given poses, lowered by the change of the mean rope length
    from `start_mean`; converged rows are stored in `out`."""
    lengths, load = out.lengths[rows], out.loads[rows]
    count, scale = rows.size, plant.moment_scale
    rotation = np.array(rotation)
    position = position + np.outer(start_mean - lengths.mean(axis=1), [0.0, 0.0, 1.0])
    stiffness = ea / lengths
    weight = np.linalg.norm(load[:, :3], axis=1)
    step_size = np.full(count, np.inf)
    steps = np.zeros(count, int)
    live = np.arange(count)
    for _ in range(MAX_STEPS):
        arms, levers, units, norms = _geometry(plant, rotation[live], position[live])
        stretch = np.maximum(norms - lengths[live], 0.0)
        tensions = stiffness[live] * stretch
        moments = np.cross(levers, units)
        residual = np.concatenate([np.einsum("nc,nci->ni", tensions, units) - load[live, :3],
                                   (np.einsum("nc,nci->ni", tensions, moments) - load[live, 3:]) / scale],
                                  axis=1) / weight[live, None]
        largest = np.abs(residual).max(axis=1)
        done = (largest < TOL) | ((step_size[live] < 1e-13) & (largest < ROUNDING_TOL))
        _store(out, rows[live[done]], rotation[live[done]], position[live[done]], tensions[done], stretch[done],
               steps[live[done]])
        keep = ~done
        live, arms, levers, units, norms = live[keep], arms[keep], levers[keep], units[keep], norms[keep]
        stretch, tensions, moments, residual = stretch[keep], tensions[keep], moments[keep], residual[keep]
        if not live.size:
            return
        pulling = stretch > 0.0
        limp = ~pulling.any(axis=1)  # no rope stretched: lowered by a thousandth of the shortest rope
        jacobian = _jacobian(arms, levers, units, norms, tensions, np.where(pulling, stiffness[live], 0.0), scale)
        jacobian /= weight[live, None, None]
        jacobian[limp], residual[limp] = np.eye(6), 0.0
        try:
            delta = np.linalg.solve(jacobian, -residual[..., None])[..., 0]
        except np.linalg.LinAlgError:
            return  # a singular system in the stack: these samples go to the per-sample solver
        largest = np.maximum.reduce([np.abs(delta[:, 3:6]).max(axis=1) / STEP_TURN,
                                     np.abs(delta[:, 0:3]).max(axis=1) / (STEP_TURN * scale), np.ones(live.size)])
        delta /= largest[:, None]
        delta[limp, 2] = -1e-3 * lengths[live[limp]].min(axis=1)
        moved = live[~limp]
        step_size[moved] = np.maximum(np.abs(delta[~limp, 0:3]).max(axis=1) / lengths[moved].max(axis=1),
                                      np.abs(delta[~limp, 3:6]).max(axis=1))
        position[live] += delta[:, 0:3]
        rotation[live] = rotations_from_vectors(delta[:, 3:6]) @ rotation[live]
        steps[live] += 1


def _jacobian(arms: np.ndarray, levers: np.ndarray, units: np.ndarray, norms: np.ndarray, tensions: np.ndarray,
              stiffness: np.ndarray, scale: float) -> np.ndarray:
    """d(force, moment / scale) / d(position, rotation vector), (n, 6, 6), in closed form.

    A rope's pull f = tau u changes with its span B - A by K = t I + (k - t) u u^T
    (t = tau / span: the turn of its direction; k = EA / l along it, 0 for a slack rope),
    and the span with the pose by [I, -[r]x]; its moment q x f also turns with q:
    [u]x [q]x tau. Products of cross-product matrices are written out ([a]x [b]x =
    b a^T - (a . b) I), so that every block is a sum over the ropes of outer products.
    """
    turn = tensions / norms                                   # t (n, 4)
    along = stiffness - turn                                  # k - t
    moments, twists = np.cross(levers, units), np.cross(arms, units)   # q x u, r x u
    jacobian = np.swapaxes(np.concatenate([units, moments], axis=2) * along[..., None], 1, 2) \
        @ np.concatenate([units, twists], axis=2)             # sum (k - t) [u; q x u] [u; r x u]^T
    pulls = np.concatenate([-turn[..., None] * arms, tensions[..., None] * levers], axis=1)
    jacobian[:, 3:6, 3:6] += np.swapaxes(pulls, 1, 2) @ np.concatenate([levers, units], axis=1)  # -t r q^T + tau q u^T
    jacobian[:, 0:3, 0:3] += turn.sum(axis=1)[:, None, None] * np.eye(3)
    jacobian[:, 0:3, 3:6] -= skew(np.einsum("nc,nci->ni", turn, arms))
    jacobian[:, 3:6, 0:3] += skew(np.einsum("nc,nci->ni", turn, levers))
    jacobian[:, 3:6, 3:6] += np.sum(turn * np.sum(levers * arms, axis=2) - tensions * np.sum(levers * units, axis=2),
                                    axis=1)[:, None, None] * np.eye(3)
    jacobian[:, 3:6] /= scale
    return jacobian


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
