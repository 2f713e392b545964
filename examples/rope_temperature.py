"""A physical effect written outside the package that reads a topic the package does not know:
ropes that lengthen with the shaft's air temperature, recorded on /shaft/temperature.

Use it with `--effect-module examples/rope_temperature.py`, or list the file under
`plant.effect_modules` in a plant file; the bag (or the live node's inputs) must then
carry /shaft/temperature.
"""
from __future__ import annotations

import numpy as np

from cable_winch_monitor.channels import Input
from cable_winch_monitor.effects import Effect, Parameter


class RopeTemperature(Effect):
    """Steel ropes lengthen by alpha (T - T_ref) per metre: l_true = l_reported (1 + alpha (T - T_ref)),
    with T the shaft air temperature (sensor_msgs/Temperature on /shaft/temperature) and T_ref the
    temperature at which the encoders were zeroed. Residual signature: depth (and with elastic
    ropes the tension share) drifts with the temperature, in proportion to the payout."""

    name = "rope_temperature"
    title = "the ropes lengthen with the shaft's air temperature"
    acts = "geometry"
    inputs = (Input("temperature", "/shaft/temperature", "temperature", "sensor_msgs/msg/Temperature"),)
    parameters = (Parameter("alpha", "1/K", 0.0, (-1e-4, 1e-4), 2e-6, "thermal expansion of the rope"),
                  Parameter("T_ref", "degC", 20.0, (-50.0, 60.0), 1.0, "temperature at the encoders' zeroing",
                            fit=False))
    signature = "depth drifts with the shaft temperature, in proportion to the payout"
    source = "thermal expansion of steel (alpha ~ 1.2e-5 1/K)"

    def lengths(self, lengths: np.ndarray, conditions) -> np.ndarray:
        temperature = self.input_value(conditions, "temperature")
        return lengths * (1.0 + self["alpha"] * (temperature - self["T_ref"]))
