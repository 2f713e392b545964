"""The equilibrium state that best explains every measurement: the cable lengths are measurements too.

Drum encoders report the paid-out lengths with noise (sigma_l, 1 mm at best). Near the
weak load-sharing mode of four taut rigid ropes (l1 + l3 = l2 + l4) a millimetre moves
tens of kilonewtons, so forward kinematics of the reported lengths cannot give the
tensions; load pins, inclinometer and depth gauge can. The estimator finds, for each
sample, the pose, taut set and tensions, and the length corrections delta, that minimise

    sum_i (delta_i / sigma_l)^2 + sum_k ((predicted_k(state) - value_k) / sigma_k)^2

with the state in static equilibrium J^T(x) tau = F exactly, tau >= 0 on the taut ropes,
a taut rope's corrected length equal to its span through the rope law (`ropes.Ropes`),
and a slack rope no longer than its corrected length (delta > 0 only where its span needs it).

Why this form: with the equilibrium as a hard constraint the state has as many degrees of
freedom as there are taut ropes, and with the lengths alone every taut rope can meet its
reported length exactly, so the optimum is today's forward kinematics (zero cost). The
taut set is chosen by an active-set search: the start's set (the previous sample's live,
the forward kinematics of the reported lengths cold) is solved by `fusion.solve_rows`;
where the result is doubtful -- a tension below zero, a slack rope overstretched, a
residual beyond SEARCH_SIGMA -- its neighbouring sets (one rope added, released or
exchanged) are solved from it, all stacked (together with the start where an observation
contradicts the start already), then the neighbours of a better set found there; where the
best is still inadmissible or overstretches a slack rope, every other set of two or more
ropes. The admissible row of least cost is kept.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from ...frozen import fast_init
from ..plantfile.plant import Plant
from ..solvers import compiled
from ..solvers.batched import BITS, BatchSolution, solve_batch
from ..solvers.batched_elastic import solve_batch_elastic
from ..solvers.elastic import solve_elastic
from ..solvers.energy import TENSION_TOL, solve_energy
from ..solvers.ropes import Ropes
from ..statics.result import Solution, SolveStatus, failed, solved_rows, validate_lengths
from .fusion import Problem, Rows, implied_lengths, residuals, solve_rows
from .observations import Observation
from .prior import Prior

METHOD = "estimate"
SEARCH_SIGMA = 3.0        # a residual beyond this many sigma makes the taut set doubtful
SLACK_SEARCH = 1e-3       # [sigma] a slack rope overstretched by more makes the taut set doubtful
RULED_OUT = 100.0         # [sigma^2] a start set the load pins price above this is solved only if theirs fails


def _neighbour_table() -> list[list[int]]:
    """For each taut set (bit i = rope i), the sets with one rope added, released or exchanged (>= 2 ropes)."""
    table = []
    for code in range(16):
        near = {code ^ (1 << i) for i in range(4)} | {code ^ (1 << i) ^ (1 << j) for i in range(4) for j in range(4)
                                                     if (code >> i & 1) != (code >> j & 1)}
        table.append(sorted(c for c in near if bin(c).count("1") >= 2))
    return table


NEIGHBOURS = _neighbour_table()
ALL_SETS = [[c for c in range(16) if bin(c).count("1") >= 2]] * 16


@fast_init
@dataclass(frozen=True)
class Estimate:
    """The fused state of one sample.

    solution     the equilibrium (the package's Solution) for the corrected lengths; for
                 rigid ropes it passes `check_physics` as it is, for elastic ones with
                 `loaded_lengths` in place of its lengths
    reported     the lengths the encoders reported [m]
    corrections  corrected minus reported lengths [m]
    residuals    (measured - predicted) / sigma of each observation used, by name (a load pin's
                 sigma and prediction include the model's expected error where a prior gave one)
    used         names of the observations measured at this sample (the lengths always are)
    cost         the minimised cost where a prior weighed it (None: the corrections' and residuals'
                 squares in sigma)
    """

    solution: Solution
    reported: np.ndarray
    corrections: np.ndarray
    sigma_length: float
    residuals: dict[str, float] = field(default_factory=dict)
    used: tuple[str, ...] = ()
    loaded_lengths: np.ndarray | None = None
    cost: float | None = None

    @property
    def ok(self) -> bool:
        return self.solution.ok

    @property
    def fused(self) -> bool:
        """True where the state was estimated (False: forward kinematics of the reported lengths only)."""
        return self.solution.method == METHOD

    @property
    def corrections_sigma(self) -> np.ndarray:
        return self.corrections / self.sigma_length

    @property
    def loaded_solution(self) -> Solution:
        """The solution with the lengths the corrected ropes have at their tension (for `check_physics`:
        a taut rope as long as its span, a slack one at least as long)."""
        if self.loaded_lengths is None:
            return self.solution
        return replace(self.solution, lengths=self.loaded_lengths)

    @property
    def chi_square(self) -> float:
        """The minimised cost: squared corrections and residuals in sigma (weighed by the prior where one was
        given)."""
        if self.cost is not None:
            return self.cost
        return float(np.sum(self.corrections_sigma ** 2) + sum(r * r for r in self.residuals.values()))


@dataclass
class BatchEstimate:
    """Estimates of N samples as arrays; `estimate(i)` gives sample i as an `Estimate`.

    Samples the estimator did not solve (bad input, a single-cable state, no admissible
    taut set) keep their forward-kinematics `Estimate` in `fallback`.
    """

    plant: Plant
    reported: np.ndarray          # (N, 4) [m]
    corrected: np.ndarray         # (N, 4) [m]
    loaded: np.ndarray            # (N, 4) [m] spans the corrected ropes make at their tension
    status: np.ndarray            # (N,) SolveStatus values
    taut: np.ndarray              # (N, 4) bool
    tensions: np.ndarray          # (N, 4) [N]
    rotation: np.ndarray          # (N, 3, 3)
    position: np.ndarray          # (N, 3) [m]
    residuals: np.ndarray         # (N, m) (measured - predicted) / sigma, NaN where not measured
    names: tuple[str, ...]
    sigma_length: float
    iterations: np.ndarray
    loads: np.ndarray             # (N, 6) the external wrench of each sample (model.load)
    fallback: dict[int, Estimate] = field(default_factory=dict)
    anchors: np.ndarray | None = None  # (N, 4, 3) each sample's anchors where they move with the pose
    cost: np.ndarray | None = None     # (N,) the minimised cost where a prior weighed it

    def __len__(self) -> int:
        return len(self.reported)

    @property
    def corrections(self) -> np.ndarray:
        return self.corrected - self.reported

    def estimate(self, i: int) -> Estimate:
        return self.estimates([i])[0]

    def take(self, rows: np.ndarray) -> BatchEstimate:
        """The estimates of samples `rows`, in that order."""
        index = {int(i): k for k, i in enumerate(rows)}
        arrays = {name: getattr(self, name)[rows] for name in ("reported", "corrected", "loaded", "status", "taut",
                                                                "tensions", "rotation", "position", "residuals",
                                                                "iterations", "loads")}
        return BatchEstimate(self.plant, names=self.names, sigma_length=self.sigma_length, **arrays,
                             fallback={index[i]: e for i, e in self.fallback.items() if i in index},
                             anchors=None if self.anchors is None else self.anchors[rows],
                             cost=None if self.cost is None else self.cost[rows])

    def estimates(self, indices: Sequence[int] | None = None) -> list[Estimate]:
        """The samples (all by default) as `Estimate`s; the solved ones are built together."""
        indices = list(range(len(self))) if indices is None else list(indices)
        rows = np.array([i for i in indices if i not in self.fallback], dtype=int)
        out = {i: self.fallback[i] for i in indices if i in self.fallback}
        solutions = solved_rows(self.plant, METHOD, self.corrected[rows], self.rotation[rows], self.position[rows],
                                self.tensions[rows], self.taut[rows], self.iterations[rows], loads=self.loads[rows],
                                anchors=None if self.anchors is None else self.anchors[rows]) if rows.size else []
        used: dict[tuple[bool, ...], tuple[str, ...]] = {}  # the names measured, for each pattern (a few)
        corrections = self.corrected[rows] - self.reported[rows]
        costs = [None] * len(rows) if self.cost is None else self.cost[rows].tolist()
        for i, solution, correction, row, cost in zip(rows.tolist(), solutions, corrections,
                                                     self.residuals[rows].tolist(), costs):
            measured = tuple(map(math.isfinite, row))
            names = used.get(measured)
            if names is None:
                names = used[measured] = tuple(n for n, m in zip(self.names, measured) if m)
            out[i] = Estimate(solution, self.reported[i], correction, self.sigma_length,
                              {n: r for n, r, m in zip(self.names, row, measured) if m}, names, self.loaded[i], cost)
        return [out[i] for i in indices]


def estimate(plant: Plant, lengths: object, observations: Sequence[Observation] = (), sigma_length: float = 1e-3,
             axial_stiffness: object = None, rope_weight: float = 0.0, load: np.ndarray | None = None,
             warm_start: Estimate | None = None, prior: Prior | None = None) -> Estimate:
    """The fused state of one sample: reported lengths (4) [m] with noise sigma_length [m] and the
    observations (scalar values; NaN = not measured), for rigid ropes (axial_stiffness None) or
    elastic ones (EA [N], scalar or per rope; rope_weight [N/m]) under the wrench `load`
    (None: gravity), with the model's expected error `prior` (one row; None: the model taken as
    exact). Live, pass the previous sample's estimate as warm_start. Never raises."""
    array, reason = validate_lengths(lengths)
    if array is None:
        return unfused(failed(SolveStatus.INVALID_INPUT, reason, METHOD, np.full(4, np.nan)), np.full(4, np.nan),
                        sigma_length)
    try:
        problem = Problem.build(plant, array[None], sigma_length, observations, Ropes.of(axial_stiffness, rope_weight),
                                load, prior=prior)
    except ValueError as error:
        return unfused(failed(SolveStatus.INVALID_INPUT, str(error), METHOD, array), array, sigma_length)
    try:
        with np.errstate(all="ignore"):
            return _estimate(problem, _warm_rows(problem, [warm_start])).estimate(0)
    except (ValueError, np.linalg.LinAlgError) as error:
        return unfused(failed(SolveStatus.SOLVER_FAILED, f"estimator failed: {error}", METHOD, array), array,
                        sigma_length)


def estimate_batch(plant: Plant, lengths: np.ndarray, observations: Sequence[Observation] = (),
                   sigma_length: float = 1e-3, axial_stiffness: object = None, rope_weight: float = 0.0,
                   loads: np.ndarray | None = None, warm_starts: Sequence[Estimate | None] | None = None,
                   anchors: np.ndarray | None = None, prior: Prior | None = None,
                   forward: BatchSolution | None = None) -> BatchEstimate:
    """`estimate` for the rows of lengths (N, 4), observation values (N,) each, under `loads` (one
    wrench (6,) for all, one per sample (N, 6), None: gravity), with each sample's `anchors` (N, 4, 3)
    where the geometry depends on the pose (None: the plant's): every sample starts from its warm start
    where given (an estimate of the sample under slightly different parameters or geometry, as a fit
    and the pose-dependent geometry's refinement make them), else from the batched forward kinematics
    of its reported lengths (with the `prior`'s expected corrections, where one is given: the model's
    expected error, one row per sample); the search runs on all together. `forward`: the samples'
    `forward_kinematics` of their expected lengths, where the caller has it (their cold starts).
    ValueError names a bad argument."""
    lengths = np.asarray(lengths, dtype=float).reshape(-1, 4)
    ropes = Ropes.of(axial_stiffness, rope_weight)
    with np.errstate(all="ignore"):
        problem = Problem.build(plant, lengths, sigma_length, observations, ropes, loads, anchors, prior)
        return _estimate(problem, _warm_rows(problem, warm_starts) if warm_starts is not None else None,
                         same_samples=True, forward=forward)


def _warm_rows(problem: Problem, warm_starts: Sequence[Estimate | None]) -> Rows | None:
    """The samples' previous states as starts (those that have one), each lowered by the change of its
    mean length."""
    picked = [(i, e.solution) for i, e in enumerate(warm_starts) if e is not None and e.ok]
    if not picked:
        return None
    samples = np.array([i for i, _ in picked], dtype=int)
    solutions = [s for _, s in picked]
    shift = np.array([s.lengths.mean() for s in solutions]) - problem.expected_lengths[samples].mean(axis=1)
    return Rows(samples, np.array([s.taut for s in solutions]), np.array([s.rotation for s in solutions]),
                np.array([s.position for s in solutions]) + np.outer(shift, [0.0, 0.0, 1.0]),
                np.array([s.tensions for s in solutions]) / problem.scales[samples, None])


def _forward_kinematics(problem: Problem, samples: np.ndarray) -> tuple[Rows, Callable[[int], Solution], bool]:
    """Cold starts of `samples`: the forward kinematics of their reported lengths (batched for many:
    elastic where the ropes are) where it solves, today's forward kinematics of any of them (for those
    the estimator leaves: a single-cable state, bad input, no admissible set), and whether the starts
    are rigid (their taut sets are often wrong: four taut rigid ropes are the exception)."""
    plant, ropes = problem.plant, problem.ropes
    effective = ropes.effective(problem.expected_lengths[samples])
    loads = problem.loads[samples]
    if len(samples) == 1:
        solution = solve_energy(plant, effective[0], load=loads[0])  # one sample: the per-sample solver is the faster
        picked = [solution] if solution.ok else []
        start = Rows(samples[:len(picked)], np.array([s.taut for s in picked], bool).reshape(-1, 4),
                     np.array([s.rotation for s in picked]).reshape(-1, 3, 3),
                     np.array([s.position for s in picked]).reshape(-1, 3),
                     np.array([s.tensions for s in picked]).reshape(-1, 4))
        one = (lambda k: solution) if ropes.rigid else \
            (lambda k: solve_elastic(plant, effective[k], ropes.axial_stiffness, load=loads[k]))
        rigid_start = True
    else:
        batch = solve_batch(plant, effective, loads=loads) if ropes.rigid else \
            solve_batch_elastic(plant, effective, ropes.axial_stiffness, loads=loads)
        ok = np.flatnonzero(batch.ok)
        start = Rows(samples[ok], batch.taut[ok], batch.rotation[ok], batch.position[ok], batch.tensions[ok])
        one, rigid_start = batch.solution, ropes.rigid
    start.mu = start.mu / problem.scales[start.sample, None]
    position = {int(i): k for k, i in enumerate(samples)}
    return start, lambda i: one(position[i]), rigid_start


def forward_kinematics(plant: Plant, lengths: np.ndarray, ropes: Ropes, loads: np.ndarray,
                       seed: Solution | None = None) -> BatchSolution:
    """The model's own equilibrium of N samples' lengths (N, 4) under their loads (N, 6), each from `seed`
    (without one: the first sample that solves alone, cold), batched: a sample's answer does not depend on
    the samples solved with it, so that the live node, which solves one or a few at a time, and replay,
    which solves many, give the same bits."""
    effective = ropes.effective(np.asarray(lengths, dtype=float).reshape(-1, 4))
    loads = np.asarray(loads, dtype=float).reshape(-1, 6)
    return solve_batch(plant, effective, seed, loads, follow=False) if ropes.rigid else \
        solve_batch_elastic(plant, effective, ropes.axial_stiffness, seed, loads, follow=False)


def _estimate(problem: Problem, warm: Rows | None, same_samples: bool = False,
              forward: BatchSolution | None = None) -> BatchEstimate:
    """The search from the warm starts; the samples without one, or whose warm search found no
    admissible state, from their forward kinematics (`forward`, where it was solved already for the
    problem's expected lengths). Warm starts that are the same samples' states under slightly other
    parameters (`same_samples`: a fit) were searched already: a misfit alone does not send them to their
    neighbouring taut sets again."""
    count = len(problem.lengths)
    kept, rest = None, np.arange(count)
    if warm is not None:
        best = _search(problem, warm, probe=False, misfit=not same_samples)
        kept = best.take(np.flatnonzero(_admissible(best)))
        rest = rest[~np.isin(rest, kept.sample)]  # np.setdiff1d's rows, without its import of numpy.ma (13 ms)
        if not rest.size:
            return _assemble(problem, kept, {})
    if forward is None:
        cold, one, rigid_start = _forward_kinematics(problem, rest)
    else:
        ok = rest[forward.ok[rest]]
        cold = Rows(ok, forward.taut[ok], forward.rotation[ok].copy(), forward.position[ok].copy(),
                    forward.tensions[ok] / problem.scales[ok, None])
        one, rigid_start = forward.solution, problem.ropes.rigid
    cold = _search(problem, cold, probe=rigid_start)
    best = cold.take(np.flatnonzero(_admissible(cold)))
    if kept is not None:
        best = Rows.joined(kept, best)
    missing = sorted(set(range(count)) - set(best.sample.tolist()))
    return _assemble(problem, best, {i: one(i) for i in missing})


def _admissible(rows: Rows) -> np.ndarray:
    """Converged, and no taut rope pushing."""
    return rows.converged & np.all(~rows.taut | (rows.mu >= -TENSION_TOL), axis=1)


def _doubtful(rows: Rows, misfit: bool = True) -> np.ndarray:
    """Rows whose taut set may not be the best: inadmissible, a slack rope overstretched, or (`misfit`)
    a residual beyond SEARCH_SIGMA."""
    overstretched = np.any(~rows.taut & (rows.residuals[:, :4] > SLACK_SEARCH), axis=1)
    doubtful = ~_admissible(rows) | overstretched
    return doubtful | (np.abs(rows.residuals).max(axis=1) > SEARCH_SIGMA) if misfit else doubtful


def _search(problem: Problem, start: Rows, probe: bool, misfit: bool = True) -> Rows:
    """The best admissible row per sample (one start row per sample in, one row per sample out).

    The start's set is solved, and where `probe` and an observation already disagrees at the
    start (from forward kinematics: a load pin reading kilonewtons on a rope the lengths have
    slack; a warm start is not probed, its pose is a sample old) the set its load pins read
    (`_pinned_sets`), or without pins its neighbours, beside it; where the best
    is doubtful, its neighbours, and the neighbours of a better set found there; where the best is
    then still inadmissible or leaves a slack rope overstretched, every other set of two or more
    ropes is solved from it (a misfit alone does not go that far: after the neighbours have not
    explained it, the model lacks something a taut set cannot give).
    """
    count = len(start.sample)
    best = Rows(start.sample, start.taut, start.rotation, start.position, start.mu)
    visited = np.zeros((count, 16), bool)
    visited[np.arange(count), best.taut @ BITS] = True
    best.residuals = np.zeros((count, 4 + len(problem.observations)))
    pending = np.zeros(0, int)
    pinned: tuple[np.ndarray, np.ndarray] | None = (np.zeros(0, int), np.zeros(0, int))
    if probe and problem.observations:
        observed = residuals(problem, best, np.arange(count))[:, 4:]
        pending = np.flatnonzero(np.abs(observed).max(axis=1) > SEARCH_SIGMA)
        pinned = _pinned_sets(problem, best, pending, visited)
        if pinned is not None:
            pending = np.zeros(0, int)
    solved = np.zeros(count, bool)
    deferred = _ruled_out(problem, best, pinned)
    start_rows = best.take(deferred)
    for stage, search in enumerate((NEIGHBOURS, NEIGHBOURS, ALL_SETS)):
        owner, codes = _candidates(best, pending, visited, search) if stage or pinned is None else pinned
        fresh = np.flatnonzero(~solved)
        if not stage:  # the start's own set where the load pins rule it out: only if what they read fails
            fresh = fresh[~np.isin(fresh, deferred)]  # np.setdiff1d's, without numpy.ma
        listed = np.concatenate([fresh, owner])
        current = np.where(solved & _admissible(best), best.cost, np.inf)
        hopeful = _pinned_cost(problem, best.sample[owner], codes) <= current[owner] * (1.0 + 1e-9)
        owner, codes = owner[hopeful], codes[hopeful]
        if not fresh.size and not owner.size:  # no new neighbours: rows still doubtful go wider
            continue
        owner = np.concatenate([fresh, owner])
        taut = np.concatenate([best.taut[fresh], (codes[:, None] & BITS) > 0])
        candidates = solve_rows(problem, best.take(owner, taut))
        key = np.where(_admissible(candidates), candidates.cost, np.inf)
        order = np.lexsort((key, owner))
        first = order[np.r_[True, owner[order][1:] != owner[order][:-1]]]   # cheapest candidate per row
        better = first[(key[first] < current[owner[first]]) | ~solved[owner[first]]]
        replaced = owner[better]
        for name in ("taut", "rotation", "position", "mu", "converged", "cost", "residuals", "steps"):
            getattr(best, name)[replaced] = getattr(candidates, name)[better]
        if not stage and deferred.size:
            _solve_deferred(problem, best, deferred, start_rows)
        solved[:] = True
        # the rows listed, with those whose every candidate was hopeless (np.unique's, without numpy.ma)
        searched = np.flatnonzero(np.bincount(listed, minlength=count))
        pending = searched[_doubtful(best.take(searched), misfit=misfit and stage == 0)]
        if not pending.size:
            break
    return _unloaded(problem, best) if problem.prior is not None else best


def _unloaded(problem: Problem, best: Rows) -> Rows:
    """With a prior, each row with taut ropes whose load pins cannot tell their tension from zero (below
    SEARCH_SIGMA of the pin's noise) solved again with those ropes slack, and taken where admissible
    and no dearer than SEARCH_SIGMA^2: where the model's lengths are free to follow the sensors, four
    rigid ropes can always be made taut, and a rope carrying a pin's noise is not one the platform
    hangs on. A rope its pin shows carrying more stays taut."""
    pins = problem.pins
    ropes = pins.ropes
    if not ropes.size:
        return best
    tension = best.mu[:, ropes] * problem.scales[best.sample, None]
    weak = np.zeros_like(best.taut)
    weak[:, ropes] = best.taut[:, ropes] & pins.measured[best.sample] & (tension < SEARCH_SIGMA * pins.sigma)
    rows = np.flatnonzero(weak.any(axis=1) & ((best.taut & ~weak).sum(axis=1) >= 2) & _admissible(best))
    if not rows.size:
        return best
    candidates = solve_rows(problem, best.take(rows, best.taut[rows] & ~weak[rows]))
    better = _admissible(candidates) & (candidates.cost <= best.cost[rows] + SEARCH_SIGMA ** 2)
    for name in ("taut", "rotation", "position", "mu", "converged", "cost", "residuals", "steps"):
        getattr(best, name)[rows[better]] = getattr(candidates, name)[better]
    return best


def _ruled_out(problem: Problem, start: Rows, pinned: tuple[np.ndarray, np.ndarray] | None) -> np.ndarray:
    """The rows whose start set leaves slack a rope whose load pin reads it far loaded (its cost at least
    RULED_OUT whatever the pose, `_pinned_cost`) while the set the pins read costs less: solved first,
    the start's set only where that one fails (on elastic ropes replayed with a rigid plant file, the
    rigid forward kinematics' three taut ropes against the pins' four: half the rows)."""
    if pinned is None or not pinned[0].size:
        return np.zeros(0, int)
    owner, codes = pinned
    samples = start.sample[owner]
    start_bound = _pinned_cost(problem, samples, start.taut[owner] @ BITS)
    return owner[(start_bound > RULED_OUT) & (_pinned_cost(problem, samples, codes) < start_bound)]


def _solve_deferred(problem: Problem, best: Rows, deferred: np.ndarray, start_rows: Rows) -> None:
    """Solve the start's own set of the deferred rows whose pinned set was not admissible; keep the better."""
    redo = np.flatnonzero(~_admissible(best.take(deferred)))
    if not redo.size:
        return
    candidates = solve_rows(problem, start_rows.take(redo))
    rows = deferred[redo]
    better = _admissible(candidates) & (~_admissible(best.take(rows)) | (candidates.cost < best.cost[rows]))
    for name in ("taut", "rotation", "position", "mu", "converged", "cost", "residuals", "steps"):
        getattr(best, name)[rows[better]] = getattr(candidates, name)[better]


def _pinned_sets(problem: Problem, best: Rows, pending: np.ndarray, visited: np.ndarray) \
        -> tuple[np.ndarray, np.ndarray] | None:
    """Rows and taut-set codes of the sets the load pins read for the pending rows, where another than
    the start's (marked visited): a rope is taut where its pin reads more than SEARCH_SIGMA sigma beyond
    what it reads of a slack rope (nothing, or the prior's expected pin error), as at the start where
    it has none. None where no load pin is read off the state. One candidate a row instead of its
    neighbours (seven for three taut ropes): with 1 mm of noise the forward kinematics of four rigid
    ropes often picks the wrong three, and the pins say which."""
    if not problem.pins.read_off:
        return None
    taut = best.taut[pending].copy()
    samples = best.sample[pending]
    for k, rope, expected, sigma in _slack_readings(problem, samples):
        value = problem.values[samples, k]
        read = np.isfinite(value)
        taut[read, rope] = value[read] - expected[read] > SEARCH_SIGMA * sigma[read]
    codes = taut @ BITS
    other = (codes != best.taut[pending] @ BITS) & (taut.sum(axis=1) >= 2)
    owner, codes = pending[other], codes[other]
    visited[owner, codes] = True
    return owner, codes


def _slack_readings(problem: Problem, samples: np.ndarray) -> list[tuple[int, int, np.ndarray, np.ndarray]]:
    """For each load pin read off the state (observation index, rope): what it is expected to read of a
    slack rope at each sample [N] (nothing, or the prior's expected pin error: the rope's own weight
    above the platform, a pin's zero) and the pin's noise (N,) [N]."""
    expected = np.zeros((len(samples), 4)) if problem.prior is None else problem.prior.pins[samples]
    return [(k, rope, expected[:, rope], np.full(len(samples), problem.sigmas[k])) for k, rope in problem.pins.read_off]


def _pinned_cost(problem: Problem, samples: np.ndarray, codes: np.ndarray) -> np.ndarray:
    """A lower bound of the cost of each candidate (its sample and taut-set code) whatever its pose: a
    rope it leaves slack carries nothing, so a load pin read off that rope's tension adds (value /
    sigma)^2 (with a prior: the pins of the slack ropes, their expected error and covariance, the
    quadratic form of that subset alone, which the other terms can only add to). A candidate whose bound
    exceeds its row's admissible best cannot replace it and is not solved: where the pins read
    kilonewtons on three ropes, the sets that slacken one of them."""
    bound = np.zeros(len(samples))
    if problem.prior is None:
        for k, rope in problem.pins.read_off:
            slack = (codes >> rope & 1) == 0
            bound += np.where(slack, np.nan_to_num((problem.values[samples, k] / problem.sigmas[k]) ** 2), 0.0)
        return bound
    ropes, deviation, covariance = problem.pins.slack_deviation
    compiled.slack_pin_bounds(np.ascontiguousarray(samples, dtype=np.int64),
                              np.ascontiguousarray(codes, dtype=np.int64), ropes, deviation, covariance, bound)
    return bound


def _candidates(best: Rows, pending: np.ndarray, visited: np.ndarray, search: list[list[int]]) \
        -> tuple[np.ndarray, np.ndarray]:
    """Rows and taut-set codes of the unvisited sets `search` lists for the pending rows' sets (marked visited)."""
    found_rows: list[int] = []
    found_codes: list[int] = []
    for row in pending.tolist():
        for code in search[int(best.taut[row] @ BITS)]:
            if not visited[row, code]:
                found_rows.append(row)
                found_codes.append(code)
    owner, codes = np.array(found_rows, dtype=int), np.array(found_codes, dtype=int)
    visited[owner, codes] = True
    return owner, codes


def _assemble(problem: Problem, best: Rows, unsolved: dict[int, Solution]) -> BatchEstimate:
    """Arrays of every sample: the estimated rows, and forward kinematics where none was admissible."""
    plant, count = problem.plant, len(problem.lengths)
    m = len(problem.observations)
    scales = problem.scales[best.sample, None]
    tensions = np.where(best.taut, np.maximum(best.mu, 0.0), 0.0) * scales
    taut = tensions > TENSION_TOL * scales
    corrected = implied_lengths(problem, best)
    out = BatchEstimate(plant, problem.lengths, problem.lengths.copy(), problem.lengths.copy(),
                        np.full(count, SolveStatus.SOLVED.value, dtype=object), np.zeros((count, 4), bool),
                        np.zeros((count, 4)), np.full((count, 3, 3), np.nan), np.full((count, 3), np.nan),
                        np.full((count, m), np.nan), tuple(o.name for o in problem.observations),
                        problem.sigma_length, np.zeros(count, int), problem.loads, anchors=problem.anchors)
    rows = best.sample
    out.corrected[rows] = corrected
    out.loaded[rows] = problem.ropes.loaded(corrected, tensions)
    out.taut[rows], out.tensions[rows] = taut, np.where(taut, tensions, 0.0)
    out.rotation[rows], out.position[rows], out.iterations[rows] = best.rotation, best.position, best.steps
    measured = np.isfinite(problem.values[rows])
    out.residuals[rows] = np.where(measured, -_marginal(problem, best), np.nan)
    if problem.prior is not None:
        out.cost = np.full(count, np.nan)
        out.cost[rows] = best.cost
    for i, solution in unsolved.items():
        out.status[i] = solution.status.value
        out.fallback[i] = unfused(solution, problem.lengths[i], problem.sigma_length)
    return out


def _marginal(problem: Problem, rows: Rows) -> np.ndarray:
    """The observations' residuals of the rows (n, m), each (predicted - measured) / its own sigma: with a
    prior, a load pin's beyond its expected error, over its marginal sigma (the whitened residuals mix
    the pins)."""
    out = rows.residuals[:, 4:].copy()
    if problem.prior is None or not rows.sample.size:
        return out
    white, sigma, _ = problem.pins.whitened
    pins = problem.pins.observations
    raw = np.linalg.solve(white[rows.sample], out[:, pins][..., None])[..., 0]
    out[:, pins] = raw / sigma[rows.sample]
    return out


def unfused(solution: Solution, reported: np.ndarray, sigma_length: float) -> Estimate:
    """A forward-kinematics result as an estimate that used nothing but the lengths."""
    return Estimate(solution, reported, np.zeros(4), sigma_length, {}, (), None)

