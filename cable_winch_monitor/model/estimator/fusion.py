"""Gauss-Newton on the equilibrium manifold: the state of one taut set that best explains the measurements.

For stacked rows (sample, taut set, start state) this finds the pose and tensions that
minimise the sum of squared normalised residuals -- unstretched lengths implied by span
and tension against the reported lengths (sigma_l), slack ropes longer than their
reported length, and every observation -- subject to the static equilibrium
J^T(x) tau = F as a hard constraint. Each step solves the KKT system of the Gauss-Newton
model with the constraint linearised (an SQP step),

    [A^T A + eps I   C^T] [dz]   [-A^T r]
    [C               0  ] [nu] = [-c    ],

with dz = (dp, dw, dmu) (position [m], rotation vector [rad] on the left, tensions in
units of the load's force |f|, m g under gravity). Every row has the same 16 x 16 system: a slack rope's tension is held at
zero by an identity row, so all rows of all taut sets go to one `np.linalg.solve`.
eps is a small Levenberg term: along a direction no measurement sees (the weak
load-sharing mode of four rigid taut ropes without load pins) it keeps the start.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from ..plantfile.plant import CABLE_NAMES, Plant
from ..solvers import compiled
from ..solvers.ropes import Ropes
from ..statics import load as loads
from .observations import Observation, States
from .prior import Prior, whitening

MAX_STEPS = 12
EPS = 1e-6                # Levenberg term (residuals are in sigma, dz in m, rad, m g)
BALANCE_TOL = 1e-9        # relative force and moment balance at convergence (per 100 m of rope)
STEP_TOL = 1e-6           # last step [m per 100 m of rope, rad, |f|] at convergence: Newton's next is ~1e-12
COST_TOL = 1e-4           # change of the cost [sigma^2, per 1 + cost] between iterates at which it has stopped falling
MAX_TURN_STEP = 0.2       # [rad] largest rotation of one step
MAX_SHIFT_STEP = 0.2      # largest translation of one step, in units of the plant's size
_NO_JACOBIAN = np.empty((0, 0, 0))  # what `_whiten` hands the compiled weighing when it weighs the residuals alone


@dataclass(frozen=True)
class LoadPins:
    """A problem's load pins, in one place: the ropes that have one, where their readings sit among the
    observations, their noise, which samples read them, those read off the state (a rope's tension
    coordinate, not through a measurement effect), and with a prior their weighing (`whitened`) and what
    the slack-rope bound needs (`slack_deviation`)."""

    ropes: np.ndarray          # (k,) the ropes with a load pin
    observations: np.ndarray   # (k,) their observations' indices
    sigma: np.ndarray          # (k,) their noise [N]
    measured: np.ndarray       # (N, k) bool, contiguous: which samples read each
    read_off: tuple[tuple[int, int], ...]  # (observation index, rope) of the pins read off the state
    values: np.ndarray         # (N, m) the problem's observation values
    prior: Prior | None

    @cached_property
    def columns(self) -> np.ndarray:
        """(k,) the pins' columns among the residuals (the four lengths' first)."""
        return 4 + self.observations

    @cached_property
    def whitened(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Each sample's whitening (N, k, k) of the pins' errors, their marginal sigmas (N, k) [N] and expected
        errors (N, k) [N], a pin not measured at a sample left out of the others' (needs a prior); the
        whitening and the errors contiguous, as the compiled weighing takes them."""
        assert self.prior is not None  # asked only of a problem weighed by a prior
        measured = np.zeros((len(self.measured), 4), bool)
        measured[:, self.ropes] = self.measured
        white, sigma = whitening(self.prior.pin_covariance, measured)
        ropes = self.ropes
        return np.ascontiguousarray(white[:, ropes][:, :, ropes]), sigma[:, ropes], \
            np.ascontiguousarray(self.prior.pins[:, ropes])

    @cached_property
    def slack_deviation(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """For the pins read off the state: their ropes (j,), each sample's readings' deviation from the prior's
        expected pin error (N, j) [N] (NaN where not read), and the prior's pin covariance (N, 4, 4) [N^2],
        contiguous for `compiled.slack_pin_bounds` (needs a prior)."""
        assert self.prior is not None  # asked only of a problem weighed by a prior
        ropes = np.array([rope for _, rope in self.read_off], dtype=np.int64)
        values = self.values[:, [k for k, _ in self.read_off]]
        return ropes, np.ascontiguousarray(self.prior.pins[:, ropes] - values), \
            np.ascontiguousarray(self.prior.pin_covariance, dtype=float)


@dataclass(frozen=True)
class Problem:
    """The measurements of N samples: reported lengths (N, 4), their noise, observation values (N, m).

    Observations that read a state coordinate (load pins, depth) are read off the state
    together, with a constant Jacobian; the others call their prediction functions.
    """

    plant: Plant
    lengths: np.ndarray
    sigma_length: float
    observations: tuple[Observation, ...]
    values: np.ndarray
    ropes: Ropes
    loads: np.ndarray         # external wrench of each sample (N, 6) [N, N m about C]
    anchors: np.ndarray | None = None  # each sample's anchors (N, 4, 3) where they move with the pose
    prior: Prior | None = None  # each sample's expected model error (None: the encoders' and pins' noise alone)

    @classmethod
    def build(cls, plant: Plant, lengths: np.ndarray, sigma_length: float, observations: Sequence[Observation],
              ropes: Ropes, load: np.ndarray | None, anchors: np.ndarray | None = None,
              prior: Prior | None = None) -> Problem:
        """The problem of N samples under `load`: one wrench (6,) for all, one per sample (N, 6), or None
        for gravity; with each sample's `anchors` (N, 4, 3) (None: the plant's) and the model's expected
        error `prior` (None: the model taken as exact, the lengths and pins off by their noise alone);
        ValueError names what is wrong."""
        if not (np.isfinite(sigma_length) and sigma_length > 0.0):
            raise ValueError(f"length noise sigma must be finite and positive, got {sigma_length!r}")
        count = len(lengths)
        values = np.zeros((count, len(observations)))
        for k, observation in enumerate(observations):
            value = np.asarray(observation.value, dtype=float)
            if value.size not in (1, count):
                raise ValueError(f"observation {observation.name!r}: {value.size} values for {count} samples")
            values[:, k] = value.reshape(-1)
        wrenches = np.array(loads.loads_for(plant, load, count), dtype=float)
        reason = loads.check_rows(wrenches)
        if reason:
            raise ValueError(reason)
        if anchors is not None and np.shape(anchors) != (count, 4, 3):
            raise ValueError(f"anchors must have shape ({count}, 4, 3), got {np.shape(anchors)}")
        if prior is not None:
            prior.check(count)
        return cls(plant, lengths, float(sigma_length), tuple(observations), values, ropes, wrenches, anchors, prior)

    def anchors_of(self, sample: np.ndarray) -> np.ndarray | None:
        """The anchors of these samples (n, 4, 3), None where they are the plant's."""
        return None if self.anchors is None else self.anchors[sample]

    @cached_property
    def scales(self) -> np.ndarray:
        """|f| of each sample's load [N]: its tensions are solved for in this unit (m g under gravity)."""
        return np.linalg.norm(self.loads[:, :3], axis=1)

    @cached_property
    def rope_rows(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """What the compiled rope terms read of each sample, contiguous: its anchors (N, 4, 3) (the plant's where
        they do not move), its load per |f| (N, 6), and the ropes' axial stiffness (4,) (zeros: rigid)."""
        anchors = np.broadcast_to(self.plant.anchors, (len(self.lengths), 4, 3)) if self.anchors is None \
            else self.anchors
        stiffness = self.ropes.axial_stiffness
        return (np.ascontiguousarray(anchors, dtype=float), np.ascontiguousarray(self.loads / self.scales[:, None]),
                np.zeros(4) if stiffness is None else np.ascontiguousarray(stiffness, dtype=float))

    @cached_property
    def sigmas(self) -> np.ndarray:
        return np.array([o.sigma for o in self.observations])

    @cached_property
    def read_off(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Indices of the coordinate observations, their coordinates, and their Jacobian rows per unit of
        the state coordinates, divided by their sigma (a tension row is still to be scaled by |f|)."""
        index = np.array([k for k, o in enumerate(self.observations) if o.coordinate is not None], dtype=int)
        columns = np.array([self.observations[k].coordinate for k in index], dtype=int)
        jacobian = np.zeros((index.size, 10))
        jacobian[np.arange(index.size), columns] = 1.0
        return index, columns, jacobian / self.sigmas[index, None] if index.size else jacobian

    @cached_property
    def expected_lengths(self) -> np.ndarray:
        """(N, 4) the lengths the model's ropes are expected to have: reported plus the prior's correction."""
        return self.lengths if self.prior is None else self.lengths + self.prior.lengths

    @cached_property
    def length_white(self) -> np.ndarray:
        """(N, 4, 4) whitening of the length corrections' deviation from the prior (needs a prior), contiguous."""
        assert self.prior is not None  # asked only of a problem weighed by a prior
        return np.ascontiguousarray(whitening(self.prior.length_covariance)[0])

    @cached_property
    def pins(self) -> LoadPins:
        """The problem's load pins: an observation named tension_<cable> on a rope."""
        index = {o.name: k for k, o in enumerate(self.observations)}
        by_rope = [(rope, index.get(f"tension_{name}", -1)) for rope, name in enumerate(CABLE_NAMES)]
        ropes = np.array([rope for rope, k in by_rope if k >= 0], dtype=int)
        observations = np.array([k for _, k in by_rope if k >= 0], dtype=int)
        read_index, read_columns, _ = self.read_off
        read_off = tuple((int(k), int(c) - 6) for k, c in zip(read_index, read_columns) if c >= 6)
        return LoadPins(ropes, observations, self.sigmas[observations],
                        np.ascontiguousarray(np.isfinite(self.values[:, observations])), read_off, self.values,
                        self.prior)

    @cached_property
    def predicted_by_function(self) -> np.ndarray:
        return np.array([k for k, o in enumerate(self.observations) if o.coordinate is None], dtype=int)


@dataclass
class Rows:
    """Stacked candidates: the sample each row explains, its taut set and its state (mu = tau / |f|)."""

    sample: np.ndarray        # (n,) int
    taut: np.ndarray          # (n, 4) bool
    rotation: np.ndarray      # (n, 3, 3)
    position: np.ndarray      # (n, 3)
    mu: np.ndarray            # (n, 4), zero on slack ropes
    converged: np.ndarray = field(init=False)   # (n,) bool
    cost: np.ndarray = field(init=False)        # (n,) sum of squared normalised residuals
    residuals: np.ndarray = field(init=False)   # (n, 4 + m) normalised residuals (lengths first)
    steps: np.ndarray = field(init=False)       # (n,) int

    def __post_init__(self) -> None:
        n = len(self.sample)
        self.mu = np.where(self.taut, self.mu, 0.0)
        self.converged = np.zeros(n, bool)
        self.cost = np.full(n, np.inf)
        self.residuals = np.zeros((n, 0))
        self.steps = np.zeros(n, int)

    @staticmethod
    def joined(first: Rows, second: Rows) -> Rows:
        """The rows of both, first's then second's."""
        out = Rows(*(np.concatenate([getattr(first, name), getattr(second, name)])
                     for name in ("sample", "taut", "rotation", "position", "mu")))
        for name in ("converged", "cost", "residuals", "steps"):
            setattr(out, name, np.concatenate([getattr(first, name), getattr(second, name)]))
        return out

    def take(self, index: np.ndarray, taut: np.ndarray | None = None) -> Rows:
        """The rows `index` (copies), with another taut set where given (its slack ropes' tensions zeroed)."""
        out = Rows(self.sample[index], self.taut[index] if taut is None else taut, self.rotation[index],
                   self.position[index], self.mu[index])
        out.converged, out.cost, out.residuals, out.steps = (self.converged[index], self.cost[index],
                                                              self.residuals[index], self.steps[index])
        return out


def implied_lengths(problem: Problem, rows: Rows) -> np.ndarray:
    """The corrected lengths of each row (n, 4): a taut rope's unstretched length through the rope law;
    a slack rope's expected length (reported, plus the prior's correction), or longer where its span needs it."""
    states = States(problem.plant, rows.rotation, rows.position, rows.mu * problem.scales[rows.sample, None],
                    anchors=problem.anchors_of(rows.sample))
    taut_length = problem.ropes.unstretched(states.spans, states.tensions)[0]
    slack_length = problem.ropes.unstretched(states.spans, np.zeros_like(states.spans))[0]
    return np.where(rows.taut, taut_length, np.maximum(slack_length, problem.expected_lengths[rows.sample]))


def residuals(problem: Problem, rows: Rows, live: np.ndarray) -> np.ndarray:
    """Normalised residuals (n, 4 + m) of the rows `live` at their current state: lengths, then observations."""
    return _residuals(problem, rows, live, False)[0]


def residuals_and_balance(problem: Problem, rows: Rows) -> tuple[np.ndarray, np.ndarray]:
    """Every row's normalised residuals (n, 4 + m) and its force and moment imbalance (n, 6) at its state,
    for derivatives of both with respect to the problem's own parameters (a load, the rope law)."""
    residual, _, constraint, _ = _residuals(problem, rows, np.arange(len(rows.sample)), False)
    return residual, constraint


def _residuals(problem: Problem, rows: Rows, live: np.ndarray, with_jacobian: bool):
    """Normalised residuals r (n, 4+m), their Jacobian A (n, 4+m, 10), constraint c (n, 6) and C (n, 6, 10).

    The ropes' terms (lengths, balance) are `compiled.equilibrium_terms`, row by row; the observations'
    are numpy calls over the rows, their prediction functions being the user's."""
    plant = problem.plant
    weight = problem.scales[rows.sample[live]]   # |f| of each row's load, (n,)
    rotation, position, mu, taut = rows.rotation[live], rows.position[live], rows.mu[live], rows.taut[live]
    sample = rows.sample[live]
    n, m = live.size, len(problem.observations)
    anchors = problem.anchors_of(sample)
    prior = problem.prior
    tensions = mu * weight[:, None]
    residual = np.empty((n, 4 + m))
    lengths_residual = np.empty((n, 4))
    constraint = np.empty((n, 6))
    jacobian = np.zeros((n, 4 + m, 10)) if with_jacobian else None
    lengths_jacobian = np.empty((n, 4, 10)) if with_jacobian else np.empty((0, 4, 10))
    balance = np.empty((n, 6, 10)) if with_jacobian else np.empty((0, 6, 10))
    row_anchors, unit_loads, stiffness = problem.rope_rows
    compiled.equilibrium_terms(
        rotation, position, mu, taut.view(np.uint8), weight, problem.expected_lengths[sample], row_anchors[sample],
        plant.attachments, plant.cog, unit_loads[sample], stiffness, problem.ropes.weight, plant.moment_scale,
        problem.sigma_length if prior is None else 1.0, lengths_residual, constraint, lengths_jacobian, balance,
        with_jacobian)
    residual[:, :4] = lengths_residual

    values = problem.values[sample]
    measured = ~np.isnan(values)
    index, columns, read_jacobian = problem.read_off
    functional = problem.predicted_by_function
    predicted = np.empty((n, m))
    if index.size:
        predicted[:, index] = np.concatenate([position, np.zeros((n, 3)), tensions], axis=1)[:, columns]
    states = States(plant, rotation, position, tensions, sample, anchors=anchors) if functional.size else None
    # derivatives first: a model that gives its own (effects.estimate) predicts the values with them, once
    derivatives = [problem.observations[k].jacobian(states) for k in functional.tolist()] if with_jacobian else []
    for k in functional.tolist():
        predicted[:, k] = problem.observations[k].evaluate(states)
    residual[:, 4:] = np.where(measured, predicted - np.where(measured, values, 0.0), 0.0) / problem.sigmas
    if jacobian is None:
        if prior is not None:
            _whiten(problem, sample, residual, None)
        return residual, None, constraint, None

    jacobian[:, :4] = lengths_jacobian
    if index.size:
        jacobian[:, 4 + index] = read_jacobian
    for k, derivative in zip(functional.tolist(), derivatives):
        jacobian[:, 4 + k] = derivative / problem.sigmas[k]
    observed = jacobian[:, 4:]
    observed[:, :, 6:] *= (weight[:, None] * taut)[:, None, :]   # per newton -> per unit of |f|; slack ropes' held
    observed *= measured[..., None]
    if prior is not None:
        _whiten(problem, sample, residual, jacobian)
    return residual, jacobian, constraint, balance


def _whiten(problem: Problem, sample: np.ndarray, residual: np.ndarray, jacobian: np.ndarray | None) -> None:
    """Weigh the rows' length and load-pin residuals (and their Jacobian rows) by the prior, in place
    (`compiled.whiten_rows`): the lengths' deviation from their expected correction by the corrections'
    covariance, the pins' readings beyond the model's prediction by the expected pin error and its
    covariance. The residuals come in as the lengths' deviations [m] and the pins' (predicted - measured) / sigma."""
    pins = problem.pins
    white, _, expected = pins.whitened
    compiled.whiten_rows(sample, residual, _NO_JACOBIAN if jacobian is None else jacobian, jacobian is not None,
                         problem.length_white, white, pins.columns, pins.sigma, pins.measured.view(np.uint8), expected)


def _kkt(jacobian: np.ndarray, residual: np.ndarray, balance: np.ndarray, slack: np.ndarray,
         mu: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The rows' 16 x 16 KKT systems of the Gauss-Newton model with the balance linearised, and the cost's
    gradient (`compiled.kkt_systems`): a slack rope's tension held (an identity row, its gradient the
    tension, so a step sets it to zero), a small Levenberg term EPS on the state."""
    n = len(jacobian)
    system, gradient = np.empty((n, 16, 16)), np.empty((n, 10))
    compiled.kkt_systems(np.ascontiguousarray(jacobian), np.ascontiguousarray(residual), balance,
                         np.ascontiguousarray(slack).view(np.uint8), np.ascontiguousarray(mu), EPS, system, gradient)
    return system, gradient


def prior_jacobian(problem: Problem, rows: Rows) -> np.ndarray:
    """(n, 4 + m, 8) derivative of the rows' weighed residuals (needs a prior) with respect to the prior's
    expected length corrections (4) [m] and expected load-pin errors (4) [N], at the rows' states: a taut
    rope's length residual, or a slack one's where its span overstretches it, moves against its expected
    correction; a measured pin's residual with its expected error."""
    live = np.arange(len(rows.sample))
    states = States(problem.plant, rows.rotation, rows.position, rows.mu * problem.scales[rows.sample, None],
                    anchors=problem.anchors_of(rows.sample))
    slack_length = problem.ropes.unstretched(states.spans, np.zeros_like(states.spans))[0]
    active = rows.taut | (slack_length > problem.expected_lengths[rows.sample])
    out = np.zeros((live.size, 4 + len(problem.observations), 8))
    out[:, :4, :4] = -problem.length_white[rows.sample] * active[:, None, :]
    pins = problem.pins
    white = pins.whitened[0]
    out[:, pins.columns[:, None], 4 + pins.ropes[None, :]] = white[rows.sample] * pins.measured[rows.sample][:, None, :]
    return out


def reduced_normal(problem: Problem, rows: Rows, jacobian: np.ndarray,
                   balance_jacobian: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Each row's part of the Gauss-Newton normal equations of k parameters that all rows share and that
    enter their weighed residuals with `jacobian` (n, 4 + m, k), and their balance with `balance_jacobian`
    (n, 6, k; None: not at all), the row's own state (pose and tensions, on its equilibrium) optimised
    again for any change of them (its Schur complement): (n, k, k) and the gradient (n, k) at the rows'
    states, as a fixed-lag smoother takes a bias's information from a window of samples."""
    live = np.arange(len(rows.sample))
    residual, state_jacobian, _, balance = _residuals(problem, rows, live, True)
    system, _ = _kkt(state_jacobian, residual, balance, ~rows.taut, rows.mu)
    coupling = np.zeros((live.size, 16, jacobian.shape[2]))
    coupling[:, :10] = np.swapaxes(state_jacobian, 1, 2) @ jacobian
    if balance_jacobian is not None:  # the state moves to keep its balance as well
        coupling[:, 10:] = balance_jacobian
    response, singular = np.empty_like(coupling), np.empty(live.size, np.uint8)
    compiled.kkt_responses(system, coupling, response, singular)  # the state's best move per unit of each parameter
    if singular.any():
        raise np.linalg.LinAlgError("Singular matrix")
    response = response[:, :10]
    projected = jacobian - state_jacobian @ response
    left = jacobian if balance_jacobian is None else projected  # the same where the balance does not move
    return np.swapaxes(left, 1, 2) @ projected, np.einsum("nki,nk->ni", projected, residual)


def solve_rows(problem: Problem, rows: Rows) -> Rows:
    """Gauss-Newton SQP on every row from its start; sets converged, cost, residuals and steps.

    Each step: the rows' residuals and their Jacobians (`_residuals`); the step control in C
    (`compiled.gauss_newton_verdict`: a row whose cost rose on the balance takes half its last step back --
    a slack rope's one-sided residual has a kink where it meets its length -- and one that went too far and
    has stopped falling is settled); the KKT systems of the others solved; their steps, shortened to at most
    MAX_TURN_STEP and MAX_SHIFT_STEP, taken (`compiled.gauss_newton_advance`) until below STEP_TOL."""
    plant = problem.plant
    count = len(rows.sample)
    reach = np.maximum(1.0, problem.lengths[rows.sample].max(axis=1) * 1e-2)
    live = np.arange(count)
    settled = np.zeros(count, bool)
    previous = np.full(count, np.inf)
    last = np.zeros((count, 10))
    scale = np.ones(count)  # of the Gauss-Newton step: halved each time one went too far
    state = (rows.rotation, rows.position, rows.mu)
    for _ in range(MAX_STEPS):
        residual, jacobian, constraint, balance = _residuals(problem, rows, live, True)
        kept, retry = np.empty(live.size, np.int64), np.empty(live.size, np.int64)
        going, retried = compiled.gauss_newton_verdict(
            live, np.einsum("nk,nk->n", residual, residual), constraint, reach, previous, last, scale,
            settled.view(np.uint8), *state, BALANCE_TOL, COST_TOL, STEP_TOL, kept, retry)
        if going < live.size:
            kept = kept[:going]
            live, residual, jacobian, constraint, balance = (live[kept], residual[kept], jacobian[kept],
                                                             constraint[kept], balance[kept])
        system, gradient = _kkt(jacobian, residual, balance, ~rows.taut[live], rows.mu[live])
        rhs = -np.concatenate([gradient, constraint], axis=1)
        step, singular = np.empty((live.size, 16)), np.empty(live.size, np.uint8)
        compiled.kkt_steps(system, rhs, step, singular)
        for k in np.flatnonzero(singular).tolist():  # a row's own: the others' steps do not depend on it
            step[k] = np.linalg.lstsq(system[k], rhs[k], rcond=None)[0]
        moving = np.empty(live.size + retried, np.int64)
        live = moving[:compiled.gauss_newton_advance(
            live, np.ascontiguousarray(step), retry[:retried], reach, scale, last, rows.steps, settled.view(np.uint8),
            *state, MAX_TURN_STEP, MAX_SHIFT_STEP * plant.moment_scale, STEP_TOL, moving)]
        if not live.size:
            break
    everything = np.arange(len(rows.sample))  # residuals and balance where the last steps left the rows
    residual, _, constraint, _ = _residuals(problem, rows, everything, False)
    rows.residuals, rows.cost = residual, np.sum(residual ** 2, axis=1)
    rows.converged = settled & (np.abs(constraint).max(axis=1) < BALANCE_TOL * reach)
    return rows

