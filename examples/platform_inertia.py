"""A physical effect written outside the package: the platform's inertia when the winches accelerate.

Use it with `--effect-module examples/platform_inertia.py`, or list the file under
`plant.effect_modules` in a plant file.
"""
from __future__ import annotations

import numpy as np

from cable_winch_monitor.effects import Effect, Parameter


class PlatformInertia(Effect):
    """The platform follows the winches' payout acceleration a (> 0 downward): the ropes carry
    m (g - k a) instead of m g (Newton's second law on the platform; k = 1 when the platform
    follows the payout rigidly). Residual signature: every load pin reads low while the
    winches accelerate a lowering or brake a hoist, high in the opposite phases, in
    proportion to the acceleration; nothing while the speed is constant."""

    name = "platform_inertia"
    title = "the platform's inertia: the ropes carry m (g - a) while the winches accelerate or brake"
    acts = "load"
    parameters = (Parameter("k", "-", 0.0, (-2.0, 3.0), 0.2, "share of the payout acceleration the platform follows"),)
    signature = "all load pins off in proportion to the payout acceleration"
    source = "Newton's second law on the platform"

    def load(self, wrench: np.ndarray, plant, conditions) -> np.ndarray:
        acceleration = self["k"] * conditions.acceleration
        return wrench + plant.mass * acceleration * np.array([0.0, 0.0, 1.0, 0.0, 0.0, 0.0])
