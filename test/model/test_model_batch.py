"""`PlantModel.solve_batch` gives `PlantModel.solve`'s answers, and the analysis uses it.

Effects that act through the rope law (elastic ropes, their weight), the geometry before
the solve (encoder scale, centre of gravity), the load (a side pull here, growing with
the payout speed) and the measurement (sheave friction) are solved in one batch; a
sheave's pose-dependent geometry is solved sample by sample inside it. Same status and
taut set, tensions within 1 N, poses within 1 mm, and every state balances its load.
"""
from __future__ import annotations

import numpy as np
import pytest
from simbags import simulated

from cable_winch_monitor.analysis.data import read_bag
from cable_winch_monitor.analysis.evaluate import Evaluator
from cable_winch_monitor.bench.plants import realistic
from cable_winch_monitor.bench.solvers import lowering_samples
from cable_winch_monitor.effects import PlantModel
from cable_winch_monitor.effects.base import Effect, Parameter
from cable_winch_monitor.effects.body import CogOffset
from cable_winch_monitor.effects.encoder import EncoderScale
from cable_winch_monitor.effects.sheave import SheaveGeometry
from cable_winch_monitor.model.conditions import Conditions
from cable_winch_monitor.model.statics.result import SolveStatus


class SidePull(Effect):
    """A horizontal pull on the platform proportional to the mean payout speed (a guide rope's drag)."""

    name = "side_pull_for_test"
    acts = "load"
    parameters = (Parameter("drag", "N s/m", 2000.0, (0.0, 1e5), 100.0),)

    def load(self, wrench, plant, conditions):
        speed = float(np.nanmean(conditions.speeds)) if np.isfinite(conditions.speeds).any() else 0.0
        if speed > 0.45:
            raise ValueError("drag table ends at 0.45 m/s")
        return wrench + np.array([self["drag"] * speed, 0.0, 0.0, 0.0, 0.0, 0.0])


def trajectory(count: int) -> tuple[np.ndarray, list[Conditions]]:
    lengths = lowering_samples(count)[:, :] * 0.2 + 10.0
    speeds = np.linspace(0.0, 0.5, count)
    return lengths, [Conditions(time=0.1 * k, speeds=np.full(4, v), direction=np.ones(4))
                     for k, v in enumerate(speeds)]


def per_sample(model, lengths, conditions):
    solutions, warm = [], None
    for row, at in zip(lengths, conditions):
        solutions.append(model.solve(row, warm, at))
        warm = solutions[-1] if solutions[-1].ok else warm
    return solutions


def assert_same(got, want):
    assert len(got) == len(want)
    for i, (g, w) in enumerate(zip(got, want)):
        assert g.status is w.status and g.taut_set == w.taut_set, i
        assert g.message == w.message, i
        if w.ok:
            assert np.abs(g.tensions - w.tensions).max() < 1.0, i
            assert np.abs(g.points_b - w.points_b).max() < 1e-3, i
            np.testing.assert_allclose(g.load, w.load, atol=1e-9)
            assert g.force_residual < 1e-6 and g.moment_residual < 1e-6 and g.tensions.min() >= 0.0, i


@pytest.mark.parametrize("elastic", [False, True])
def test_effects_before_the_solve_batched_as_per_sample(plant, elastic):
    effects = [EncoderScale({"k_2": 2e-3}), CogOffset({"dx": 0.05}), SidePull()]
    model = PlantModel.from_plant(realistic(plant) if elastic else plant).with_effects(effects)
    assert model.batchable
    lengths, conditions = trajectory(400)
    got = model.solve_batch(lengths, conditions)
    want = per_sample(model, lengths, conditions)
    assert_same(got, want)
    # where a hook raises, the sample is an invalid input naming the effect (it was solved under gravity alone,
    # as if the effect were off), batched or not
    assert got[-1].status is SolveStatus.INVALID_INPUT
    assert got[-1].message == "effect 'side_pull_for_test': its load hook raised ValueError: drag table ends at 0.45 m/s"
    assert 350 < sum(s.ok for s in want) < 400
    pulled = [s for s in got if s.ok and s.load[0] > 500.0]
    assert pulled and all(s.point_c[0] > got[0].point_c[0] for s in pulled)  # the pull moves the platform


def test_pose_dependent_geometry_solved_sample_by_sample(plant):
    model = PlantModel.from_plant(realistic(plant)).with_effects([SheaveGeometry({"r": 1.0})])
    assert not model.batchable
    lengths, conditions = trajectory(30)
    assert_same(model.solve_batch(lengths, conditions), per_sample(model, lengths, conditions))


def test_evaluator_solves_the_realistic_plant_in_batches(tmp_path, plant):
    exact = {key: value for key, value in plant.noise.items() if key != "length"}  # the solves, not the fused estimate
    model = PlantModel.from_plant(realistic(plant).with_changes(noise=exact))
    data = read_bag(simulated(tmp_path, "benchmark", "duration=40.0"), model)
    evaluator = Evaluator(data)
    got = evaluator.solutions(model)
    assert evaluator.solves == len(data) > 300
    assert_same(got, per_sample(model, data.lengths, evaluator.conditions))
    assert evaluator.solutions(model.with_effects([model.get("sheave_friction").replaced(mu=0.1)])) is got
    residuals = evaluator.residuals(model)
    assert np.isfinite(residuals).any()
