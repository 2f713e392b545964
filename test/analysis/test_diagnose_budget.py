"""diagnose within a time budget: a fit stops at its deadline and is never found; what is left unfinished is said."""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest

from cable_winch_monitor.analysis import report
from cable_winch_monitor.analysis.data import read_bag
from cable_winch_monitor.analysis.diagnose import Candidate, Diagnosis, Step, diagnose
from cable_winch_monitor.analysis.evaluate import Evaluator, noise, split, thin
from cable_winch_monitor.analysis.fit import fit_effects
from cable_winch_monitor.effects import PlantModel, effect_class
from cable_winch_monitor.model.plantfile.plant import load_plant

BAG = Path(__file__).parents[2] / "bags" / "all_channels"


@pytest.fixture(scope="module")
def bag():
    model = PlantModel.from_plant(load_plant())
    data = read_bag(BAG)
    return model, data, noise(model, data)[0]


def test_fit_past_its_deadline_keeps_the_best_values_met_and_is_not_found(bag):
    model, data, sigma = bag
    train = Evaluator(data.subset(thin(split(data)[0], data.kinds, 30)))
    effect = effect_class("rope_elasticity")(plant=model.plant)
    fit = fit_effects(model, [effect], train, sigma, deadline=time.monotonic() - 1.0)
    assert fit.truncated and not fit.honest("rope_elasticity")
    assert fit.values == pytest.approx([effect["EA"]])  # only the start was evaluated
    assert np.isnan(fit.sigmas).all() and "time budget" in fit.warnings[0]


def test_spent_budget_lists_every_candidate(bag):
    model, data, sigma = bag
    result = diagnose(model, data, sigma, ["sheave_friction", "rope_elasticity", "cog_offset"], budget=0.0)
    assert result.ranking == [] and result.selected == []
    assert result.unfinished == ["candidate sheave_friction (round 1: not screened)",
                                 "candidate rope_elasticity (round 1: not screened)",
                                 "candidate cog_offset (round 1: not screened)",
                                 "the identifiability check (ill-conditioned channels)"]  # cheapest first
    text = report.diagnose_text(result)
    assert "unfinished (the time budget of 0 s was spent): candidate sheave_friction (round 1: not screened)" in text
    assert "found: nothing within the time budget -- 3 candidate(s) were not tried or not fitted fully: give diagnose a larger " \
        "--budget" in text and "no candidate effect explains" not in text
    assert report.diagnose_json(result, "all_channels", len(data))["unfinished"] == result.unfinished


@pytest.mark.parametrize("seconds", [1.0, 4.0, 12.0])
def test_a_short_budget_ends_with_converged_fits_or_lists_what_it_left(bag, seconds):
    """Whatever the budget, every candidate was screened or is listed as unfinished, and what is selected
    comes from a joint fit that converged (a fit the budget stopped is never added)."""
    model, data, sigma = bag
    names = ["inclinometer_offset", "rope_elasticity", "encoder_offset", "cog_offset"]
    result = diagnose(model, data, sigma, names, budget=seconds)
    listed = {n for n in names if any(u.startswith(f"candidate {n} (") for u in result.unfinished)}
    assert set(names) <= listed | {c.name for c in result.ranking}, (result.unfinished, result.ranking)
    assert result.final is None or (result.final.converged and not result.final.truncated)
    assert all(result.final.honest(name) for name in result.selected)


def test_a_candidate_stopped_by_the_budget_while_it_improved_is_not_called_no_explanation(bag):
    """The report's words for a ranking whose best candidate lowered the held-out error but was stopped at
    the time budget ("no candidate explains the data" stood beside it)."""
    model, data, sigma = bag
    train = Evaluator(data.subset(thin(split(data)[0], data.kinds, 30)))
    fit = fit_effects(model, [effect_class("rope_weight")(plant=model.plant)], train, sigma,
                      deadline=time.monotonic() - 1.0)
    result = Diagnosis([Candidate("rope_weight", fit, 19.57, 0.981, -5000.0)], [Step(None, 19.0, 19.57, 1e5)],
                       None, model, len(train.data), 100)
    text = report.diagnose_text(result)
    assert "rope_weight              19.570->0.981" in text and "(not converged)" in text
    assert "found: nothing within the time budget -- rope_weight (19.570->0.981) lowered the held-out error but " \
        "stopped at the time budget before converging: give diagnose a larger --budget" in text
    assert "no candidate effect explains" not in text


@pytest.mark.slow
def test_unbounded_diagnosis_skips_nothing(bag):
    model, data, sigma = bag
    result = diagnose(model, data, sigma, ["inclinometer_offset"], budget=None)
    assert result.unfinished == [] and [c.name for c in result.ranking] == ["inclinometer_offset"]
