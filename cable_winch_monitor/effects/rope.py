"""Rope-law effects: elastic stretch and the rope's own weight."""
from __future__ import annotations

import numpy as np

from ..model.estimator import States
from ..model.plantfile.plant import CABLE_NAMES, Plant
from .base import Effect, Parameter, RopeLaw, StackedConditions, relative, relative_bounds, span, weight


def _weight_per_span(plant: Plant) -> float:
    """m g per metre of the plant's span [N/m]: the size of a rope's weight per metre."""
    return weight(plant) / span(plant)


class RopeElasticity(Effect):
    """Hooke stretch of each rope: tau_i = EA / l_i * max(0, s_i - l_i) (seeds 000 and 004).

    Seeds 000 and 004 model a steel rope as a linear spring of axial stiffness EA (the
    free-length stiffness K = EA / L of seed 000, eq. 22). With it the tension
    distribution of four taut ropes is determinate: all four share the load, where rigid
    ropes leave one slack. Residual signature (missing from a rigid model): the rigid
    model predicts one rope slack (zero tension) and the other three overloaded, while
    every load pin reads a share; the error flips with the winches' synchronisation
    errors and the depth reads deeper than predicted by l * mg / (4 EA).
    """

    name = "rope_elasticity"
    title = "the ropes stretch elastically (Hooke, axial stiffness EA)"
    acts = "rope_law"
    # a quarter of m g stretches a rope by a strain between 1e-1 and 1e-6; 1e-3 by default
    parameters = (Parameter("EA", "N", relative(1000.0, weight), relative_bounds(2.5, 2.5e5, weight),
                            relative(200.0, weight), "axial stiffness of each rope"),)
    signature = "one rope predicted slack and the others overloaded while all four pins read a share"
    source = "seeds 000 (eq. 22, K = EA/L) and 004 (eqs. 14-28)"

    def rope(self, law: RopeLaw) -> RopeLaw:
        return RopeLaw(EA=self["EA"], weight=law.weight)


class RopeWeight(Effect):
    """The rope's own weight w per metre: the load pin at the head sheave carries it too.

    Tension grows along a hanging rope: at the top it is the platform's share plus the
    weight of the rope below, T_top = T_platform + w * (z_A - z_B) (the vertical span;
    a slack rope still hangs from its sheave). An elastic rope also stretches under its
    own weight by w l^2 / (2 EA), as if it were l + w l^2 / (2 EA) long. Residual
    signature: every load pin reads more than predicted, by an amount growing in
    proportion to the payout, the same for all four cables.
    """

    name = "rope_weight"
    title = "the ropes' own weight (the load pins read more than the platform carries)"
    acts = "rope_law"
    order = 10
    # at most m g per plant span of rope
    parameters = (Parameter("w", "N/m", relative(0.003, _weight_per_span), relative_bounds(0.0, 1.0, _weight_per_span),
                            relative(0.001, _weight_per_span), "rope weight per metre"),)
    signature = "all load pins read high by an amount proportional to the payout"
    source = "statics of a hanging rope; stretch as in seeds 000/004 with a linearly growing tension"

    def rope(self, law: RopeLaw) -> RopeLaw:
        return RopeLaw(EA=law.EA, weight=law.weight + self["w"])

    def measure_states(self, channels: dict[str, np.ndarray], states: States, plant: Plant,
                       conditions: StackedConditions) -> None:
        drop = np.maximum(plant.anchors[:, 2] - states.points_b[:, :, 2], 0.0)
        for i, name in enumerate(CABLE_NAMES):
            channels[f"tension_{name}"] = channels[f"tension_{name}"] + self["w"] * drop[:, i]

    def measure_gradients(self, gradients: dict[str, np.ndarray], channels: dict[str, np.ndarray], states: States,
                          plant: Plant, conditions: StackedConditions) -> None:
        # the drop falls as B_i rises: dB_z = dz + (w x R a_i)_z = dz + w_x (R a_i)_y - w_y (R a_i)_x
        hanging = (plant.anchors[:, 2] > states.points_b[:, :, 2]) * self["w"]
        arms = states.points_b - states.position[:, None, :]
        change = np.zeros(hanging.shape + (10,))
        change[..., 2], change[..., 3], change[..., 4] = -hanging, -hanging * arms[..., 1], hanging * arms[..., 0]
        for i, name in enumerate(CABLE_NAMES):
            gradients[f"tension_{name}"] = gradients[f"tension_{name}"] + change[:, i]
