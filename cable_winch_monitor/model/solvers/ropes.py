"""The rope law as the estimator needs it: a taut rope's unstretched length from its span and tension.

Rigid ropes (EA None) are as long as their span. Elastic ropes follow Hooke with the
stiffness EA / L of the paid-out length L, and stretch under their own weight w [N/m]
as if they were l + w l^2 / (2 EA) long (the law effects.model solves with):
span = L (1 + tau / EA) with L = l + w l^2 / (2 EA).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Ropes:
    """Axial stiffness EA [N] of the four ropes ((4,), or None for rigid ropes) and their weight w [N/m]."""

    axial_stiffness: np.ndarray | None = None
    weight: float = 0.0

    @classmethod
    def of(cls, axial_stiffness: object = None, weight: float = 0.0) -> Ropes:
        """Ropes from a scalar or per-rope EA (None: rigid); ValueError names what is wrong."""
        if axial_stiffness is None:
            return cls(None, 0.0)
        ea = np.broadcast_to(np.asarray(axial_stiffness, dtype=float), (4,)).copy()
        if not np.all(np.isfinite(ea)) or np.any(ea <= 0.0):
            raise ValueError(f"rope axial stiffness EA must be finite and positive, got {ea}")
        if not (np.isfinite(weight) and weight >= 0.0):
            raise ValueError(f"rope weight must be finite and non-negative, got {weight}")
        return cls(ea, float(weight))

    @property
    def rigid(self) -> bool:
        return self.axial_stiffness is None

    def effective(self, lengths: np.ndarray) -> np.ndarray:
        """L = l + w l^2 / (2 EA): the length the rope behaves as under its own weight [m]."""
        if self.axial_stiffness is None:  # rigid
            return lengths
        return lengths + self.weight * lengths ** 2 / (2.0 * self.axial_stiffness)

    def loaded(self, lengths: np.ndarray, tensions: np.ndarray) -> np.ndarray:
        """Span of ropes of unstretched length l at tension tau [N] (tau = 0: hanging slack, unstretched)."""
        if self.rigid:
            return lengths
        return self.effective(lengths) * (1.0 + tensions / self.axial_stiffness)

    def unstretched(self, spans: np.ndarray, tensions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Unstretched length l* of ropes with this span and tension, and its derivatives d l*/d span,
        d l*/d tau [m/N] (arrays shaped like `spans`, (..., 4))."""
        if self.rigid:
            return spans, np.ones_like(spans), np.zeros_like(spans)
        ea = self.axial_stiffness
        factor = 1.0 + tensions / ea
        effective = spans / factor
        if self.weight > 0.0:
            root = np.sqrt(1.0 + 2.0 * self.weight * effective / ea)
            length = 2.0 * effective / (1.0 + root)       # the root of w l^2 / (2 EA) + l = L
            d_effective = 1.0 / (1.0 + self.weight * length / ea)
        else:
            length, d_effective = effective, np.ones_like(spans)
        return length, d_effective / factor, -d_effective * effective / (ea * factor)
