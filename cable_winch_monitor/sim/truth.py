"""The plant's true state at each sample, and what its sensors read of it before noise.

Independent of the package's model: the equilibrium is `sim.equilibrium` (root finding
on force and moment balance) and every hidden effect is the function of the same name in
`sim.physics`, never the package's effect class. The effects come from the plant file's
`effects:` section with the scenario's on top (same names and parameters as the
package's); `ropes.model: elastic` is rope_elasticity with `ropes.EA`. In the plant's
physical order:

  reported lengths -> encoder_scale, encoder_offset -> rope_temperature -> true lengths
  plant -> cog_offset, payload_mass; load m (g - a) with platform_acceleration
  ropes: rigid or rope_elasticity, with rope_weight's own-weight stretch; sheave_geometry, or the
         plant file's pulleys (geometry.sheaves) with pulley_geometry's radius (sim.pulleys)
  load pins: tension + rope_weight below -> sheave_friction -> tension_sensor_bending
             -> load_pin_calibration; inclinometer: roll, pitch + inclinometer_offset

A user's effect class (`simulate --effect-module`) can only be a measurement effect: it
edits the truth's channels after the built-in ones. Geometry and rope-law effects of the
package cannot enter the truth: that would make it the code under test again.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..channels import TENSION_CHANNELS
from ..effects import Conditions
from ..model.plantfile.plant import Plant
from ..model.statics.result import Solution, SolveStatus, failed
from . import physics
from .equilibrium import NoEquilibrium, Rig, State, Trajectory, imbalance
from .hidden import hidden_effects
from .keys import ScenarioError
from .pulleys import Pulleys

METHOD = "truth"
AIR_TEMPERATURE = "/shaft/temperature.temperature"  # the input key a user's effect reads the air temperature by


@dataclass(frozen=True)
class Sample:
    """What the truth depends on at one instant besides the lengths."""

    time: float                 # [s]
    speeds: np.ndarray          # true payout speed of each winch [m/s]
    acceleration: float         # payout acceleration [m/s^2] (positive: paying out faster)
    temperature: float          # shaft air [deg C]


def head_sheaves(plant: Plant, radius: float) -> Pulleys:
    """sheave_geometry: fixed head sheaves in vertical planes pointing from the shaft axis through each
    anchor (each turns the rope towards its winch outside the shaft); the anchor is where a vertical rope
    leaves, and the rope runs on upwards to the winch."""
    outward = plant.anchors[:, :2] - plant.shaft_centre
    outward = outward / np.linalg.norm(outward, axis=1, keepdims=True)
    return Pulleys(np.full(4, radius), np.tile([0.0, 0.0, 1.0], (4, 1)), np.column_stack([outward, np.zeros(4)]))


def plant_pulleys(plant: Plant, hidden: Mapping[str, float] | None) -> Pulleys | None:
    """The pulleys of the plant file (`geometry.sheaves`), their radius replaced by pulley_geometry's where
    it is hidden; a plant without them gets pulley_geometry's four alike: swivelling about its axis, or
    fixed with their planes towards the shaft axis. None: no pulleys."""
    if plant.sheaves:
        radius = [s.radius for s in plant.sheaves] if hidden is None else [hidden["r"]] * 4
        facing = [np.full(3, np.nan) if s.swivel else s.towards for s in plant.sheaves]
        return Pulleys(np.array(radius, dtype=float), np.array([s.axis for s in plant.sheaves]), np.array(facing))
    if hidden is None:
        return None
    axis = np.array([hidden["axis_x"], hidden["axis_y"], hidden["axis_z"]])
    if np.linalg.norm(axis) < 1e-9:
        raise ScenarioError("key 'effects.pulley_geometry': the axis (axis_x, axis_y, axis_z) must not be zero")
    axis = axis / np.linalg.norm(axis)
    towards = np.full((4, 3), np.nan)
    if hidden["swivel"] < 0.5:
        towards = np.column_stack([plant.shaft_centre - plant.anchors[:, :2], np.zeros(4)])
        towards -= (towards @ axis)[:, None] * axis
        towards /= np.linalg.norm(towards, axis=1, keepdims=True)
    return Pulleys(np.full(4, hidden["r"]), np.tile(axis, (4, 1)), towards)


class TruthModel:
    """The true equilibrium along a simulated run, and the sensors' noise-free readings."""

    def __init__(self, plant: Plant, config: Mapping[str, Any]):
        self.plant = plant
        self.effects, self.user_effects = hidden_effects(plant, config)
        e = self.effects
        cog = physics.cog_offset(plant.cog, e["cog_offset"]) if "cog_offset" in e else plant.cog
        self.mass = physics.payload_mass(plant.mass, e["payload_mass"]) if "payload_mass" in e else plant.mass
        self.physical = plant.with_changes(cog=cog, mass=self.mass)
        self.rig = Rig(anchors=plant.anchors, attachments=plant.attachments, cog=cog,
                       weight_scale=plant.weight, lever_scale=float(np.linalg.norm(plant.attachments - cog, axis=1).max()),
                       EA=e["rope_elasticity"]["EA"] if "rope_elasticity" in e else None,
                       rope_weight=e["rope_weight"]["w"] if "rope_weight" in e else 0.0,
                       pulleys=head_sheaves(plant, e["sheave_geometry"]["r"]) if "sheave_geometry" in e
                       else plant_pulleys(plant, e.get("pulley_geometry")))
        self.trajectory = Trajectory(self.rig)
        self.direction = np.zeros(4)

    def lengths(self, reported: np.ndarray, temperature: float) -> np.ndarray:
        """The unstretched rope lengths the winches have paid out for what they report."""
        e, lengths = self.effects, np.asarray(reported, dtype=float)
        if "encoder_scale" in e:
            lengths = physics.encoder_scale(lengths, e["encoder_scale"])
        if "encoder_offset" in e:
            lengths = physics.encoder_offset(lengths, e["encoder_offset"])
        if "rope_temperature" in e:
            lengths = physics.rope_temperature(lengths, e["rope_temperature"], temperature)
        return lengths

    def reported(self, lengths: np.ndarray, temperature: float) -> np.ndarray:
        """What the encoders report for ropes paid out `lengths` [m]: the inverse of `lengths`, which is
        affine in each rope's reported length."""
        zero, one = self.lengths(np.zeros(4), temperature), self.lengths(np.ones(4), temperature)
        return (np.asarray(lengths, dtype=float) - zero) / (one - zero)

    def load(self, acceleration: float) -> np.ndarray:
        """The external wrench on the platform (force [N], moment about C [N m], shaft frame)."""
        g = self.plant.g
        if "platform_acceleration" in self.effects:
            g = physics.platform_acceleration(g, self.effects["platform_acceleration"], acceleration)
        return np.array([0.0, 0.0, -self.mass * g, 0.0, 0.0, 0.0])

    def __call__(self, reported: np.ndarray, sample: Sample) -> tuple[Solution, dict[str, float]]:
        """The true equilibrium for the lengths the winches report, and what the sensors read of it."""
        return self.paid_out(self.lengths(reported, sample.temperature), sample)

    def paid_out(self, lengths: np.ndarray, sample: Sample) -> tuple[Solution, dict[str, float]]:
        """The true equilibrium for the ropes paid out `lengths` [m], and what the sensors read of it."""
        load = self.load(sample.acceleration)
        self.direction = physics.motion_direction(np.asarray(sample.speeds, dtype=float), self.direction)
        try:
            state = self.trajectory(sample.time, lengths, load)
        except NoEquilibrium as error:
            return failed(SolveStatus.NO_EQUILIBRIUM, f"truth: {error}", METHOD, lengths), {}
        solution = self._solution(state, load)
        return solution, self._readings(state, solution, sample)

    def _solution(self, state: State, load: np.ndarray) -> Solution:
        force_vector, moment_vector = imbalance(state, load)
        force = np.linalg.norm(force_vector) / self.rig.weight_scale
        moment = np.linalg.norm(moment_vector) / (self.rig.weight_scale * self.rig.lever_scale)
        return Solution(status=SolveStatus.SOLVED, message="true equilibrium", method=METHOD,
                        lengths=state.free_lengths, taut=state.taut, tensions=state.tensions,
                        rotation=state.rotation, position=state.position, points_b=state.points_b,
                        point_c=state.point_c, spans=state.spans, force_residual=float(force),
                        moment_residual=float(moment), iterations=state.evaluations,
                        extras={"exits": state.exits, "angles": state.angles})

    def _readings(self, state: State, solution: Solution, sample: Sample) -> dict[str, float]:
        e = self.effects
        pins = state.tensions
        if "rope_weight" in e:
            vertical = (state.exits[:, 2] - state.points_b[:, 2]) / state.spans
            pins = physics.rope_weight(pins, e["rope_weight"], state.free_lengths, vertical)
        if "sheave_friction" in e:
            pins = physics.sheave_friction(pins, e["sheave_friction"], self.direction)
        if "tension_sensor_bending" in e:
            pins = physics.tension_sensor_bending(pins, e["tension_sensor_bending"])
        if "load_pin_calibration" in e:
            pins = physics.load_pin_calibration(pins, e["load_pin_calibration"])
        roll, pitch = float(state.angles[0]), float(state.angles[1])
        if "inclinometer_offset" in e:
            roll, pitch = physics.inclinometer_offset(roll, pitch, e["inclinometer_offset"])
        channels = dict(zip(TENSION_CHANNELS, pins.tolist()))
        channels.update(roll=roll, pitch=pitch, x=float(state.position[0]), y=float(state.position[1]),
                        depth=float(state.position[2]))
        if self.user_effects:
            conditions = Conditions(time=sample.time, speeds=np.asarray(sample.speeds, dtype=float),
                                    accelerations=np.full(4, sample.acceleration), direction=self.direction.copy(),
                                    inputs={AIR_TEMPERATURE: sample.temperature})
            for effect in self.user_effects:
                effect.measure(channels, solution, self.physical, conditions)
        return channels
