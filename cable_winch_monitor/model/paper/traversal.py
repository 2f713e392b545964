"""Seed 002, 4.2: the Traversal Solving Algorithm (TSA), try-and-error over tension states.

(i)    guess (4.1): the level pose at the mean length, the even tensions of 3.2 on the taut set;
(ii)   four equal lengths (max - min <= EQUAL_LENGTH_TOL): the closed form of 3.2;
(iii)  one cable carrying the platform alone (3.1): pose indeterminate, reported as such;
(iv)   two taut cables, (v) three, (vi) adjacent equal lengths (3.3, planar), (vii) four.
A state is accepted when its equations (2), (3)-(6), (7) hold to within tolerances checked
here (not hybr's exit flag), the solved body is not the mirror image of the platform, every
taut tension is > 0 and every slack cable has |A_k B_k| <= l_k. The length tolerance is at
rounding level: near-degenerate inputs have two- or three-cable states that miss
admissibility by only 1e-10..1e-7 m, and a looser test would accept them.

One deviation: with adjacent lengths equal, (vi) is tried before (iv) and (v). At most one
state is admissible, so in exact arithmetic the order is immaterial, but there J^T is nearly
singular and a three-cable state overstretches its fourth cable by only 1e-13..1e-9 m,
too little to reject reliably; the planar solution, exact by symmetry, settles it.

Step (iii) generalises "the shortest cable": at any admissible pose
z_C >= A_k,z - (l_k + r_k) for every cable k, so a hang from cable j alone
(z_C = A_j,z - l_j - r_j) is admissible only for the cable with the smallest
l_j + r_j - A_j,z. The paper's shortest cable is the common case (the r_i differ by
centimetres to decimetres); both cables are checked when they differ.

The unknowns are B1, B2, B3, C and the taut tensions per mg; B4 is the affine combination
of them given by the body coordinates (B1 - B2 + B3 for the rectangle). Cable directions
are taken as (B_i - A_i) / l_i, equal to eq. (8)'s unit vectors wherever |A_i B_i| = l_i
holds, which keeps the equations polynomial and the Jacobian short.
"""
from __future__ import annotations

from itertools import combinations
from typing import Any

import numpy as np

from ..plantfile.plant import Plant
from ..statics import load as loads
from ..statics.geometry import cross, fit_rotation, skew, wrench_residual
from ..statics.result import Solution, SolveStatus, failed, guarded_solve, single_cable_result, solved
from .critical_lengths import describe, rotation_range
from .equal_lengths import even_tensions, level_pose, solve_equal_lengths
from .planar import solve_planar

EQUAL_LENGTH_TOL = 1e-9  # [m] lengths (or adjacent pairs) this close count as equal
LENGTH_TOL = 1e-13  # distance residual or overstretch allowed, relative to max(l_i, |CB_i|): rounding level
BALANCE_TOL = 1e-9  # wrench residual allowed, relative to mg and mg * max |CB_i|
TWO_CABLE_STATES = tuple(combinations(range(4), 2))
THREE_CABLE_STATES = tuple(combinations(range(4), 3))
PAIRS = tuple(combinations(range(4), 2))
E_Z = np.array([0.0, 0.0, 1.0])


