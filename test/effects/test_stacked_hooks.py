"""The stacked geometry hook (`lengths_states`) and an effect copied with other values (`replaced`).

The stacked hook gives every row the lengths the per-sample hook gives it, to the bit; where it
fails on a row, that row alone is refused (as the per-sample hooks refuse it) and the others kept.
A copy with other values keeps the effect's numbers for the plant and checks the new values as a
new effect would.
"""
from __future__ import annotations

import numpy as np
import pytest
from lengths import random_lengths

from cable_winch_monitor.effects.base import Effect, EffectError, Parameter
from cable_winch_monitor.effects.encoder import EncoderOffset, EncoderScale
from cable_winch_monitor.effects.model import PlantModel
from cable_winch_monitor.effects.rope import RopeWeight
from cable_winch_monitor.model.conditions import Conditions


def test_encoder_effects_give_every_row_its_own_lengths_at_once(plant):
    model = PlantModel(plant, (EncoderScale({"k_1": 0.003, "k_3": -0.001}), EncoderOffset({"d_2": 0.04, "d_4": -0.02})))
    reported = random_lengths(50, seed=3)
    reported[7] = np.nan  # not lengths: carried through, as row by row
    conditions = [Conditions(time=float(k)) for k in range(len(reported))]
    lengths, loads, hooked = model.batch_inputs(reported, conditions)
    assert hooked == []
    for k, row in enumerate(reported):
        assert np.array_equal(lengths[k], model.true_lengths(row, conditions[k]), equal_nan=True)
        assert np.array_equal(loads[k], plant.wrench)


class ShortDrum(Effect):
    """A drum that cannot pay out beyond 500 m: its hook fails there, row by row and stacked."""

    name, acts = "short_drum", "geometry"
    parameters = (Parameter("d", "m", 0.0, (-1.0, 1.0), 0.01, "offset"),)

    def lengths(self, lengths, conditions):
        if lengths[0] > 500.0:
            raise ValueError("beyond the drum")
        return lengths + self["d"]

    def lengths_states(self, lengths, conditions):
        if (lengths[:, 0] > 500.0).any():
            raise ValueError("beyond the drum")
        return lengths + self["d"]


def test_a_stacked_hook_failing_on_one_row_refuses_that_row_only(plant):
    model = PlantModel(plant, (ShortDrum({"d": 0.01}),))
    reported = np.full((5, 4), 300.0)
    reported[2, 0] = 600.0
    lengths, _, hooked = model.batch_inputs(reported, [Conditions()] * len(reported))
    assert hooked == [2]
    assert np.isnan(lengths[2]).all()
    kept = [0, 1, 3, 4]
    assert np.array_equal(lengths[kept], reported[kept] + 0.01)


def test_a_copy_keeps_the_numbers_for_the_plant_and_checks_its_values(plant):
    weight = RopeWeight({"w": 58.0}, plant)
    heavier = weight.replaced(w=70.0)
    assert type(heavier) is RopeWeight and heavier.specs is weight.specs and heavier.for_plant is plant
    assert heavier.values == RopeWeight({"w": 70.0}, plant).values and weight["w"] == 58.0
    high = weight.specs[0].bounds[1]
    with pytest.raises(EffectError, match="outside its bounds"):
        weight.replaced(w=2.0 * high + 1.0)
    with pytest.raises(EffectError, match="unknown parameter 'mass'"):
        weight.replaced(mass=1.0)


def test_an_effect_that_sets_itself_up_is_made_anew_when_copied(plant):
    class Tabled(RopeWeight):
        name = "tabled_weight"

        def __init__(self, values=None, plant=None):
            super().__init__(values, plant)
            self.per_km = 1000.0 * self["w"]

    assert Tabled({"w": 58.0}, plant).replaced(w=60.0).per_km == 60_000.0
