"""Head-sheave effects: the tangent point moves with the rope angle; friction between rope and pin."""
from __future__ import annotations

import numpy as np

from ..model.conditions import Conditions, StackedConditions
from ..model.estimator import States
from ..model.plantfile.plant import CABLE_NAMES, Plant
from .base import Effect, Parameter, relative, relative_bounds, span

MIN_SHARE = 0.05  # fraction of samples needed in each direction of motion to identify friction


def radial_planes(plant: Plant) -> np.ndarray:
    """Horizontal unit vectors from the shaft axis through each anchor: the sheave planes' direction
    (winches stand outside the shaft, each sheave turns the rope towards its winch)."""
    radial = plant.anchors[:, :2] - plant.shaft_centre
    radial /= np.linalg.norm(radial, axis=1, keepdims=True)
    return np.column_stack([radial, np.zeros(4)])


class SheaveGeometry(Effect):
    """Head sheaves of radius r: the rope leaves each sheave at a tangent point that moves with its angle.

    The plant's A_i is the tangent point of a vertical rope; the sheave centre is
    O_i = A_i + r n_i (n_i horizontal, towards the winch). A rope inclined by phi_i in the
    sheave plane (towards the winch positive) leaves at T_i = O_i - r (cos phi_i n_i +
    sin phi_i z) and wraps r phi_i more rope on the sheave, so the free span is
    l_i - r phi_i. phi_i solves p_n cos phi + p_z sin phi = -r for p = B_i - O_i (tangent
    condition); the out-of-plane (fleet) angle is ignored. Solved by fixed-point
    iteration on the pose. Residual signature: errors growing with the platform's tilt
    and swing (large synchronisation errors), shrinking with the payout.
    """

    name = "sheave_geometry"
    title = "the head sheaves' radius moves the rope's tangent point with its angle"
    acts = "geometry"
    parameters = (Parameter("r", "m", relative(0.07, span), relative_bounds(0.0, 0.35, span), relative(0.015, span),
                            "head-sheave radius (to the rope axis)"),)
    signature = "errors that grow with tilt and swing and fall with the payout"
    source = "geometry of a rope wrapping a pulley (seed 000, Fig. 3; seed 004, eqs. 3-9)"

    def refine_states(self, plant: Plant, anchors: np.ndarray, lengths: np.ndarray,
                      states: States) -> tuple[np.ndarray, np.ndarray]:
        r = self["r"]
        planes = radial_planes(plant)
        centres = anchors + r * planes
        p = states.points_b - centres
        p_n, p_z = np.sum(p * planes, axis=-1), p[..., 2]
        radius, psi = np.hypot(p_n, p_z), np.arctan2(p_z, p_n)
        opening = np.arccos(np.clip(-r / radius, -1.0, 1.0))
        candidates = (np.stack([psi + opening, psi - opening]) + np.pi) % (2.0 * np.pi) - np.pi
        phi = np.where(np.abs(candidates[0]) <= np.abs(candidates[1]), candidates[0], candidates[1])
        tangent = centres - r * (np.cos(phi)[..., None] * planes + np.sin(phi)[..., None] * np.array([0.0, 0.0, 1.0]))
        return tangent, lengths - r * phi


class SheaveFriction(Effect):
    """Capstan friction between the rope and the load pin's sheave (Euler-Eytelwein, seeds 000 and 004).

    Over a wrap angle theta the tension changes by e^{mu theta} (seed 004, eqs. 6-9;
    seed 000, eq. 5): the load pin reads T e^{+mu theta} while the winch hauls in (the
    rope slips towards the winch against friction) and T e^{-mu theta} while it pays
    out; at rest the rope keeps the slip state of its last motion. Residual signature:
    tension errors of opposite sign when lowering and hoisting, proportional to the
    tension, jumping when the direction of motion changes.
    """

    name = "sheave_friction"
    title = "friction on the sheave: the load pins read high when hoisting and low when lowering"
    acts = "measurement"
    order = 20
    parameters = (Parameter("mu", "-", 0.05, (0.0, 0.5), 0.01, "rope-sheave friction coefficient"),
                  Parameter("wrap", "rad", float(np.pi / 2), (0.0, 2.0 * np.pi), 0.1,
                            "wrap angle between the platform side and the pin", fit=False))
    signature = "tension error changes sign with the direction of motion, proportional to the tension"
    source = "seeds 000 (eq. 5) and 004 (eqs. 6-9): Euler-Eytelwein T2 = T1 e^{mu theta}"

    def measure_states(self, channels: dict[str, np.ndarray], states: States, plant: Plant,
                       conditions: StackedConditions) -> None:
        factors = self._factors(conditions)
        for i, name in enumerate(CABLE_NAMES):
            channels[f"tension_{name}"] = channels[f"tension_{name}"] * factors[:, i]

    def measure_gradients(self, gradients: dict[str, np.ndarray], channels: dict[str, np.ndarray], states: States,
                          plant: Plant, conditions: StackedConditions) -> None:
        factors = self._factors(conditions)
        for i, name in enumerate(CABLE_NAMES):
            gradients[f"tension_{name}"] = gradients[f"tension_{name}"] * factors[:, i, None]

    def _factors(self, conditions: StackedConditions) -> np.ndarray:
        """(n, 4) what each pin reads per newton of the rope's tension: e^{-mu theta} paying out, e^{+mu theta}
        hauling in."""
        return np.exp(-conditions.direction * self["mu"] * self["wrap"])

    def warnings(self, conditions: list[Conditions]) -> list[str]:
        directions = np.array([c.direction for c in conditions]) if conditions else np.zeros((0, 4))
        share_out, share_in = np.mean(directions > 0) if directions.size else 0.0, \
            np.mean(directions < 0) if directions.size else 0.0
        if min(share_out, share_in) < MIN_SHARE:
            return [f"sheave_friction: the bag moves the ropes in one direction only (paying out {share_out:.0%}, "
                    f"hauling in {share_in:.0%} of samples): mu cannot be told apart from a tension scale "
                    "(payload_mass, tension_sensor_bending); record a lowering and a hoist"]
        return []
