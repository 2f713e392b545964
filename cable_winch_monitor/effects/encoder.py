"""Geometry effects of the winch encoders: scale (drum radius, layer build-up) and zero offset."""
from __future__ import annotations

import numpy as np

from ..model.conditions import Conditions, StackedConditions
from .base import Bounds, Effect, Number, Parameter, relative, relative_bounds, span


def _per_winch(prefix: str, unit: str, bounds: Bounds, scale: Number, doc: str) -> tuple[Parameter, ...]:
    return tuple(Parameter(f"{prefix}_{i}", unit, 0.0, bounds, scale, f"{doc}, winch {i}") for i in range(1, 5))


class EncoderScale(Effect):
    """A winch reports l but pays out (1 + k_i) l: its drum radius or rope layer differs from the setting.

    True unstretched length l_true = (1 + k_i) * l_reported. Residual signature: a
    length error growing with the payout, so tilt (roll/pitch), depth and the tension
    share drift away from the model as the platform is lowered, differently per cable.
    """

    name = "encoder_scale"
    title = "the winch encoders' scale is off (drum radius or rope layer)"
    acts = "geometry"
    parameters = _per_winch("k", "-", (-0.1, 0.1), 1.0e-4, "relative payout scale error")
    signature = "tilt, depth and tension share drift in proportion to the payout"
    source = "drum kinematics: payout = drum angle * effective radius"

    def lengths(self, lengths: np.ndarray, conditions: Conditions) -> np.ndarray:
        return self._true(lengths)

    def lengths_states(self, lengths: np.ndarray, conditions: StackedConditions) -> np.ndarray:
        return self._true(lengths)

    def _true(self, lengths: np.ndarray) -> np.ndarray:
        """The true lengths of one row (4,) or many (N, 4): the same scale for every sample."""
        return lengths * (1.0 + np.array([self[f"k_{i}"] for i in range(1, 5)]))


class EncoderOffset(Effect):
    """A winch's zero is off by d_i: l_true = l_reported + d_i.

    Residual signature: constant tilt and depth errors and a constant redistribution of
    the tension among the ropes, independent of the payout.
    """

    name = "encoder_offset"
    title = "the winch encoders' zero is off"
    acts = "geometry"
    parameters = _per_winch("d", "m", relative_bounds(-0.25, 0.25, span), relative(0.001, span), "length zero offset")
    signature = "constant tilt, depth and tension-share errors at every payout"
    source = "encoder zeroing"

    def lengths(self, lengths: np.ndarray, conditions: Conditions) -> np.ndarray:
        return self._true(lengths)

    def lengths_states(self, lengths: np.ndarray, conditions: StackedConditions) -> np.ndarray:
        return self._true(lengths)

    def _true(self, lengths: np.ndarray) -> np.ndarray:
        """The true lengths of one row (4,) or many (N, 4): the same offsets for every sample."""
        return lengths + np.array([self[f"d_{i}"] for i in range(1, 5)])
