"""The derivatives of the predicted readings through the measurement effects (`measure_gradients`).

Each built-in measurement effect gives the derivative of its hook, so the estimator needs
no forward differences of the model's predictions. Held here to central differences of the
predictions themselves (steps of their own, not the estimator's), at states solved across
the shaft and tilted, with the ropes hoisting on some and lowering on others; and the
estimate with them to the one the forward differences give.
"""
from __future__ import annotations

import numpy as np
import pytest
from lengths import random_lengths

from cable_winch_monitor import channels
from cable_winch_monitor.effects.base import Effect, EffectError
from cable_winch_monitor.effects.calibration import InclinometerOffset, LoadPinCalibration
from cable_winch_monitor.effects.estimate import estimate_recording
from cable_winch_monitor.effects.model import PlantModel
from cable_winch_monitor.effects.rope import RopeElasticity, RopeWeight
from cable_winch_monitor.effects.sensor import TensionSensorBending
from cable_winch_monitor.effects.sheave import SheaveFriction
from cable_winch_monitor.model.conditions import Conditions, StackedConditions
from cable_winch_monitor.model.estimator import States
from cable_winch_monitor.model.statics.geometry import rotations_from_vectors

STEPS = np.array([1e-4] * 3 + [1e-6] * 3 + [1.0] * 4)  # [m, rad, N]: central differences, the test's own
NOISE = {"length": 1e-3, "tension": 150.0, "roll": np.radians(0.01), "pitch": np.radians(0.01), "depth": 5e-3}

EFFECTS = {
    "rope_weight": lambda: RopeWeight({"w": 58.0}),
    "load_pin_calibration": lambda: LoadPinCalibration({"zero_1": 300.0, "gain_2": 0.02, "gain_4": -0.03}),
    "inclinometer_offset": lambda: InclinometerOffset({"roll": 0.004, "pitch": -0.002}),
    "tension_sensor_bending": lambda: TensionSensorBending({"B": 2000.0}),
    "sheave_friction": lambda: SheaveFriction({"mu": 0.08}),
}


def _states(plant, count: int = 12) -> tuple[States, StackedConditions]:
    """Solved states tilted a little each way, with directions of motion of every kind."""
    model = PlantModel(plant)
    solved = [s for s in (model.solve(row) for row in random_lengths(3 * count, seed=5)) if s.ok][:count]
    states = States.of(plant, solved)
    rng = np.random.default_rng(8)
    turned = rotations_from_vectors(rng.normal(0.0, 0.01, (len(states), 3))) @ states.rotation
    states = States(plant, turned, states.position, states.tensions, np.arange(len(states)))
    directions = rng.choice([-1.0, 0.0, 1.0], (len(states), 4))
    return states, StackedConditions.of([Conditions(direction=d) for d in directions])


def _central(model: PlantModel, states: States, conditions: StackedConditions) -> dict[str, np.ndarray]:
    """Central differences; at a slack rope's tension (0) the one-sided one into taut, the only side a
    state takes (a sensor reading bending has a kink there)."""
    here = model.predict_states(states, conditions)
    out = {name: np.zeros((len(states), 10)) for name in model.channels.names()}
    for k, h in enumerate(STEPS):
        step = np.zeros((len(states), 10))
        step[:, k] = h
        ahead, back = (model.predict_states(states.moved(s, rotations_from_vectors(s[:, 3:6])), conditions)
                       for s in (step, -step))
        slack = states.tensions[:, k - 6] == 0.0 if k >= 6 else np.zeros(len(states), bool)
        for name in out:
            out[name][:, k] = np.where(slack, (ahead[name] - here[name]) / h, (ahead[name] - back[name]) / (2.0 * h))
    return out


@pytest.mark.parametrize("effects", [*([name] for name in EFFECTS), list(EFFECTS)], ids=lambda e: "+".join(e))
def test_the_derivatives_are_those_of_the_predictions(plant, effects):
    model = PlantModel(plant, (RopeElasticity({"EA": 7e7}), *(EFFECTS[name]() for name in effects)))
    states, conditions = _states(plant)
    exact = model.predict_gradients(states, conditions)
    assert exact is not None
    values, gradients = exact
    plain = model.predict_states(states, conditions)
    assert values.keys() == plain.keys() == gradients.keys()
    for name in plain:
        assert np.array_equal(values[name], plain[name])
    central = _central(model, states, conditions)
    for name, gradient in gradients.items():
        scale = np.abs(central[name]).max(axis=0) + (1e-6 if name in ("roll", "pitch") else 1e-3)
        assert np.all(np.abs(gradient - central[name]) <= 1e-4 * scale), name


def test_a_pin_reading_the_rope_weight_moves_with_the_attachments_height(plant):
    """Raise the platform 1 m: each pin reads w x 1 m less (the rope hanging below the sheave is shorter)."""
    model = PlantModel(plant, (RopeWeight({"w": 58.0}),))
    states, conditions = _states(plant, 3)
    exact = model.predict_gradients(states, conditions)
    assert exact is not None
    for name in channels.TENSION_CHANNELS:
        assert np.allclose(exact[1][name][:, 2], -58.0)  # d/dz
        assert np.allclose(exact[1][name][:, 6:], np.eye(4)[channels.TENSION_CHANNELS.index(name)])  # d/d tau


class NumericRopeWeight(RopeWeight):
    """The rope's weight without the derivative of its hook: the estimator differentiates numerically."""

    measure_gradients = Effect.measure_gradients


def test_an_effect_without_derivatives_is_differentiated_numerically_to_the_same_estimate(plant):
    noisy = plant.with_changes(noise={**plant.noise, **NOISE})
    exact = PlantModel(noisy, (RopeElasticity({"EA": 7e7}), RopeWeight({"w": 58.0})))
    numeric = PlantModel(noisy, (RopeElasticity({"EA": 7e7}), NumericRopeWeight({"w": 58.0})))
    assert exact.differentiated and not numeric.differentiated
    states, conditions = _states(plant, 2)
    assert numeric.predict_gradients(states, conditions) is None
    lengths = random_lengths(30, seed=21)
    rng = np.random.default_rng(3)
    measured = {name: 25e3 + rng.normal(0.0, 3e3, len(lengths)) for name in channels.TENSION_CHANNELS}
    conditions_list = [Conditions()] * len(lengths)
    for a, b in zip(estimate_recording(exact, lengths, measured, conditions_list),
                    estimate_recording(numeric, lengths, measured, conditions_list)):
        assert a.solution.status is b.solution.status
        if a.solution.ok:
            assert a.solution.taut_set == b.solution.taut_set
            assert np.abs(a.solution.points_b - b.solution.points_b).max() < 1e-6
            assert np.abs(a.solution.tensions - b.solution.tensions).max() < 0.5


def test_a_wrong_derivative_is_named(plant):
    class Broken(RopeWeight):
        def measure_gradients(self, gradients, channels, states, plant, conditions):
            gradients["tension_cable_1"] = np.zeros(3)

    model = PlantModel(plant, (Broken({"w": 58.0}),))
    states, conditions = _states(plant, 2)
    with pytest.raises(EffectError, match="tension_cable_1.*measure_gradients"):
        model.predict_gradients(states, conditions)
