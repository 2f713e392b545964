"""Measured minus model for every measured channel: load pins, inclinometer, depth gauge."""
from __future__ import annotations

import math
from typing import Mapping, NamedTuple, Sequence

import numpy as np

from ..model.geometry import roll_pitch_of_quaternion, roll_pitch_yaw
from ..model.plant import CABLE_NAMES, Plant
from ..model.result import Solution

TENSION_CHANNELS = tuple(f"tension_{name}" for name in CABLE_NAMES)  # load pins, one per cable
NOISE_KEYS = {channel: "tension" for channel in TENSION_CHANNELS}  # channel -> its key in noise_levels()


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


def noise_levels(plant: Plant) -> dict[str, float]:
    """1-sigma noise per channel family from the plant file's `noise` section (NaN if absent)."""
    section: Mapping[str, float] = plant.raw.get("plant", {}).get("noise", {}) or {}
    return {key: float(section.get(key, np.nan)) for key in ("tension", "roll", "pitch", "depth", "x", "y")}


def predicted_channels(solution: Solution) -> dict[str, float]:
    """What each sensor should read for a solved pose under the rigid-rope model.

    Load pins at the head sheave read the rope tension, equal to the tension at the
    platform for a weightless rope; the inclinometer reads roll and pitch of `platform`;
    the depth gauge reads the platform origin.
    """
    roll, pitch, _ = roll_pitch_yaw(solution.rotation)
    channels = dict(zip(TENSION_CHANNELS, solution.tensions.tolist()))
    channels.update(roll=roll, pitch=pitch, x=float(solution.position[0]), y=float(solution.position[1]),
                    depth=float(solution.position[2]))
    return channels


def residuals(noise: Mapping[str, float], stamp: float, measured: Mapping[str, float],
              predicted: Mapping[str, float]) -> Residuals | None:
    """Residuals of the finite measured channels; None if nothing to compare.

    `predicted` is what the sensors read for the solved pose (`predicted_channels`, or
    effects.PlantModel.predict under the plant's effects); `noise` is `noise_levels(plant)`.
    """
    rows = [(k, v, predicted[k], noise[NOISE_KEYS.get(k, k)]) for k, v in measured.items()
            if k in predicted and math.isfinite(v)]
    return Residuals(stamp, *zip(*rows)) if rows else None


def imu_channels(quaternion_xyzw: Sequence[float]) -> dict[str, float]:
    """Roll and pitch of an inclinometer's orientation (yaw is not measured)."""
    roll, pitch = roll_pitch_of_quaternion(quaternion_xyzw)
    return {"roll": roll, "pitch": pitch}


def position_channels(xyz: Sequence[float]) -> dict[str, float]:
    """Depth gauge (z) and, where measured, x and y of the platform origin."""
    return {"x": float(xyz[0]), "y": float(xyz[1]), "depth": float(xyz[2])}
