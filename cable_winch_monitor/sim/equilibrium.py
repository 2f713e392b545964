"""The simulator's own equilibrium: force and moment balance of the platform, solved by root finding.

A formulation of its own, sharing no code with the package's solvers, so that data made
with it tests them rather than repeating them. For a guessed taut set S the unknowns are
the pose (position of the platform origin, roll-pitch-yaw angles) and the tension of each
rope in S; the equations are

    sum_S T_i u_i + F = 0,   sum_S (B_i - C) x T_i u_i + M = 0        (6 balance equations)
    |A_i B_i| = f_i (1 + T_i / EA + w f_i c_i / (2 EA))   for i in S   (one per taut rope)

with u_i the unit vector from B_i towards its anchor, (F, M) the external load (force,
and moment about the centre of gravity C), f_i the free (unstretched) rope length, c_i
the rope's vertical direction cosine, w its weight per metre (own-weight stretch) and
EA = inf for rigid ropes. `scipy.optimize.root` (Powell's hybrid method) solves them.
S is accepted when admissible: every tension >= 0 and every other rope's span no longer
than its length. Along a trajectory the previous taut set and state are the start (two
to three iterations); only when that set stops being admissible are the other sets
tried, and of the admissible ones the lowest energy is taken.

With pulleys (head sheaves, swivelling lab pulleys) the anchor is the point where the rope
leaves its pulley: it depends on the rope's direction, and the wrapped arc shortens the free
length (`sim.pulleys`).
"""
from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import root

from .pulleys import Pulleys, pulley_exits

TENSION_TOL = 1e-9   # [fraction of the weight] a tension this far below zero is zero (rounding)
LENGTH_TOL = 1e-8    # [m] a slack span this far beyond its length is at its length (rounding)
BALANCE_TOL = 1e-9   # largest accepted scaled residual
ROUNDING = 1e-13     # a scaled residual this small is rounding: solved
FD_STEP = 1e-7       # relative finite-difference step of the Jacobian
MAX_EVALUATIONS = 100
SETS = tuple(tuple(s) for k in (4, 3, 2) for s in itertools.combinations(range(4), k))
MANY = tuple(s for s in SETS if len(s) > 2)  # tried first when cold; two taut ropes only if none of these holds


@dataclass(frozen=True)
class Rig:
    """The mechanism as the truth sees it: anchors A_i (shaft), attachments B_i and centre of gravity C
    (platform frame), rope stiffness EA (None: rigid) and weight w [N/m], and the pulleys the ropes wrap
    (None: the ropes leave from the anchors)."""

    anchors: np.ndarray
    attachments: np.ndarray
    cog: np.ndarray
    weight_scale: float        # [N] scale of the equations (the nominal weight)
    lever_scale: float         # [m] scale of the moment equations
    EA: float | None = None
    rope_weight: float = 0.0
    pulleys: Pulleys | None = None


@dataclass(frozen=True)
class State:
    """An equilibrium: pose, taut set and tensions at the platform, where each rope leaves its sheave."""

    position: np.ndarray        # platform origin in shaft [m]
    angles: np.ndarray          # roll, pitch, yaw [rad] (fixed axes x-y-z)
    rotation: np.ndarray
    taut: np.ndarray            # bool (4,)
    tensions: np.ndarray        # [N] at B_i
    points_b: np.ndarray
    point_c: np.ndarray
    exits: np.ndarray           # where each rope leaves its pulley (the anchor without pulleys)
    spans: np.ndarray           # |exit_i B_i| [m]
    free_lengths: np.ndarray    # unstretched rope length below the exit point [m]
    evaluations: int            # residual evaluations of the accepted root find


class NoEquilibrium(RuntimeError):
    """No taut set of two or more ropes is admissible (the platform hangs from one rope, or worse)."""


def rotations(angles: np.ndarray) -> np.ndarray:
    """R = Rz(yaw) Ry(pitch) Rx(roll) for stacked angles (m, 3) -> (m, 3, 3)."""
    (cr, cp, cy), (sr, sp, sy) = np.cos(angles).T, np.sin(angles).T
    out = np.empty((len(angles), 3, 3))
    out[:, 0, 0], out[:, 0, 1], out[:, 0, 2] = cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr
    out[:, 1, 0], out[:, 1, 1], out[:, 1, 2] = sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr
    out[:, 2, 0], out[:, 2, 1], out[:, 2, 2] = -sp, cp * sr, cp * cr
    return out


def _moment(levers: np.ndarray, pulls: np.ndarray) -> np.ndarray:
    """sum over ropes of levers x pulls, for stacked (m, k, 3) arrays (np.cross is slow on small ones)."""
    turned = levers[..., [1, 2, 0]] * pulls[..., [2, 0, 1]] - levers[..., [2, 0, 1]] * pulls[..., [1, 2, 0]]
    return turned.sum(axis=1)


