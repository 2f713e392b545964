"""Measured minus model for the channels measured at a stamp, with their noise from the plant file."""
from __future__ import annotations

import math
from collections.abc import Mapping
from typing import NamedTuple

from ..channels import ChannelRegistry
from ..model.plantfile.plant import Plant


class Residuals(NamedTuple):
    """Measured and predicted readings of the channels measured at `stamp`, with their 1-sigma noise
    (a few numbers per message: tuples of floats, not arrays)."""

    stamp: float
    channels: tuple[str, ...]
    measured: tuple[float, ...]
    predicted: tuple[float, ...]
    noise: tuple[float, ...]

    @property
    def values(self) -> tuple[float, ...]:
        """Measured minus predicted."""
        return tuple(m - p for m, p in zip(self.measured, self.predicted))


def noise_levels(plant: Plant, channels: ChannelRegistry) -> dict[str, float]:
    """1-sigma noise of every channel of `channels` from the plant file's `noise:` section (NaN if absent)."""
    return {c.name: float(plant.noise.get(c.noise_key, math.nan)) for c in channels.declared()}


def residuals(noise: Mapping[str, float], stamp: float, measured: Mapping[str, float],
              predicted: Mapping[str, float]) -> Residuals | None:
    """Residuals of the finite measured channels; None if nothing to compare.

    `predicted` is what the sensors read for the solved pose (effects.PlantModel.predict);
    `noise` is `noise_levels(plant, channels)`.
    """
    rows = [(k, v, predicted[k], noise.get(k, math.nan)) for k, v in measured.items()
            if k in predicted and math.isfinite(v)]
    return Residuals(stamp, *zip(*rows)) if rows else None
