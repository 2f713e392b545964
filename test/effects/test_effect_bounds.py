"""Effect bounds and fit steps scale with the plant: one library for a 10 t platform and a 13 kg robot."""
from __future__ import annotations

import numpy as np
import pytest

from cable_winch_monitor.effects import EffectError, PlantModel, available, effect_class
from cable_winch_monitor.effects.base import span
from cable_winch_monitor.model.plantfile.plant import PlantConfigError, load_plant, plant_from_mapping

LAB = {"name": "lab robot", "mass": 13.0, "g": 9.81,
       "geometry": {"anchors": [[0.9, 0.75, 0.0], [-0.9, 0.75, 0.0], [-0.9, -0.75, 0.0], [0.9, -0.75, 0.0]],
                    "attachments": [[0.15, 0.15, 0.0], [-0.15, 0.15, 0.0], [-0.15, -0.15, 0.0], [0.15, -0.15, 0.0]],
                    "centre_of_gravity": [0.0, 0.0, -0.1]}}


def lab_plant(**extra):
    return plant_from_mapping({"plant": {**LAB, **extra}})


@pytest.fixture(params=["mine", "lab"])
def any_plant(request):
    return load_plant() if request.param == "mine" else lab_plant()


def test_defaults_lie_inside_bounds_and_steps_are_small(any_plant):
    for name, cls in available().items():
        effect = cls(plant=any_plant)
        for p in effect.specs:
            assert p.bounds[0] <= p.default <= p.bounds[1], (name, p)
            if p.fit:
                assert 0.0 < p.scale < 0.1 * (p.bounds[1] - p.bounds[0]), (name, p)


def test_rope_stiffness_bounds_cover_strains_of_any_plant(any_plant):
    """A quarter of the weight stretches a rope by a strain T / EA: the bounds allow 1e-5 .. 1e-2 on any plant."""
    low, high = effect_class("rope_elasticity")(plant=any_plant).specs[0].bounds
    share = any_plant.weight / 4.0
    assert share / high < 1e-5 and share / low > 1e-2


def test_lab_robot_takes_its_own_values():
    plant = lab_plant()
    assert effect_class("rope_elasticity")({"EA": 2.0e5}, plant)["EA"] == 2.0e5  # refused at mine scale before
    with pytest.raises(EffectError, match="outside its bounds"):  # a mine rope on a 13 kg robot: strain 1e-7
        effect_class("rope_elasticity")({"EA": 1.0e9}, plant)
    offsets = effect_class("encoder_offset")(plant=plant).specs[0]
    assert offsets.scale < 0.005 and offsets.bounds[1] == pytest.approx(0.25 * span(plant))
    mass = effect_class("payload_mass")(plant=plant).specs[0]
    assert mass.bounds == pytest.approx((-6.5, 26.0)) and mass.scale == pytest.approx(0.065)


def test_plant_file_bounds_replace_an_effects_own():
    plant = lab_plant(effect_bounds={"rope_elasticity": {"EA": [1.0e4, 1.0e6]}},
                      effects={"rope_elasticity": {"EA": 5.0e5}})
    model = PlantModel.from_plant(plant)
    assert model.get("rope_elasticity").specs[0].bounds == (1.0e4, 1.0e6)
    with pytest.raises(PlantConfigError, match="outside its bounds"):
        PlantModel.from_plant(lab_plant(effect_bounds={"rope_elasticity": {"EA": [1.0e4, 1.0e5]}},
                                        effects={"rope_elasticity": {"EA": 5.0e5}}))


@pytest.mark.parametrize("bounds, message", [
    ({"rope_elasticity": {"stiffness": [1.0, 2.0]}}, "effect_bounds.rope_elasticity.stiffness"),
    ({"rope_elasticity": {"EA": [2.0, 1.0]}}, "low < high"),
    ({"rope_elasticity": {"EA": "wide"}}, "must be \\[low, high\\]"),
    ({"no_such_effect": {"x": [0.0, 1.0]}}, "unknown effect 'no_such_effect'"),
])
def test_bad_effect_bounds_name_the_key(bounds, message):
    with pytest.raises(PlantConfigError, match=message):
        PlantModel.from_plant(lab_plant(effect_bounds=bounds))


def test_fit_steps_follow_the_plant_size():
    """A lab robot's centre of gravity moves in millimetre steps, the mine platform's in centimetres."""
    mine, lab = load_plant(), lab_plant()
    step = [effect_class("cog_offset")(plant=p).specs[0].scale for p in (mine, lab)]
    reach = [np.linalg.norm(p.attachments, axis=1).max() for p in (mine, lab)]
    assert step[0] / step[1] == pytest.approx(reach[0] / reach[1])