def rope_exits(rig: Rig, points_b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where each rope leaves for the platform, and the rope its pulley holds [m], for points B (..., 4, 3)."""
    if rig.pulleys is None:
        return np.broadcast_to(rig.anchors, points_b.shape), np.zeros(points_b.shape[:-1])
    exits, theta = pulley_exits(rig.pulleys, rig.anchors, points_b)
    return exits, rig.pulleys.radius * theta


class _Equations:
    """Balance and length equations of one taut set for stacked unknowns (m, 6 + k)."""

    def __init__(self, rig: Rig, lengths: np.ndarray, load: np.ndarray, taut: tuple[int, ...]):
        self.rig, self.lengths, self.taut = rig, lengths, list(taut)
        self.compliance = 0.0 if rig.EA is None else 1.0 / rig.EA
        self.scaled_load = np.concatenate([load[:3] / rig.weight_scale,
                                           load[3:] / (rig.weight_scale * rig.lever_scale)])
        self.last: tuple[bytes, np.ndarray] | None = None
        self.last_jacobian: tuple[bytes, np.ndarray] | None = None

    def geometry(self, x: np.ndarray) -> dict[str, np.ndarray]:
        rig = self.rig
        rotation = rotations(x[:, 3:6])
        points_b = x[:, None, 0:3] + rig.attachments @ np.swapaxes(rotation, -1, -2)
        point_c = x[:, 0:3] + rotation @ rig.cog
        exits, wrapped = rope_exits(rig, points_b)
        ropes = exits - points_b
        spans = np.sqrt(np.einsum("...i,...i->...", ropes, ropes))
        free = self.lengths - wrapped
        # the span a rope reaches at zero tension at B: its own weight stretches it (vertical share)
        hanging = free * (1.0 + (0.5 * self.compliance * rig.rope_weight) * free * ropes[..., 2] / spans) \
            if self.compliance and rig.rope_weight else free
        return {"rotation": rotation, "points_b": points_b, "point_c": point_c, "exits": exits, "spans": spans,
                "ropes": ropes, "free": free, "hanging": hanging}

    def residual(self, x: np.ndarray) -> np.ndarray:
        rig, taut = self.rig, self.taut
        g = self.geometry(x)
        share = x[:, 6:]                                                  # T_i / weight_scale, i in S
        pulls = (share / g["spans"][:, taut])[..., None] * g["ropes"][:, taut]
        levers = g["points_b"][:, taut] - g["point_c"][:, None]
        balance = np.concatenate([pulls.sum(axis=1), _moment(levers, pulls) / rig.lever_scale], axis=1)
        free = g["free"][:, taut]
        stretch = (self.compliance * rig.weight_scale) * share * free
        lengths = (g["spans"][:, taut] - g["hanging"][:, taut] - stretch) / free
        return np.concatenate([balance + self.scaled_load, lengths], axis=1)

    def function(self, x: np.ndarray) -> np.ndarray:
        """The residual of one set of unknowns; exactly zero once it is at rounding level, which ends
        Powell's method there (it has no residual tolerance and would go on halving its step). The
        last value is kept: root evaluates its start twice (a shape check)."""
        key = x.tobytes()
        if self.last is None or self.last[0] != key:
            residual = self.residual(x[None])[0]
            self.last = key, residual if np.abs(residual).max() > ROUNDING else np.zeros_like(residual)
        return self.last[1]

    def jacobian(self, x: np.ndarray) -> np.ndarray:
        """Forward differences, all columns in one stacked evaluation (kept, as root checks its shape first)."""
        key = x.tobytes()
        if self.last_jacobian is None or self.last_jacobian[0] != key:
            steps = FD_STEP * np.maximum(np.abs(x), 1.0)
            values = self.residual(np.vstack([x, x + np.diag(steps)]))
            self.last_jacobian = key, ((values[1:] - values[0]) / steps[:, None]).T
        return self.last_jacobian[1]


def solve_set(rig: Rig, lengths: np.ndarray, load: np.ndarray, taut: tuple[int, ...],
              start: np.ndarray) -> tuple[State | None, float]:
    """The equilibrium with exactly the ropes `taut` taut, from unknowns `start` (pose, then tensions);
    None when the root find fails or the result is not admissible. Second: its energy."""
    equations = _Equations(rig, lengths, load, taut)
    found = root(equations.function, start, jac=equations.jacobian, method="hybr",
                 options={"xtol": 1e-10, "maxfev": MAX_EVALUATIONS})
    x = found.x
    if not np.all(np.isfinite(x)) or np.abs(equations.function(x)).max() > BALANCE_TOL:
        return None, np.inf
    g = {k: np.broadcast_to(v, (1,) + np.shape(v)[-2:])[0] if k == "exits" else v[0]
         for k, v in equations.geometry(x[None]).items()}
    tensions = np.zeros(4)
    tensions[list(taut)] = x[6:] * rig.weight_scale
    slack = [i for i in range(4) if i not in taut]
    if tensions.min() < -TENSION_TOL * rig.weight_scale or \
            np.any(g["spans"][slack] > g["hanging"][slack] + LENGTH_TOL):
        return None, np.inf
    tensions = np.maximum(tensions, 0.0)
    energy = -float(load[:3] @ g["point_c"])
    if rig.EA is not None:
        energy += float(np.sum(tensions ** 2 * g["free"]) / (2.0 * rig.EA))
    state = State(position=x[0:3], angles=x[3:6], rotation=g["rotation"], taut=tensions > 0.0,
                  tensions=tensions, points_b=g["points_b"], point_c=g["point_c"], exits=np.array(g["exits"]),
                  spans=g["spans"], free_lengths=g["free"], evaluations=int(found.nfev))
    return state, energy


def imbalance(state: State, load: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Resultant force [N] and moment about C [N m] of the ropes and the load on a state (zero in balance)."""
    pulls = (state.tensions / state.spans)[:, None] * (state.exits - state.points_b)
    return pulls.sum(axis=0) + load[:3], _moment((state.points_b - state.point_c)[None], pulls[None])[0] + load[3:]


def _level(rig: Rig, lengths: np.ndarray, taut: tuple[int, ...]) -> np.ndarray:
    """Unknowns of the level pose hanging the mean length below the anchors, the weight shared evenly."""
    position = rig.anchors.mean(axis=0) - rig.attachments.mean(axis=0) - np.array([0.0, 0.0, lengths.mean()])
    return np.concatenate([position, np.zeros(3), np.full(len(taut), 1.0 / len(taut))])


def _unknowns(state: State, taut: tuple[int, ...], weight_scale: float) -> np.ndarray:
    """A state's pose and the tensions of the ropes `taut` as unknowns (even shares where not all pull)."""
    shares = state.tensions[list(taut)] / weight_scale
    if not np.all(shares > 0.0):
        shares = np.full(len(taut), 1.0 / len(taut))
    return np.concatenate([state.position, state.angles, shares])


class Trajectory:
    """Equilibria along a motion, each warm-started from the ones before.

    The previous taut set is tried first, from the previous two states extrapolated to the new
    time; if it is no longer admissible, the sets one rope away, then the others; with no
    history (or when those all fail), every set from the level pose, three and four taut
    ropes before two. Of the admissible sets of a group the one of lowest energy is taken.
    """

    def __init__(self, rig: Rig):
        self.rig = rig
        self.history: list[tuple[float, State]] = []

    def _predicted(self, t: float, lengths: np.ndarray) -> np.ndarray:
        (t1, last), taut = self.history[-1], tuple(np.flatnonzero(self.history[-1][1].taut).tolist())
        x1 = _unknowns(last, taut, self.rig.weight_scale)
        if len(self.history) == 2 and np.array_equal(self.history[0][1].taut, last.taut) and t1 > self.history[0][0]:
            t2, before = self.history[0]
            return x1 + (x1 - _unknowns(before, taut, self.rig.weight_scale)) * (t - t1) / (t1 - t2)
        x1[2] -= float(np.mean(lengths - last.free_lengths))
        return x1

    def __call__(self, t: float, lengths: np.ndarray, load: np.ndarray) -> State:
        """The stable equilibrium at time t [s] for rope lengths [m] under `load` (force [N], moment about C
        [N m], shaft frame); raises NoEquilibrium."""
        state = self._solve(t, np.asarray(lengths, dtype=float), np.asarray(load, dtype=float))
        self.history = (self.history + [(t, state)])[-2:]
        return state

    def _solve(self, t: float, lengths: np.ndarray, load: np.ndarray) -> State:
        rig = self.rig
        groups: list[tuple[Sequence[tuple[int, ...]], State | None]] = [(MANY, None), (SETS[len(MANY):], None)]
        if self.history:
            last = self.history[-1][1]
            taut = tuple(np.flatnonzero(last.taut).tolist())
            state, _ = solve_set(rig, lengths, load, taut, self._predicted(t, lengths))
            if state is not None:
                return state
            near = [s for s in SETS if len(set(s) ^ set(taut)) <= 2 and s != taut]
            groups = [(near, last), ([s for s in SETS if s not in near and s != taut], last)] + groups
        for sets, start in groups:
            found = [solve_set(rig, lengths, load, s, _level(rig, lengths, s) if start is None
                               else _unknowns(start, s, rig.weight_scale)) for s in sets]
            admissible = [(energy, k) for k, (state, energy) in enumerate(found) if state is not None]
            if admissible:
                best = found[min(admissible)[1]][0]
                assert best is not None  # admissible
                return best
        raise NoEquilibrium("no taut set of two or more ropes is admissible: the platform hangs from one rope "
                            f"or the lengths {np.round(lengths, 4).tolist()} admit no equilibrium")


def equilibrium(rig: Rig, lengths: np.ndarray, load: np.ndarray) -> State:
    """The stable equilibrium for rope lengths [m] under `load`, solved cold (every taut set)."""
    return Trajectory(rig)(0.0, lengths, load)
