"""Measurement effects of sensor calibration: the inclinometer's mounting and the load pins' zero and gain."""
from __future__ import annotations

import numpy as np

from ..channels import TENSION_CHANNELS
from ..model.estimator import States
from ..model.plantfile.plant import Plant
from .base import Effect, Parameter, StackedConditions, relative, relative_bounds, weight

INCLINOMETER_CHANNELS = ("roll", "pitch")


class InclinometerOffset(Effect):
    """The inclinometer (AHRS) is mounted tilted by (roll, pitch) on the platform.

    It reads the platform's roll and pitch plus its mounting offset: roll_read = roll + roll_0,
    pitch_read = pitch + pitch_0 (the small-angle form of composing the mounting rotation,
    exact to first order; the second-order term is below 1e-4 rad for offsets and tilts under
    0.01 rad). Residual signature: a constant roll and pitch error at every pose, with
    tensions, depth and position unaffected -- the level homing pose reads the offset itself.
    """

    name = "inclinometer_offset"
    title = "the inclinometer is mounted tilted: it reads a constant roll and pitch offset"
    acts = "measurement"
    order = 40
    parameters = (Parameter("roll", "rad", 0.0, (-0.2, 0.2), 1.0e-3, "mounting roll offset"),
                  Parameter("pitch", "rad", 0.0, (-0.2, 0.2), 1.0e-3, "mounting pitch offset"))
    signature = "constant roll and pitch errors at every pose; tensions and depth unaffected"
    source = "sensor mounting: the reading is the platform's attitude composed with the mounting rotation"

    def measure_states(self, channels: dict[str, np.ndarray], states: States, plant: Plant,
                       conditions: StackedConditions) -> None:
        for name in INCLINOMETER_CHANNELS:
            channels[name] = channels[name] + self[name]

    def measure_gradients(self, gradients: dict[str, np.ndarray], channels: dict[str, np.ndarray], states: States,
                          plant: Plant, conditions: StackedConditions) -> None:
        """A constant offset: the derivatives stay as they are."""


class LoadPinCalibration(Effect):
    """Each load pin (load cell) has a zero error and a gain error: reading_i = (1 + gain_i) T_i + zero_i.

    Zero drift of the strain gauges and a wrong calibration factor, per cable.
    Residual signature: per-cable tension errors that are an offset plus a part proportional
    to the tension, different for every cable; with tensions that barely change (a static bag) zero
    and gain cannot be told apart, and a common gain is a mass change (payload_mass).
    """

    name = "load_pin_calibration"
    title = "the load pins' zero and gain are off (per cable)"
    acts = "measurement"
    order = 40
    parameters = (*(Parameter(f"zero_{i}", "N", 0.0, relative_bounds(-0.5, 0.5, weight), relative(0.002, weight),
                              f"zero error, load pin {i}") for i in range(1, 5)),
                  *(Parameter(f"gain_{i}", "-", 0.0, (-0.5, 0.5), 1.0e-3, f"relative gain error, load pin {i}")
                    for i in range(1, 5)))
    signature = "per-cable tension errors: an offset plus a part proportional to the tension"
    source = "load-cell calibration: reading = gain x force + zero"

    def measure_states(self, channels: dict[str, np.ndarray], states: States, plant: Plant,
                       conditions: StackedConditions) -> None:
        for i, name in enumerate(TENSION_CHANNELS, 1):
            channels[name] = (1.0 + self[f"gain_{i}"]) * channels[name] + self[f"zero_{i}"]

    def measure_gradients(self, gradients: dict[str, np.ndarray], channels: dict[str, np.ndarray], states: States,
                          plant: Plant, conditions: StackedConditions) -> None:
        for i, name in enumerate(TENSION_CHANNELS, 1):
            gradients[name] = (1.0 + self[f"gain_{i}"]) * gradients[name]
