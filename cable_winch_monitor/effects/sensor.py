"""Measurement effect of a three-point-bending tension sensor that ignores the rope's bending rigidity."""
from __future__ import annotations

import numpy as np

from ..channels import TENSION_CHANNELS
from ..model.estimator import States
from ..model.plantfile.plant import Plant
from .base import Effect, Parameter, StackedConditions, relative, relative_bounds, weight

MAX_BENDING = 0.5  # 3 sqrt(B/T)/l beyond this the sensor is outside its range: reading capped at 2 T


def bending_reading(tension: np.ndarray, rigidity: float, span: float) -> np.ndarray:
    """Tension a three-point-bending sensor reports with T = P l / (4 delta) for a true tension T.

    Seed 001, eqs. (12)-(15): the bending moments M_A + M_C = (3P/4) sqrt(B/T) enter the
    moment balance T delta + M_A + M_C = P l / 4, so P = 4 T delta / (l - 3 sqrt(B/T)) and
    the plain formula (16) reports T l / (l - 3 sqrt(B/T)) -- too high, by a relative
    amount falling as 1/sqrt(T). The deflection delta cancels.
    """
    tension = np.asarray(tension, dtype=float)
    safe = np.where(tension > 0.0, tension, 1.0)
    x = np.minimum(3.0 * np.sqrt(rigidity / safe) / span, MAX_BENDING)
    return np.where(tension > 0.0, tension / (1.0 - x), tension)


def bending_slope(tension: np.ndarray, rigidity: float, span: float) -> np.ndarray:
    """d bending_reading / d T: with x = 3 sqrt(B/T) / l (dx/dT = -x / 2T), 1/(1 - x) - x / (2 (1 - x)^2);
    1/(1 - MAX_BENDING) where the reading is capped, also at T = 0 (the slope into taut: a tension is
    never negative), 1 below."""
    tension = np.asarray(tension, dtype=float)
    root = np.sqrt(np.maximum(tension, 0.0))
    raw = np.divide(3.0 * np.sqrt(rigidity), span * root, out=np.full_like(tension, np.inf), where=root > 0.0)
    x = np.minimum(raw, MAX_BENDING)
    slope = np.where(raw < MAX_BENDING, 1.0 / (1.0 - x) - x / (2.0 * (1.0 - x) ** 2), 1.0 / (1.0 - x))
    return np.where(tension >= 0.0, slope, 1.0)


class TensionSensorBending(Effect):
    """The load pins are three-point-bending sensors evaluated with T = P l / 4 delta (seed 001).

    The plain formula misses the rope's bending rigidity B (EI): the reading is
    T l / (l - 3 sqrt(B/T)) for a sensor span l (seed 001, eqs. 15-18, solved for the
    reading). Residual signature: every tension reads high, relatively more at low
    tension (excess 3 sqrt(B T) / l, roughly).
    """

    name = "tension_sensor_bending"
    title = "the tension sensors ignore the rope's bending rigidity (three-point bending, T = Pl/4d)"
    acts = "measurement"
    order = 30
    parameters = (Parameter("B", "N m^2", relative(0.001, weight), relative_bounds(0.0, 0.1, weight),
                            relative(2.0e-4, weight), "rope bending rigidity EI (bounds per N of m g, times 1 m^2)"),
                  Parameter("span", "m", 2.0, (0.05, 20.0), 0.1, "sensor span l between the outer rollers",
                            fit=False))
    signature = "all tensions read high, relatively more at low tension (excess ~ 3 sqrt(B T) / l)"
    source = "seed 001, eqs. (12)-(18)"

    def measure_states(self, channels: dict[str, np.ndarray], states: States, plant: Plant,
                       conditions: StackedConditions) -> None:
        for name in TENSION_CHANNELS:
            channels[name] = bending_reading(channels[name], self["B"], self["span"])

    def measure_gradients(self, gradients: dict[str, np.ndarray], channels: dict[str, np.ndarray], states: States,
                          plant: Plant, conditions: StackedConditions) -> None:
        for name in TENSION_CHANNELS:
            gradients[name] = bending_slope(channels[name], self["B"], self["span"])[:, None] * gradients[name]
