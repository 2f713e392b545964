"""compare says where a channel's prediction is ill-conditioned on the lengths (the internal mode)."""
from __future__ import annotations

import numpy as np
import pytest

from cable_winch_monitor.analysis import report
from cable_winch_monitor.analysis.compare import compare
from cable_winch_monitor.analysis.conditioning import INTERNAL_MODE, LENGTH_STEP, LIMIT
from cable_winch_monitor.analysis.data import read_bag
from cable_winch_monitor.effects import PlantModel, effect_class
from cable_winch_monitor.model.plantfile.plant import load_plant


@pytest.fixture(scope="module")
def bag_data():
    from pathlib import Path
    return read_bag(Path(__file__).parents[2] / "bags" / "all_channels")


def test_rigid_ropes_leave_tensions_undetermined_where_the_taut_set_changes(bag_data):
    plant = load_plant()
    result = compare(PlantModel.from_plant(plant), bag_data)
    tensions = {s.channel: s for s in result.ill_conditioned if s.channel.startswith("tension_")}
    assert set(tensions) == {f"tension_cable_{i}" for i in range(1, 5)}
    model = PlantModel.from_plant(plant)
    for span in tensions.values():
        assert span.mode.startswith("the internal mode") and span.sigma_per_mm > LIMIT
        assert all(0.0 <= a <= b <= bag_data.times[-1] - bag_data.times[0] for a, b in span.spans)  # from the start
    # at a reported time, a millimetre along the internal mode really moves the tensions by > LIMIT sigma
    start, end = tensions["tension_cable_1"].spans[0]
    row = int(np.flatnonzero((bag_data.kinds == 0) & (bag_data.times - bag_data.times[0] >= start))[0])
    lengths = bag_data.lengths[row]
    here = model.solve(lengths)
    moved = [model.solve(lengths + sign * LENGTH_STEP * INTERNAL_MODE, here) for sign in (1.0, -1.0)]
    assert here.ok and all(m.ok and np.all(m.tensions >= 0.0) for m in moved)
    change = max(np.abs(m.tensions - here.tensions).max() for m in moved)
    assert change > LIMIT * plant.noise["tension"]
    text = report.compare_text(result)
    assert "ill-conditioned: tension_cable_1 moves up to" in text
    assert report.compare_json(result)["ill_conditioned"][0]["spans"]


def test_elastic_ropes_determine_the_tensions(bag_data):
    """EA / L = 7.5e7 N / 50 m: a millimetre along the internal mode moves a tension by a few kN, an
    order of magnitude less than with rigid ropes (the rope's stiffness makes four tensions
    determinate); with 150 N load pins that is still more than their noise, and it is said."""
    plant = load_plant()
    rigid = compare(PlantModel.from_plant(plant), bag_data)
    model = PlantModel(plant, (effect_class("rope_elasticity")({"EA": 7.5e7}, plant),))
    elastic = compare(model, bag_data)
    worst = {r.channel: r.sigma_per_mm for r in rigid.ill_conditioned}
    for span in (s for s in elastic.ill_conditioned if s.channel.startswith("tension_")):
        assert span.sigma_per_mm < 0.25 * worst[span.channel], (span, worst)
