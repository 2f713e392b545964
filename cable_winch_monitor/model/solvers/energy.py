"""Static equilibrium as the minimum of the platform's potential energy.

With rigid cables the stable equilibrium minimises the height of the centre of gravity
subject to |A_i B_i| <= l_i (the minimum-potential-energy principle of seed 003). The
Karush-Kuhn-Tucker multipliers of the length constraints are the cable tensions, the
inactive constraints are the slack cables. The solve has two parts:

* a Newton iteration on the KKT conditions of the taut set, changing the set one cable
  at a time: warm-started from the previous sample it is the fast path of the monitor
  (a few steps per sample); cold, it starts from the level pose;
* a global search (SLSQP over the six pose coordinates) that finds the minimum and so
  the taut set from any start, used where the iteration finds no admissible set; the
  iteration then polishes its result to machine precision.

A platform that can hang from one cable alone has no definite pose; that case is
recognised first with `plumb_hang`.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..paper.equal_lengths import level_pose
from ..paper.plumb_hang import PlumbHang, lowest_hang_cable
from ..plantfile.plant import Plant
from ..statics import load as loads
from ..statics.geometry import cross, rotation_from_vector, skew, structure_matrix
from ..statics.result import Solution, SolveStatus, failed, guarded_solve, single_cable_result, solved
from ..statics.tensions import balance_tensions
from . import compiled

METHOD = "energy"
NEWTON_MAX_STEPS = 15
NEWTON_TOL = 1e-12          # relative force/moment balance and length error [m]
ACTIVE_BAND = 1e-5          # [m] a cable this close to its length after the global search may be taut
SLACK_TOL = 1e-13           # relative to the plant's size: a slack cable may exceed its length by rounding only
TENSION_TOL = 1e-9          # relative to the load's force: smaller tensions are zero
ACTIVE_SET_ROUNDS = 12
MAX_TURN = 0.3            # [rad] largest turn of the platform the polish may make from its start


@dataclass
class _State:
    """Pose, active cables and normalised multipliers mu = tau / |f| during the solve, under `load`
    (the external wrench, see model.load; `scale` = |f|)."""

    rotation: np.ndarray
    position: np.ndarray
    active: np.ndarray
    mu: np.ndarray
    load: np.ndarray
    steps: int = 0

    @property
    def scale(self) -> float:
        return loads.magnitude(self.load)


def solve_energy(plant: Plant, lengths: object, warm_start: Solution | None = None,
                 load: np.ndarray | None = None) -> Solution:
    """Equilibrium for four cable lengths under `load` (model.load; None: gravity); never raises,
    the status says what happened."""
    wrench = loads.resolve(plant, load)
    reason = loads.check(wrench)
    return guarded_solve(METHOD, lengths, lambda array: _solve(plant, array, warm_start, wrench), reason, plant)


def _solve(plant: Plant, lengths: np.ndarray, warm_start: Solution | None, load: np.ndarray) -> Solution:
    if warm_start is not None and warm_start.ok:
        assert warm_start.rotation is not None and warm_start.position is not None  # a solved pose
        assert warm_start.taut is not None and warm_start.tensions is not None
        warm = _State(warm_start.rotation, warm_start.position, warm_start.taut.copy(),
                      warm_start.tensions / loads.magnitude(load), load)
        if _settle_active_set(plant, lengths, warm):
            result = _result(plant, lengths, warm)
            if len(result.taut_set) > 1:  # one taut cable: the single-cable test below decides
                return result
    single = _single_cable(plant, lengths, load)
    if single is not None:
        return single
    state = _level_start(plant, lengths, load)  # settled already where it is not None
    if state is not None:
        return _result(plant, lengths, state)
    state = _global_minimum(plant, lengths, load)
    if _settle_active_set(plant, lengths, state):
        return _result(plant, lengths, state)
    return failed(SolveStatus.SOLVER_FAILED, "energy solver: no admissible taut set found near the energy minimum",
                  METHOD, lengths, iterations=state.steps)


def _settle_active_set(plant: Plant, lengths: np.ndarray, state: _State) -> bool:
    """Newton on the KKT conditions, changing the taut set one cable at a time until admissible.

    Every taut set starts from the same pose and is tried once, so the iteration neither
    cycles nor drifts; a result that turned further than MAX_TURN from the start is a
    different configuration (crossed cables), not this sample's equilibrium. The sets are
    tried in the order they were proposed, the first set's proposals before theirs: four
    nearly compatible rigid ropes (the lab robot's) are the first set's last proposal, and
    depth first reached them after ten sets, breadth first after five.
    """
    start_rotation, start_position = state.rotation, state.position
    visited: set[tuple[bool, ...]] = set()
    pending: list[np.ndarray] = []
    for _ in range(ACTIVE_SET_ROUNDS):
        visited.add(tuple(state.active))
        converged = _newton(plant, lengths, state)
        turn = np.arccos(np.clip((np.trace(state.rotation @ start_rotation.T) - 1.0) / 2.0, -1.0, 1.0))
        if converged and turn < MAX_TURN and _admissible(plant, lengths, state):
            return True
        fresh = _next_active_sets(plant, lengths, state, converged)
        pending = list({tuple(c): c for c in pending + fresh if tuple(c) not in visited}.values())
        if not pending:
            return False
        state.rotation, state.position, state.active = start_rotation, start_position, pending.pop(0)
        state.mu = _multipliers(plant, state)
    return False


def _single_cable(plant: Plant, lengths: np.ndarray, load: np.ndarray) -> Solution | None:
    """The single-cable state if the lowest-hanging cable can carry the platform alone (a plumb
    hang: the load's force is taken as vertical, as gravity and inertia along the shaft are)."""
    cable = lowest_hang_cable(plant, lengths)
    hang = PlumbHang(plant, cable, lengths[cable])
    others = np.arange(4) != cable
    if np.any(lengths[others] < hang.shortest_spans()[others]):
        return None
    intervals = hang.rotation_range(lengths)
    if sum(hi - lo for lo, hi in intervals) <= 1e-9:
        return None
    rotation, position = hang.pose(0.0)
    return single_cable_result(plant, METHOD, lengths, cable, intervals,
                               {"B_hanging": position + rotation @ plant.attachments[cable],
                                "C": position + rotation @ plant.cog}, load)


def _level_start(plant: Plant, lengths: np.ndarray, load: np.ndarray) -> _State | None:
    """The minimum found from the level pose at the mean length (settled, tensions set), or None
    where it is not clear-cut.

    Winches pay out nearly in step, so the platform hangs close to level: from there the
    KKT iteration (with its taut-set exchanges and its limit on the turn) reaches the
    equilibrium in a few steps, without the global search. Where a slack cable touches its
    length within ACTIVE_BAND (four taut ropes, l1 + l3 = l2 + l4 to the micrometre), the
    global search decides the taut set, as it always has.
    """
    rotation, position = level_pose(plant, float(lengths.mean()))
    state = _State(rotation, position, np.arange(4) != int(np.argmax(lengths)), np.zeros(4), load)
    state.mu = _multipliers(plant, state)
    if not _settle_active_set(plant, lengths, state):
        return None
    _, _, _, norms = _geometry(plant, state)
    return state if np.array_equal(_touching(lengths, lengths - norms), state.active) else None


def _touching(lengths: np.ndarray, slack: np.ndarray) -> np.ndarray:
    """Cables whose span is within ACTIVE_BAND of their length (at least the tightest one)."""
    active = slack < ACTIVE_BAND * max(1.0, lengths.max() * 1e-3)
    if not active.any():
        active[np.argmin(slack)] = True
    return active


def _global_minimum(plant: Plant, lengths: np.ndarray, load: np.ndarray) -> _State:
    """SLSQP on the load's potential -f.C over (position, rotation vector) from the level pose at the
    shortest length (the height of C under gravity)."""
    pull = load[:3] / loads.magnitude(load)
    start = np.array([0.0, 0.0, -lengths.min(), 0.0, 0.0, 0.0])
    anchor_centre = plant.anchors.mean(axis=0)
    start[:2] = anchor_centre[:2]

    def pose(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return rotation_from_vector(x[3:]), x[:3]

    def left_jacobian(omega: np.ndarray) -> np.ndarray:
        angle = np.linalg.norm(omega)
        k = skew(omega)
        if angle < 1e-8:
            return np.eye(3) + 0.5 * k
        return np.eye(3) + (1 - np.cos(angle)) / angle**2 * k + (angle - np.sin(angle)) / angle**3 * (k @ k)

    def height(x: np.ndarray) -> float:
        rotation, position = pose(x)
        return float(-pull @ (position + rotation @ plant.cog))

    def height_gradient(x: np.ndarray) -> np.ndarray:
        rotation = rotation_from_vector(x[3:])
        return np.concatenate([-pull, left_jacobian(x[3:]).T @ cross(rotation @ plant.cog, -pull)])

    def slack(x: np.ndarray) -> np.ndarray:
        rotation, position = pose(x)
        return lengths - np.linalg.norm(position + plant.attachments @ rotation.T - plant.anchors, axis=1)

    def slack_jacobian(x: np.ndarray) -> np.ndarray:
        rotation, position = pose(x)
        arms = plant.attachments @ rotation.T
        spans = position + arms - plant.anchors
        units = spans / np.linalg.norm(spans, axis=1, keepdims=True)
        return -np.hstack([units, cross(arms, units) @ left_jacobian(x[3:])])

    from scipy.optimize import minimize  # imported on first use: scipy.optimize takes 0.4 s to load
    result = minimize(height, start, jac=height_gradient, method="SLSQP",
                      constraints={"type": "ineq", "fun": slack, "jac": slack_jacobian},
                      options={"maxiter": 500, "ftol": 1e-10})
    rotation, position = pose(result.x)
    state = _State(rotation, position, _touching(lengths, slack(result.x)), np.zeros(4), load, steps=int(result.nit))
    state.mu = _multipliers(plant, state)
    return state


def _geometry(plant: Plant, state: _State) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Arms r_i = R b_i, arm of C, spans A_i B_i and their lengths."""
    arms = plant.attachments @ state.rotation.T
    arm_c = state.rotation @ plant.cog
    spans = state.position + arms - plant.anchors
    return arms, arm_c, spans, np.linalg.norm(spans, axis=1)


def _multipliers(plant: Plant, state: _State) -> np.ndarray:
    """mu = tau / |f| from the wrench balance on the active cables."""
    _, arm_c, _, _ = _geometry(plant, state)
    points_b = state.position + plant.attachments @ state.rotation.T
    structure = structure_matrix(plant, points_b, state.position + arm_c)
    mu = np.zeros(4)
    mu[state.active] = balance_tensions(structure[:, state.active], state.load) / state.scale
    return mu


def _newton(plant: Plant, lengths: np.ndarray, state: _State) -> bool:
    """Newton's method on the KKT conditions of the active set; True when converged.

    Unknowns: position, a rotation increment (applied on the left) and mu of the active
    cables. Equations: force and moment balance about C and |A_i B_i| = l_i. Two or three
    taut cables make a square regular system, solved exactly; otherwise steps are
    least-squares solutions of minimum norm, so a redundant set (four equal lengths) still
    converges in pose; its tensions are settled afterwards by `balance_tensions`. In C
    (`compiled.newton_taut_set`, the batched solver's, on one row): a step is some forty
    numpy calls on 3 x 3 arrays.
    """
    idx = np.flatnonzero(state.active)
    rotation, position = state.rotation[None].copy(), state.position[None].copy()
    mu, steps, converged = state.mu[None].copy(), np.zeros(1, np.int64), np.zeros(1, np.uint8)
    tolerance = np.array([NEWTON_TOL * max(1.0, lengths.max() * 1e-2)])
    compiled.newton_taut_set(np.ascontiguousarray(lengths, dtype=float)[None], rotation, position, mu,
                             (state.load / state.scale)[None], steps, idx.astype(np.int64), plant.attachments, plant.cog,
                             plant.anchors, plant.moment_scale, tolerance, NEWTON_MAX_STEPS, converged, 0.2,
                             0.2 * plant.moment_scale, minimum_norm=idx.size not in (2, 3))
    state.rotation, state.position, state.mu = rotation[0], position[0], mu[0]
    state.steps += int(steps[0])
    return bool(converged[0])


def _admissible(plant: Plant, lengths: np.ndarray, state: _State) -> bool:
    """Tensions of taut cables >= 0 and slack cables within their length."""
    state.mu = _multipliers(plant, state)
    _, _, _, norms = _geometry(plant, state)
    rounding = SLACK_TOL * max(lengths.max(), plant.moment_scale)
    slack_ok = np.all(norms[~state.active] <= lengths[~state.active] + rounding)
    return bool(slack_ok and np.all(state.mu[state.active] >= -TENSION_TOL))


def _next_active_sets(plant: Plant, lengths: np.ndarray, state: _State, converged: bool) -> list[np.ndarray]:
    """Taut sets to try next, best guess first.

    Converged with a negative tension: release that cable. Converged with a slack cable
    overstretched: take it up in exchange for one of the taut cables, ranked by how well
    each set balances the weight with tensions >= 0 at the current pose (a linear check,
    far cheaper than a Newton run on a set that cannot hold), or in addition to them
    (first when fewer than three are taut). Not
    converged (the set cannot reach all its lengths at once): release one cable, the
    least loaded first.
    """
    _, _, _, norms = _geometry(plant, state)
    active = np.flatnonzero(state.active)
    by_load = active[np.argsort(state.mu[active])]

    def toggled(*cables: int) -> np.ndarray:
        candidate = state.active.copy()
        candidate[list(cables)] = ~candidate[list(cables)]
        return candidate

    if not converged:
        return [toggled(k) for k in by_load] if active.size > 1 else []
    if state.mu[active].min() < -TENSION_TOL and active.size > 1:
        return [toggled(by_load[0])]
    overstretch = np.where(state.active, -np.inf, norms - lengths)
    if overstretch.max() <= 0.0:
        return []
    cable = int(np.argmax(overstretch))
    structure = structure_matrix(plant, state.position + plant.attachments @ state.rotation.T,
                                 state.position + state.rotation @ plant.cog)
    swaps = sorted((toggled(cable, k) for k in by_load), key=lambda c: _balance_misfit(structure[:, c], state.load))
    # Four taut rigid ropes need l1 + l3 = l2 + l4 to the micrometre: from three, exchange first.
    return swaps + [toggled(cable)] if active.size >= 3 else [toggled(cable)] + swaps


def _balance_misfit(structure: np.ndarray, wrench: np.ndarray) -> float:
    """How far these cables are from holding the wrench at this pose with tensions >= 0."""
    tensions = np.linalg.lstsq(structure, wrench, rcond=None)[0]
    scale = float(np.linalg.norm(wrench))
    return float(np.linalg.norm(structure @ tensions - wrench)) / scale + max(0.0, -tensions.min()) / scale


def _result(plant: Plant, lengths: np.ndarray, state: _State) -> Solution:
    tensions = np.where(state.active, state.mu, 0.0) * state.scale
    taut = tensions > TENSION_TOL * state.scale
    tensions = np.where(taut, tensions, 0.0)
    return solved(plant, METHOD, lengths, state.rotation, state.position, tensions, taut, state.steps,
                  load=state.load)
