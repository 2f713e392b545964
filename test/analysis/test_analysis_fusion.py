"""compare and diagnose judge a model by the fused estimate: the lengths are measurements (errors in variables).

The bags are written from a truth found by root finding on the force and moment balance
(`root_truth`, `fusionbags`), with the plant's sensor noise: encoders 1 mm, load pins
150 N, inclinometer 0.01 deg 30-40 ms after the winches, depth 5 mm at 2 Hz. Taken as
exact, 1 mm of length moves the load share by kilonewtons along the weak mode, and the
correct model cannot explain its own load pins; estimated, it scores at the noise. On a
lowering whose winch 3 reports 0.3 % more than it pays out and whose winch 1 has its zero
4 cm off, diagnose finds exactly the encoder scale and offset, with their values. Elastic
ropes with their weight lowered 50-650 m: the correct model scores at the noise (the same
model without the rope weight: above 100) and selects nothing.
"""
from __future__ import annotations

import pytest
from fusionbags import NOISE, elastic_lowering_truths, lowering_truths, noisy, sensed, write_bag

from cable_winch_monitor.analysis.compare import compare
from cable_winch_monitor.analysis.data import read_bag
from cable_winch_monitor.analysis.diagnose import diagnose
from cable_winch_monitor.analysis.evaluate import noise
from cable_winch_monitor.effects import PlantModel

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
    diagnosis = diagnose(model, data, noise(model, data)[0], list(CANDIDATES))
    assert diagnosis.selected == [] and diagnosis.ladder[0].score_heldout <= 1.3
    assert {c.name for c in diagnosis.ranking} == set(CANDIDATES)  # each was screened, none worth its parameters



TRUE_SCALE_3 = 1.0 / 1.003 - 1.0   # winch 3 reports 0.3 % more than it pays out: true = (1 + k) reported
TRUE_OFFSET_1 = -0.04              # winch 1's zero is 4 cm off: true = reported + d
CONFOUNDERS = ("encoder_scale", "encoder_offset", "cog_offset", "load_pin_calibration", "payload_mass")


def _miscalibrated(lengths):
    reported = lengths.copy()
    reported[2] /= 1.0 + TRUE_SCALE_3
    reported[0] -= TRUE_OFFSET_1
    return reported


@pytest.fixture(scope="module")
def miscalibrated_bag(plant, tmp_path_factory):
    """A rigid lowering 20-320 m (1 m/s, 3,000 samples) with lag events, winch 3's scale and winch 1's zero off."""
    truths = lowering_truths(plant, 3000, seed=31, speed=1.0)
    items = sensed(truths, seed=32, reported=_miscalibrated, speed=1.0)
    return write_bag(items, tmp_path_factory.mktemp("fusion") / "miscalibrated")


def _assert_encoders_recovered(diagnosis):
    assert sorted(diagnosis.selected) == ["encoder_offset", "encoder_scale"]  # in either order
    effects = {e.name: e for e in diagnosis.model.effects}
    assert effects["encoder_scale"]["k_3"] == pytest.approx(TRUE_SCALE_3, rel=0.1)
    assert effects["encoder_offset"]["d_1"] == pytest.approx(TRUE_OFFSET_1, rel=0.1)
    others = [effects["encoder_scale"][f"k_{i}"] for i in (1, 2, 4)] + \
        [effects["encoder_offset"][f"d_{i}"] for i in (2, 3, 4)]
    assert max(abs(k) for k in others[:3]) < 0.1 * abs(TRUE_SCALE_3)  # the good winches stay good
    assert max(abs(d) for d in others[3:]) < 0.1 * abs(TRUE_OFFSET_1)
    assert diagnosis.ladder[0].score_heldout > 10.0 and diagnosis.ladder[-1].score_heldout <= 1.3


def test_encoder_scale_and_offset_are_found_among_their_confounders(plant, miscalibrated_bag):
    model = PlantModel.from_plant(noisy(plant))
    data = read_bag(miscalibrated_bag)
    _assert_encoders_recovered(diagnose(model, data, noise(model, data)[0], list(CONFOUNDERS)))


@pytest.mark.slow
def test_encoder_scale_and_offset_are_found_among_every_effect(plant, miscalibrated_bag):
    model = PlantModel.from_plant(noisy(plant))
    data = read_bag(miscalibrated_bag)
    _assert_encoders_recovered(diagnose(model, data, noise(model, data)[0]))


EA, WEIGHT = 7.5e7, 60.0  # [N], [N/m]
ELASTIC_CANDIDATES = ("encoder_scale", "payload_mass", "sheave_friction", "tension_sensor_bending")


@pytest.fixture(scope="module")
def elastic_bag(plant, tmp_path_factory):
    """Elastic ropes with their weight lowered 50-650 m (2 m/s, 3,000 samples); the load pins at the head
    sheaves feel the rope below them too: tension plus its weight over the drop."""
    truths = elastic_lowering_truths(plant, 3000, seed=41, start=50.0, speed=2.0, ea=EA, weight=WEIGHT)

    def pins(truth):
        drop = plant.anchors[:, 2] - (truth.position + plant.attachments @ truth.rotation.T)[:, 2]
        return truth.tensions + WEIGHT * drop

    return write_bag(sensed(truths, seed=42, speed=2.0, pins=pins), tmp_path_factory.mktemp("fusion") / "elastic")


def _elastic_model(plant):
    effects = {"rope_elasticity": {"EA": EA}, "rope_weight": {"w": WEIGHT}}
    return PlantModel.from_plant(noisy(plant).with_changes(effects=effects))


def test_the_correct_elastic_model_scores_at_the_noise_and_selects_nothing(plant, elastic_bag):
    model = _elastic_model(plant)
    data = read_bag(elastic_bag)
    assert compare(model, data).score <= 1.3
    diagnosis = diagnose(model, data, noise(model, data)[0], list(ELASTIC_CANDIDATES))
    assert diagnosis.selected == [] and diagnosis.ladder[0].score_heldout <= 1.3
    assert {c.name for c in diagnosis.ranking} == set(ELASTIC_CANDIDATES)


@pytest.mark.slow
def test_the_correct_elastic_model_selects_nothing_among_every_effect(plant, elastic_bag):
    model = _elastic_model(plant)
    data = read_bag(elastic_bag)
    diagnosis = diagnose(model, data, noise(model, data)[0])
    assert diagnosis.selected == [] and diagnosis.ladder[0].score_heldout <= 1.3
