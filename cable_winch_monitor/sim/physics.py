"""The simulator's own physics of each hidden effect: one small function per effect, no package effect code.

A scenario's `effects:` section names them with the package's effect names and
parameters (`sim.truth` applies them in the plant's physical order); the effects the
package does not have yet (platform_acceleration, rope_temperature, inclinometer_offset,
load_pin_calibration) are defined here first; the pulleys' geometry (sheave_geometry,
pulley_geometry) is `sim.pulleys`, inside the equilibrium. These are the independent truth:
fitted data made with them tests the package's effect classes instead of repeating them.
"""
from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

DEADBAND = 0.02  # [m/s] slower payout counts as standing still: the rope keeps its last slip direction
BENDING_LIMIT = 0.5  # 3 sqrt(B/T) / span beyond this the bending sensor is out of range: it reads 2 T

# name -> parameter defaults ([unit] in the comment); the names and meanings follow the package's effects
PARAMETERS: dict[str, dict[str, float]] = {
    "rope_elasticity": {"EA": 1.0e8},                                   # [N] axial stiffness
    "rope_weight": {"w": 50.0},                                         # [N/m]
    "encoder_scale": {f"k_{i}": 0.0 for i in range(1, 5)},              # [-] true = (1 + k) reported
    "encoder_offset": {f"d_{i}": 0.0 for i in range(1, 5)},             # [m] true = reported + d
    "sheave_friction": {"mu": 0.05, "wrap": float(np.pi / 2)},          # [-], [rad]
    "cog_offset": {"dx": 0.0, "dy": 0.0},                               # [m] platform frame
    "payload_mass": {"dm": 0.0},                                        # [kg]
    "sheave_geometry": {"r": 1.0},                                      # [m] head-sheave radius
    "pulley_geometry": {"r": 0.05, "swivel": 1.0,                       # [m] pulley radius; 1: swivelling
                        "axis_x": 0.0, "axis_y": 0.0, "axis_z": -1.0},  # [-] axis (plants without sheaves)
    "tension_sensor_bending": {"B": 100.0, "span": 2.0},                # [N m^2], [m]
    "platform_acceleration": {"scale": 1.0},                            # [-] share of the payout acceleration
    "rope_temperature": {"alpha": 1.2e-5, "T_ref": 15.0},               # [1/K], [deg C]
    "inclinometer_offset": {"roll": 0.0, "pitch": 0.0},                 # [rad] mounting offset
    "load_pin_calibration": {**{f"zero_{i}": 0.0 for i in range(1, 5)},  # [N]
                             **{f"gain_{i}": 0.0 for i in range(1, 5)}},  # [-]
}
POSITIVE = {("rope_elasticity", "EA"), ("tension_sensor_bending", "span")}
NOT_NEGATIVE = {("rope_weight", "w"), ("sheave_friction", "mu"), ("sheave_friction", "wrap"),
                ("sheave_geometry", "r"), ("pulley_geometry", "r"), ("tension_sensor_bending", "B"),
                ("rope_temperature", "alpha")}


def per_cable(values: Mapping[str, float], prefix: str) -> np.ndarray:
    """The four values prefix_1..prefix_4 as an array."""
    return np.array([values[f"{prefix}_{i}"] for i in range(1, 5)])


# -- lengths: what the winches pay out for what they report ------------------------------------
def encoder_scale(reported: np.ndarray, p: Mapping[str, float]) -> np.ndarray:
    """Drum radius or rope layer off: the winch pays out (1 + k_i) times what it reports."""
    return (1.0 + per_cable(p, "k")) * reported


def encoder_offset(reported: np.ndarray, p: Mapping[str, float]) -> np.ndarray:
    """Encoder zero off by d_i."""
    return reported + per_cable(p, "d")


def rope_temperature(lengths: np.ndarray, p: Mapping[str, float], temperature: float) -> np.ndarray:
    """Steel lengthens with the shaft air temperature: l (1 + alpha (T - T_ref))."""
    return lengths * (1.0 + p["alpha"] * (temperature - p["T_ref"]))


