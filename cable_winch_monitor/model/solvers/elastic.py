"""Equilibrium with elastic ropes: the minimum of potential plus strain energy.

Each rope is a unilateral Hooke spring: tension tau_i = EA_i / l_i * max(0, s_i - l_i)
for a span s_i and unstretched (paid-out) length l_i, zero when slack (seeds 000 and
004 treat the rope as such a spring). The equilibrium is then an unconstrained minimum
of m g z_C + sum 1/2 EA_i / l_i max(0, s_i - l_i)^2, found by Newton's method on the
gradient from the rigid solution, which is always close: the stretch is l * tau / EA.
With elastic ropes the tension distribution of four taut ropes is determinate, unlike
the rigid case where four taut ropes need l1 + l3 = l2 + l4 to the micrometre.
"""
from __future__ import annotations

import numpy as np

from ..plantfile.plant import Plant
from ..statics import load as loads
from ..statics.geometry import cross, rotation_from_vector, skew
from ..statics.result import Solution, SolveStatus, failed, guarded_solve, solved
from .energy import solve_energy

METHOD = "elastic"
MAX_STEPS = 50
TOL = 1e-11  # relative force and moment balance
ROUNDING_TOL = 1e-8  # accepted balance once Newton steps reach rounding level (very stiff ropes)


def solve_elastic(plant: Plant, lengths: object, axial_stiffness: object,
                  warm_start: Solution | None = None, load: np.ndarray | None = None) -> Solution:
    """Equilibrium of the platform on four elastic ropes of axial stiffness EA [N] each (scalar or 4),
    under `load` (model.load; None: gravity)."""
    wrench = loads.resolve(plant, load)
    ea = np.broadcast_to(np.asarray(axial_stiffness, dtype=float), (4,))
    if not np.all(np.isfinite(ea)) or np.any(ea <= 0.0):
        return failed(SolveStatus.INVALID_INPUT, f"rope axial stiffness EA must be finite and positive, got {ea}",
                      METHOD, np.full(4, np.nan))

    def from_rigid(array: np.ndarray) -> Solution:
        if warm_start is not None and warm_start.ok:
            warm = _newton(plant, array, ea, warm_start, wrench)
            if warm.ok:
                return warm
        rigid = solve_energy(plant, array, load=wrench)  # cold, or where the warm start failed (Newton across a kink)
        if not rigid.ok:
            return rigid  # a single elastic rope leaves the pose as indeterminate as a rigid one
        # Lowered by its ropes' static stretch, so that every taut rope pulls from the first step:
        # at the rigid pose itself the stretches are rounding errors of either sign.
        return _newton(plant, array, ea, rigid, wrench, sag=float(np.max(rigid.tensions * array / ea)))

    return guarded_solve(METHOD, lengths, from_rigid, loads.check(wrench))


def _newton(plant: Plant, lengths: np.ndarray, ea: np.ndarray, start: Solution, load: np.ndarray,
            sag: float = 0.0) -> Solution:
    """Newton on the force and moment balance under `load` from `start`'s pose, lowered by `sag` [m]."""
    assert start.rotation is not None and start.position is not None  # `start` is a solved pose
    rotation, position = start.rotation, start.position - np.array([0.0, 0.0, sag])
    stiffness = ea / lengths
    weight, scale = loads.magnitude(load), plant.moment_scale
    step_size = np.inf
    for step in range(MAX_STEPS):
        arms = plant.attachments @ rotation.T
        levers = arms - rotation @ plant.cog
        spans = position + arms - plant.anchors
        norms = np.linalg.norm(spans, axis=1)
        units = spans / norms[:, None]
        stretch = np.maximum(norms - lengths, 0.0)
        tensions = stiffness * stretch
        force = (units.T @ tensions - load[:3]) / weight
        moment = (cross(levers, units).T @ tensions - load[3:]) / (weight * scale)
        residual = np.concatenate([force, moment])
        if np.abs(residual).max() < TOL or (step_size < 1e-13 and np.abs(residual).max() < ROUNDING_TOL):
            return solved(plant, METHOD, lengths, rotation, position, tensions, tensions > 0.0, step,
                          load=load, stretch=stretch)
        jacobian = np.zeros((6, 6))
        for i in np.flatnonzero(stretch > 0.0):
            u, r, q = units[i], arms[i], levers[i]
            d_span = np.hstack([np.eye(3), -skew(r)])                       # dB_i / d(p, omega)
            d_unit = (np.eye(3) - np.outer(u, u)) / norms[i] @ d_span
            d_tension = stiffness[i] * u @ d_span
            jacobian[0:3] += (np.outer(u, d_tension) + tensions[i] * d_unit) / weight
            d_lever = np.hstack([np.zeros((3, 3)), -skew(q)])
            jacobian[3:6] += (np.outer(cross(q, u), d_tension) + tensions[i] * (
                -skew(u) @ d_lever + skew(q) @ d_unit)) / (weight * scale)
        if not np.any(stretch > 0.0):
            position = position - np.array([0.0, 0.0, 1e-3 * lengths.min()])
            continue
        delta = np.linalg.lstsq(jacobian, -residual, rcond=1e-14)[0]
        largest = max(np.abs(delta[3:6]).max() / 0.05, np.abs(delta[0:3]).max() / (0.05 * scale), 1.0)
        delta /= largest
        step_size = max(np.abs(delta[0:3]).max() / lengths.max(), np.abs(delta[3:6]).max())
        position = position + delta[0:3]
        rotation = rotation_from_vector(delta[3:6]) @ rotation
    return failed(SolveStatus.SOLVER_FAILED, "elastic solver: Newton did not converge", METHOD, lengths,
                  iterations=MAX_STEPS)
