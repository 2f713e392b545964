"""Geometry effects of the platform body: where its centre of gravity is and how heavy it is."""
from __future__ import annotations

import numpy as np

from ..model.plantfile.plant import Plant
from .base import Effect, Parameter, reach, relative, relative_bounds

PLAUSIBLE_MASS_CHANGE = 0.3  # a payload beyond +-30 % of the platform's mass is a wrong plant file, not a load


def _mass(plant: Plant) -> float:
    return plant.mass


class CogOffset(Effect):
    """The centre of gravity sits (dx, dy) away from the plant file's C (platform frame).

    Moves the load among the ropes (moment balance of seed 002, eq. 7) and tilts the
    platform. Residual signature: constant tension-share errors (one diagonal pair
    high, the other low) and a constant roll/pitch error, at every payout.
    """

    name = "cog_offset"
    title = "the centre of gravity is not where the plant file puts it"
    acts = "geometry"
    parameters = tuple(Parameter(f"d{axis}", "m", 0.0, relative_bounds(-1.0, 1.0, reach), relative(0.02, reach),
                                 f"shift of C along platform {axis}") for axis in "xy")
    signature = "constant redistribution of tension among the ropes and a constant tilt error"
    source = "seed 002, eqs. (7)-(8): moments about C"

    def plant(self, plant: Plant) -> Plant:
        return plant.with_changes(cog=plant.cog + np.array([self["dx"], self["dy"], 0.0]))


class PayloadMass(Effect):
    """The platform carries dm more (or less) than the plant file's mass.

    Residual signature: every load pin reads high (or low) in proportion to its tension,
    the sum by dm * g; pose and depth almost unchanged.
    """

    name = "payload_mass"
    title = "the platform is heavier or lighter than the plant file says"
    acts = "geometry"
    parameters = (Parameter("dm", "kg", 0.0, relative_bounds(-0.5, 2.0, _mass), relative(0.005, _mass), "extra mass"),)
    signature = "all tensions off by the same factor; their sum by dm * g"
    source = "seed 002, eq. (7): J^T tau = (0, 0, -mg, 0, 0, 0)"

    def plant(self, plant: Plant) -> Plant:
        return plant.with_changes(mass=plant.mass + self["dm"])

    def implausible(self, plant: Plant) -> list[str]:
        share = self["dm"] / plant.mass
        if abs(share) > PLAUSIBLE_MASS_CHANGE:
            return [f"{self.name}.dm: a mass change of {share:+.0%} of the plant's {plant.mass:g} kg is beyond "
                    f"+-{PLAUSIBLE_MASS_CHANGE:.0%}: check the plant file's mass or another effect (tension scale)"]
        return []
