"""Honest fits: a value stopped by a bound is no estimate, an implausible value is flagged, neither is "found"."""
from __future__ import annotations

import numpy as np
import pytest
from effectbags import ELASTIC, SEED002, plant_file, simulate_bag

from cable_winch_monitor.analysis import report
from cable_winch_monitor.analysis.data import read_bag
from cable_winch_monitor.analysis.diagnose import diagnose
from cable_winch_monitor.analysis.evaluate import Evaluator, noise, split, thin
from cable_winch_monitor.analysis.fit import fit_effects
from cable_winch_monitor.effects import Parameter, PlantModel
from cable_winch_monitor.effects.body import PayloadMass
from cable_winch_monitor.model.plant import load_plant

HIDDEN_DM = 4000.0  # 40 % of the 10 t platform: beyond any plausible payload


class NarrowPayloadMass(PayloadMass):
    """payload_mass with bounds too narrow for the hidden mass."""

    parameters = (Parameter("dm", "kg", 0.0, (-1000.0, 1000.0), 50.0, "extra mass"),)


@pytest.fixture(scope="module")
def heavy(tmp_path_factory):
    directory = tmp_path_factory.mktemp("honest")
    plant = plant_file(directory, "elastic", SEED002, ELASTIC)
    bag = simulate_bag(directory, "heavy", plant, {"payload_mass": {"dm": HIDDEN_DM}}, duration=60.0)
    base = PlantModel.from_plant(load_plant(plant))
    data = read_bag(bag)
    return base, data, noise(base.plant, data)[0]


def test_value_stopped_by_a_bound_is_no_estimate(heavy):
    base, data, sigma = heavy
    train = Evaluator(data.subset(thin(split(data)[0], data.kinds, 60)))
    fit = fit_effects(base, [NarrowPayloadMass()], train, sigma)
    value = fit.params("payload_mass")["dm"]
    assert value["value"] == pytest.approx(1000.0, abs=10.0)  # pulled by 4 t, held by the bound
    assert fit.at_bound == ["payload_mass.dm"] and not fit.honest("payload_mass")
    assert any("upper bound" in w for w in fit.warnings)
    assert not any("not identified" in w for w in fit.warnings)  # a bound is not an uncertainty


def test_implausible_mass_is_flagged_and_not_found(heavy):
    base, data, sigma = heavy
    result = diagnose(base, data, sigma, ["payload_mass", "encoder_offset"])
    mass = next(c for c in result.ranking if c.name == "payload_mass")
    # the fit itself recovers the truth: the flag is about physics, not about a failed fit
    assert mass.fit.params("payload_mass")["dm"]["value"] == pytest.approx(HIDDEN_DM, rel=0.1)
    assert mass.fit.implausible and "+40%" in mass.fit.implausible[0]
    assert mass.score_after < 0.5 * mass.score_before  # a large gain, still not selected
    assert "payload_mass" not in result.selected
    text = report.diagnose_text(result)
    assert "found: the platform is heavier" not in text
    entry = next(e for e in report.diagnose_json(result, "heavy", len(data))["effects"] if e["name"] == "payload_mass")
    assert entry["found"] is False and entry["honest"] is False and entry["implausible"]
    assert np.isfinite(entry["params"]["dm"])