class TautModel:
    """Eqs. (2), (3)-(6) and (7) of one tension state as F(x) = 0, x = (B1, B2, B3, C, tau_S / mg)."""

    def __init__(self, plant: Plant, lengths: np.ndarray, taut: tuple[int, ...]):
        body = np.vstack([plant.attachments[:3], plant.cog])
        weights = np.linalg.solve(np.vstack([body.T, np.ones(4)]), np.append(plant.attachments[3], 1.0))
        self.mix = np.vstack([np.eye(4)[:3], weights])  # B = mix @ P, P = (B1, B2, B3, C)
        self.distances = np.array([np.linalg.norm(body[p] - body[q]) for p, q in PAIRS])
        self.taut = list(taut)
        self.anchors, self.lengths = plant.anchors[self.taut], lengths[self.taut]
        self.scale = plant.moment_scale

    def residual(self, x: np.ndarray) -> np.ndarray:
        """Distances (|PQ|^2 - d^2) / 2d [m], then forces per mg and moments per mg max |CB_i|."""
        points, t = x[:12].reshape(4, 3), x[12:]
        gaps = points[[p for p, _ in PAIRS]] - points[[q for _, q in PAIRS]]
        spans = self.mix[self.taut] @ points - self.anchors
        units = spans / self.lengths[:, None]
        arms = self.mix[self.taut] @ points - points[3]
        return np.concatenate([
            (np.einsum("ij,ij->i", gaps, gaps) - self.distances ** 2) / (2.0 * self.distances),
            (np.einsum("ij,ij->i", spans, spans) - self.lengths ** 2) / (2.0 * self.lengths),
            t @ units + E_Z,
            t @ cross(arms, units) / self.scale,
        ])

    def jacobian(self, x: np.ndarray) -> np.ndarray:
        """dF/dx, analytic."""
        points, t = x[:12].reshape(4, 3), x[12:]
        n, mix = len(self.taut), self.mix[self.taut]
        spans = mix @ points - self.anchors
        units, arms = spans / self.lengths[:, None], mix @ points - points[3]
        out = np.zeros((12 + n, 12 + n))
        for row, (p, q) in enumerate(PAIRS):
            gap = (points[p] - points[q]) / self.distances[row]
            out[row, 3 * p:3 * p + 3], out[row, 3 * q:3 * q + 3] = gap, -gap
        out[6:6 + n, :12] = (mix[:, :, None] * units[:, None, :]).reshape(n, 12)
        out[6 + n:9 + n, :12] = np.kron((t / self.lengths) @ mix, np.eye(3))
        out[6 + n:9 + n, 12:] = units.T
        turn = (t / self.scale)[:, None, None] * (skew(arms) / self.lengths[:, None, None] - skew(units))
        moment = np.einsum("ik,iab->akb", mix, turn)
        moment[:, 3, :] += np.einsum("i,iab->ab", t / self.scale, skew(units))
        out[9 + n:, :12] = moment.reshape(3, 12)
        out[9 + n:, 12:] = cross(arms, units).T / self.scale
        return out

    def solve(self, guess: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
        """hybr (trust-region dogleg) from the guess: B (4, 3), C, tau_S per mg, evaluations."""
        from scipy.optimize import root  # imported on first use: scipy.optimize takes 0.4 s to load
        result = root(self.residual, guess, jac=self.jacobian, method="hybr", options={"xtol": 1e-13})
        points = result.x[:12].reshape(4, 3)
        return self.mix @ points, points[3], result.x[12:], int(result.nfev + result.njev)


def _admissible(plant: Plant, lengths: np.ndarray, points_b: np.ndarray, point_c: np.ndarray,
                tensions: np.ndarray, taut: np.ndarray, load: np.ndarray) -> bool:
    """The inequalities of 4.2 plus a residual check of eqs. (2), (3)-(6), (7) and handedness."""
    if not (np.all(np.isfinite(points_b)) and np.all(np.isfinite(point_c)) and np.all(np.isfinite(tensions))):
        return False
    tol = LENGTH_TOL * max(float(lengths.max()), plant.moment_scale)
    body, world = np.vstack([plant.attachments, plant.cog]), np.vstack([points_b, point_c])
    rigid = np.abs(np.linalg.norm(world[:, None] - world[None], axis=2) - np.linalg.norm(body[:, None] - body[None], axis=2))
    excess = np.linalg.norm(points_b - plant.anchors, axis=1) - lengths
    force, moment = wrench_residual(plant, points_b, point_c, tensions, load)
    handed = np.linalg.det(world[[1, 2, 4]] - world[0]) * np.linalg.det(body[[1, 2, 4]] - body[0])  # B1 B2 B3 C
    return bool(rigid.max() <= tol and np.all(np.abs(excess[taut]) <= tol) and np.all(excess[~taut] <= tol)
                and np.all(tensions[taut] > 0.0) and max(force, moment) <= BALANCE_TOL and handed > 0.0)


def _accept(plant: Plant, lengths: np.ndarray, method: str, points_b: np.ndarray, point_c: np.ndarray,
            tensions: np.ndarray, evaluations: int, step: str, load: np.ndarray) -> Solution:
    """The pose fitted to the solved points (body = attachments + cog) as a SOLVED Solution."""
    rotation, position = fit_rotation(np.vstack([plant.attachments, plant.cog]), np.vstack([points_b, point_c]))
    taut = tensions > 0.0
    names = ",".join(str(i + 1) for i in np.flatnonzero(taut))
    return solved(plant, method, lengths, rotation, position, tensions, taut, evaluations,
                  message=f"static equilibrium, taut cables {{{names}}} (seed 002 TSA step {step})", load=load,
                  step=step)


def _traverse(plant: Plant, lengths: np.ndarray, method: str, load: np.ndarray) -> Solution:
    """Steps (i)-(viii) of 4.2 on valid lengths, under a vertical load (tensions in units of its force)."""
    weight = loads.magnitude(load)
    if np.ptp(lengths) <= EQUAL_LENGTH_TOL:  # (ii)
        level = solve_equal_lengths(plant, lengths, method, load)
        if level is not None:
            return level
    shortest, lowest = int(np.argmin(lengths)), int(np.argmin(lengths + plant.cog_distances - plant.anchors[:, 2]))
    for cable in dict.fromkeys((shortest, lowest)):  # (iii)
        phi, critical = rotation_range(plant, lengths, cable)
        if phi:
            return single_cable_result(plant, method, lengths, cable, phi,
                                       {"critical_lengths": describe(critical, lengths)}, load)
    rotation, position = level_pose(plant, float(np.mean(lengths)))  # (i)
    guess_b, guess_c = position + plant.attachments @ rotation.T, position + rotation @ plant.cog
    even = even_tensions(plant, guess_b, guess_c, load)
    even = np.full(4, 0.25) if even is None else even / weight
    start = np.concatenate([guess_b[:3].ravel(), guess_c])
    evaluations = 0

    def attempt(taut: tuple[int, ...], step: str) -> Solution | None:
        nonlocal evaluations
        points_b, point_c, t, count = TautModel(plant, lengths, taut).solve(np.concatenate([start, even[list(taut)]]))
        evaluations += count
        tensions = np.zeros(4)
        tensions[list(taut)] = t * weight
        mask = np.isin(np.arange(4), taut)
        if _admissible(plant, lengths, points_b, point_c, tensions, mask, load):
            return _accept(plant, lengths, method, points_b, point_c, tensions, evaluations, step, load)
        return None

    planar = solve_planar(plant, lengths, EQUAL_LENGTH_TOL, load)  # (vi), ahead of (iv) and (v): see the docstring
    if planar is not None:
        evaluations += planar.evaluations
        if _admissible(plant, lengths, planar.points_b, planar.point_c, planar.tensions, np.ones(4, dtype=bool), load):
            return _accept(plant, lengths, method, planar.points_b, planar.point_c, planar.tensions, evaluations, "vi",
                           load)
    for states, step in ((TWO_CABLE_STATES, "iv"), (THREE_CABLE_STATES, "v")):
        for taut in states:
            found = attempt(taut, step)
            if found is not None:
                return found
    found = attempt((0, 1, 2, 3), "vii")
    if found is not None:
        return found
    return failed(SolveStatus.NO_EQUILIBRIUM, "no tension state accepted: from the level-pose guess of seed 002, "
                  "4.1, hybr found no equilibrium with positive tensions and slack cables within their lengths "
                  "for any two-, three- or four-cable state", method, lengths, iterations=evaluations)


def solve_traversal(plant: Plant, lengths: Any, *, method_name: str = "traversal",
                    load: np.ndarray | None = None) -> Solution:
    """Seed 002's TSA for four cable lengths [m] under `load` (model.load; None: gravity); never raises.

    The paper's algorithm is written for gravity: the load must be a vertical pull (gravity,
    or inertia along the shaft), else the result is INVALID_INPUT naming the energy solver.

    INVALID_INPUT for bad lengths, SINGLE_CABLE_INDETERMINATE with the rotation range phi,
    SOLVED with the pose, tensions [N] and taut = tension > 0, NO_EQUILIBRIUM when no state
    is accepted, SOLVER_FAILED on a numerical exception. `iterations` counts the residual
    and Jacobian evaluations of every hybr run.
    """
    wrench = loads.resolve(plant, load)
    problem = loads.check(wrench) or ("" if loads.is_vertical(wrench) else
                                      "seed 002's traversal takes a vertical load only; use the energy solver")
    return guarded_solve(method_name, lengths, lambda array: _traverse(plant, array, method_name, wrench), problem,
                         plant)