# -- the body and its load ---------------------------------------------------------------------
def cog_offset(cog: np.ndarray, p: Mapping[str, float]) -> np.ndarray:
    """The centre of gravity sits (dx, dy) from the plant file's, platform frame."""
    return cog + np.array([p["dx"], p["dy"], 0.0])


def payload_mass(mass: float, p: Mapping[str, float]) -> float:
    """The platform carries dm more than the plant file says."""
    return mass + p["dm"]


def platform_acceleration(g: float, p: Mapping[str, float], acceleration: float) -> float:
    """The platform accelerates downwards with the payout's acceleration a: the ropes carry m (g - a)."""
    return g - p["scale"] * acceleration


# -- load pins at the head sheave: rope tension there, friction, the sensor, its calibration ----
def rope_weight(tensions: np.ndarray, p: Mapping[str, float], free_lengths: np.ndarray,
                vertical: np.ndarray) -> np.ndarray:
    """The pin carries the platform's pull plus the weight of the rope below along the rope: w l cos(theta)
    (the whole hanging rope for a slack one)."""
    return tensions + p["w"] * free_lengths * vertical


def motion_direction(speeds: np.ndarray, previous: np.ndarray) -> np.ndarray:
    """+1 paying out, -1 hauling in; within the dead band the last direction holds."""
    return np.where(speeds > DEADBAND, 1.0, np.where(speeds < -DEADBAND, -1.0, previous))


def sheave_friction(readings: np.ndarray, p: Mapping[str, float], direction: np.ndarray) -> np.ndarray:
    """Capstan friction over the wrap between rope and pin: T e^(-dir mu wrap)."""
    return readings * np.exp(-direction * p["mu"] * p["wrap"])


def tension_sensor_bending(readings: np.ndarray, p: Mapping[str, float]) -> np.ndarray:
    """A three-point-bending sensor evaluated without the rope's rigidity B reads T l / (l - 3 sqrt(B/T))
    (seed 001); out of range it reads 2 T, and nothing at no tension."""
    pulled = readings > 0.0
    ratio = np.minimum(3.0 * np.sqrt(p["B"] / np.where(pulled, readings, 1.0)) / p["span"], BENDING_LIMIT)
    return np.where(pulled, readings / (1.0 - ratio), readings)


def load_pin_calibration(readings: np.ndarray, p: Mapping[str, float]) -> np.ndarray:
    """Each pin's zero and gain: (1 + gain_i) T + zero_i."""
    return (1.0 + per_cable(p, "gain")) * readings + per_cable(p, "zero")


# -- the inclinometer ------------------------------------------------------------------------------
def inclinometer_offset(roll: float, pitch: float, p: Mapping[str, float]) -> tuple[float, float]:
    """The inclinometer is mounted tilted by (roll, pitch): the offset adds to what it reads."""
    return roll + p["roll"], pitch + p["pitch"]


def check_parameters(name: str, given: Mapping[str, Any], where: str) -> dict[str, float]:
    """The parameters of truth effect `name` (defaults filled in); errors name the key."""
    defaults = PARAMETERS[name]
    unknown = [key for key in given if key not in defaults]
    if unknown:
        raise ValueError(f"unknown key '{where}.{unknown[0]}' (known: {', '.join(defaults)})")
    values = dict(defaults)
    for key, value in given.items():
        if isinstance(value, bool) or not isinstance(value, (int, float, str)):
            raise ValueError(f"key '{where}.{key}' must be a number, got {value!r}")
        try:
            values[key] = float(value)
        except ValueError:
            raise ValueError(f"key '{where}.{key}' must be a number, got {value!r}") from None
        if not np.isfinite(values[key]) or ((name, key) in POSITIVE and values[key] <= 0.0) or \
                ((name, key) in NOT_NEGATIVE and values[key] < 0.0):
            kind = "positive" if (name, key) in POSITIVE else "finite" if (name, key) not in NOT_NEGATIVE \
                else "finite and not negative"
            raise ValueError(f"key '{where}.{key}' must be {kind}, got {values[key]}")
    return values
