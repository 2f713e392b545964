"""compare and diagnose judge a model by the fused estimate: the lengths are measurements (errors in variables).

The bags are written from a truth found by root finding on the force and moment balance
(`root_truth`, `fusionbags`), with the plant's sensor noise: encoders 1 mm, load pins
150 N, inclinometer 0.01 deg 30-40 ms after the winches, depth 5 mm at 2 Hz. Taken as
exact, 1 mm of length moves the load share by kilonewtons along the weak mode, and the
correct model cannot explain its own load pins; estimated, it scores at the noise.
"""
from __future__ import annotations

import pytest

from cable_winch_monitor.analysis.compare import compare
from cable_winch_monitor.analysis.data import read_bag
from cable_winch_monitor.analysis.diagnose import diagnose
from cable_winch_monitor.analysis.evaluate import noise
from cable_winch_monitor.effects import PlantModel
from fusionbags import NOISE, lowering_truths, noisy, sensed, write_bag

CANDIDATES = ("rope_elasticity",)  # what a model taking its lengths as exact selects on such a bag (issue 11)


@pytest.fixture(scope="module")
def rigid_bag(plant, tmp_path_factory):
    truths = lowering_truths(plant, 300, seed=21)
    return write_bag(sensed(truths, seed=22), tmp_path_factory.mktemp("fusion") / "rigid")


def test_the_correct_rigid_model_scores_at_the_noise_and_selects_nothing(plant, rigid_bag):
    model = PlantModel.from_plant(noisy(plant))
    data = read_bag(rigid_bag)
    fused = compare(model, data)
    exact = compare(PlantModel.from_plant(noisy(plant, length=float("nan"))), data)
    assert fused.score <= 1.3 < 3.0 < exact.score
    pins = fused.channels["tension_cable_1"]
    assert pins.rms <= 2.0 * NOISE["tension"] and pins.failed == 0
    diagnosis = diagnose(model, data, noise(model.plant, data)[0], list(CANDIDATES))
    assert diagnosis.selected == [] and diagnosis.ladder[0].score_heldout <= 1.3
    assert {c.name for c in diagnosis.ranking} == set(CANDIDATES)  # each was screened, none worth its parameters

