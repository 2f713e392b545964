"""An evaluation of a model on given rows is a function of the model alone: evaluating A, then B, then A
gives A's score twice, and A's score in a fresh evaluator -- with rigid ropes, whose taut set is a local
choice, and over the lab robot's swivel pulleys, whose tangent points are a fixed point of the pose."""
from __future__ import annotations

import pytest
from effectbags import SEED002, plant_file, simulate_bag

from cable_winch_monitor.analysis.data import read_bag
from cable_winch_monitor.analysis.evaluate import Evaluator, noise, split, thin
from cable_winch_monitor.effects import PlantModel, effect_class
from cable_winch_monitor.model.plantfile.plant import load_plant
from cable_winch_monitor.paths import lab_bag, lab_plant_file


def _scores(base: PlantModel, a: PlantModel, b: PlantModel, rows, sigma, reference: PlantModel | None):
    first = Evaluator(rows, reference)
    a_first, b_then, a_again = first.score(a, sigma), first.score(b, sigma), first.score(a, sigma)
    fresh = Evaluator(rows, reference)
    b_fresh, a_after_b = fresh.score(b, sigma), fresh.score(a, sigma)
    return a_first, a_again, a_after_b, b_then, b_fresh


@pytest.fixture(scope="module")
def rigid(tmp_path_factory):
    """The rigid seed-002 plant file on elastic ropes with weight (four taut ropes, site noise)."""
    directory = tmp_path_factory.mktemp("purity")
    plant = plant_file(directory, "rigid", SEED002, {})
    bag = simulate_bag(directory, "elastic", plant, {"rope_weight": {"w": 58.0}}, duration=60.0,
                       ropes={"model": "elastic", "EA": 6.8e7})
    base = PlantModel.from_plant(load_plant(plant))
    data = read_bag(bag)
    return base, data.subset(thin(split(data)[0], data.kinds, 50)), noise(base, data)[0]


@pytest.mark.parametrize("reference", [False, True], ids=["cold", "from the base"])
def test_rigid_model_scores_the_same_whatever_came_before(rigid, reference):
    base, rows, sigma = rigid
    scaled = base.with_effects([effect_class("encoder_scale")({"k_1": 6e-4, "k_2": 6e-4, "k_3": 5e-4, "k_4": 6e-4},
                                                              base.plant)])
    a_first, a_again, a_after_b, b_then, b_fresh = _scores(base, base, scaled, rows, sigma,
                                                           base if reference else None)
    assert a_again == pytest.approx(a_first, rel=1e-12) and a_after_b == pytest.approx(a_first, rel=1e-12)
    assert b_fresh == pytest.approx(b_then, rel=1e-12)
    assert abs(b_then - a_first) > 1e-3 * a_first  # two different models: the scores differ


@pytest.mark.parametrize("reference", [False, True], ids=["cold", "from the base"])
def test_model_over_swivel_pulleys_scores_the_same_whatever_came_before(reference):
    plant = load_plant(lab_plant_file())
    base = PlantModel.from_plant(plant)
    assert base.refining  # the plant's pulleys make the geometry depend on the pose
    data = read_bag(lab_bag())
    rows = data.subset(thin(split(data)[0], data.kinds, 50))
    sigma = noise(base, data)[0]
    elastic = base.with_effects([effect_class("rope_elasticity")({"EA": 2e4}, plant)])
    a_first, a_again, a_after_b, b_then, b_fresh = _scores(base, elastic, base, rows, sigma,
                                                           base if reference else None)
    assert a_again == pytest.approx(a_first, rel=1e-12) and a_after_b == pytest.approx(a_first, rel=1e-12)
    assert b_fresh == pytest.approx(b_then, rel=1e-12)
    assert abs(b_then - a_first) > 1e-3 * a_first
