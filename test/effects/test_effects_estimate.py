"""The fused estimate under a plant model: the plant file's noise, the model's rope law and sensor effects.

Truth for elastic ropes with their own weight comes from root finding on the balance
(`root_truth`); the load pins sit at the head sheaves and read the platform's share plus
the rope hanging below them, written here from the truth's points.
"""
from __future__ import annotations

import numpy as np
from lengths import random_lengths
from root_truth import elastic_truth

from cable_winch_monitor.effects.estimate import estimate_recording, length_noise
from cable_winch_monitor.effects.model import NO_CONDITIONS, PlantModel
from cable_winch_monitor.effects.rope import RopeElasticity, RopeWeight
from cable_winch_monitor.model.statics.result import check_physics

NOISE = {"length": 1e-3, "tension": 150.0, "roll": np.radians(0.01), "pitch": np.radians(0.01), "depth": 5e-3}


def noisy_plant(plant):
    return plant.with_changes(noise={**plant.noise, **NOISE})


def test_lengths_alone_are_the_models_forward_kinematics(plant):
    model = PlantModel(noisy_plant(plant))
    assert length_noise(model) == 1e-3
    lengths = random_lengths(40, seed=17)
    recording = estimate_recording(model, lengths, {"depth": np.full(len(lengths), np.nan)},
                                   [NO_CONDITIONS] * len(lengths))
    for row, fused in zip(lengths, recording):
        want = model.solve(row)
        assert fused.used == ()  # nothing measured but the lengths
        assert fused.solution.status is want.status
        if want.ok:
            assert fused.solution.taut_set == want.taut_set
            assert np.abs(fused.solution.points_b - want.points_b).max() < 1e-6
            assert np.abs(fused.solution.tensions - want.tensions).max() < 1.0


def test_without_length_noise_the_lengths_are_exact(plant):
    model = PlantModel(plant.with_changes(noise={k: v for k, v in plant.noise.items() if k != "length"}))
    got, = estimate_recording(model, np.array([[300.02, 300.0, 300.01, 300.0]]), {"tension_cable_1": np.array([5e4])},
                              [NO_CONDITIONS])
    assert not got.fused and got.used == ()
    assert np.array_equal(got.solution.tensions, model.solve([300.02, 300.0, 300.01, 300.0]).tensions)


def test_pins_reading_the_rope_weight_are_predicted_by_the_model(plant):
    ea, weight = 75e6, 60.0
    model = PlantModel(noisy_plant(plant), (RopeElasticity({"EA": ea}), RopeWeight({"w": weight})))
    rng = np.random.default_rng(4)
    truths, reported, measured = [], [], []
    for _ in range(12):
        truth = elastic_truth(plant, rng.uniform(100.0, 600.0) + rng.uniform(-0.05, 0.05, 4), ea, weight)
        points = truth.position + plant.attachments @ truth.rotation.T
        top = truth.tensions + weight * (plant.anchors[:, 2] - points[:, 2])  # the pins carry the rope too
        readings = {f"tension_cable_{i + 1}": top[i] + rng.normal(0.0, NOISE["tension"]) for i in range(4)}
        readings["depth"] = truth.position[2] + rng.normal(0.0, NOISE["depth"])
        truths.append(truth)
        reported.append(truth.lengths + rng.normal(0.0, NOISE["length"], 4))
        measured.append(readings)
    channels = {name: np.array([row[name] for row in measured]) for name in measured[0]}
    conditions = [NO_CONDITIONS] * len(truths)
    recording = estimate_recording(model, np.array(reported), channels, conditions)
    without = estimate_recording(PlantModel(model.plant, (RopeElasticity({"EA": ea}),)), np.array(reported), channels,
                                 conditions)
    for truth, got, forgetting in zip(truths, recording, without):
        assert got.fused and set(got.used) == set(channels)
        assert check_physics(model.physical, got.loaded_solution).passes()
        assert max(abs(r) for r in got.residuals.values()) < 4.0
        assert np.abs(got.solution.tensions - truth.tensions).max() <= 3.0 * NOISE["tension"]
        # a model that forgets the rope's weight cannot explain the pins: the balance holds the tensions
        # to the platform's weight, and every pin is left many sigma off
        assert min(abs(forgetting.residuals[f"tension_cable_{i + 1}"]) for i in range(4)) > 10.0

def test_bad_lengths_are_a_status_under_rigid_and_elastic_ropes(plant):
    for model, method in ((PlantModel(noisy_plant(plant)), "energy"),
                          (PlantModel(plant, (RopeElasticity({"EA": 7.5e7}),)), "elastic")):
        got = model.solve(["a", 1.0, 2.0, 3.0])
        assert got.status.value == "invalid_input" and "number" in got.message and got.method == method
