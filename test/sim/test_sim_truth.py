"""The simulator's truth: its own equilibrium obeys the mechanics and agrees with the package's solvers
where both model the same plant; its effect physics does what each effect's definition says.

The truth (sim/equilibrium.py, sim/physics.py) shares no code with the package's solvers
or effects; agreement here on effect-free plants is agreement of two formulations.
"""
from __future__ import annotations

import numpy as np
import pytest
import yaml
from lengths import random_lengths

from cable_winch_monitor.effects import PlantModel, effect_class
from cable_winch_monitor.model.plantfile.plant import load_plant
from cable_winch_monitor.model.solvers.elastic import solve_elastic
from cable_winch_monitor.model.solvers.solve import solve
from cable_winch_monitor.model.statics.result import SolveStatus
from cable_winch_monitor.sim.equilibrium import NoEquilibrium, Rig, Trajectory, equilibrium
from cable_winch_monitor.sim.scenario import ScenarioError, load_scenario
from cable_winch_monitor.sim.truth import Sample, TruthModel

PLANT = load_plant()
EA = 7.5e7


def rig(**changes) -> Rig:
    values = dict(anchors=PLANT.anchors, attachments=PLANT.attachments, cog=PLANT.cog, weight_scale=PLANT.weight,
                  lever_scale=PLANT.moment_scale)
    return Rig(**{**values, **changes})


def truth_model(tmp_path, effects: dict, ropes: dict | None = None) -> TruthModel:
    """The truth of a scenario hiding `effects`, a user's among them where its module is in `tmp_path`."""
    path = tmp_path / "scenario.yaml"
    modules = sorted(p.name for p in tmp_path.glob("*.py"))
    path.write_text(yaml.safe_dump({"effects": effects, "effect_modules": modules, **({"ropes": ropes} if ropes else {})}))
    return TruthModel(PLANT, load_scenario(path))


def assert_mechanics(state, lengths: np.ndarray, load: np.ndarray, ea: float | None = None, w: float = 0.0):
    """Balance recomputed from the points, tensions >= 0, taut spans at their (stretched) length,
    slack spans within it."""
    units = (state.exits - state.points_b) / np.linalg.norm(state.exits - state.points_b, axis=1)[:, None]
    pulls = state.tensions[:, None] * units
    force = pulls.sum(axis=0) + load[:3]
    moment = np.cross(state.points_b - state.point_c, pulls).sum(axis=0) + load[3:]
    weight = -load[2]
    assert np.linalg.norm(force) <= 1e-8 * weight
    assert np.linalg.norm(moment) <= 1e-8 * weight * PLANT.moment_scale
    assert state.tensions.min() >= 0.0
    spans = np.linalg.norm(state.exits - state.points_b, axis=1)
    vertical = (state.exits[:, 2] - state.points_b[:, 2]) / spans
    stretched = lengths if ea is None else lengths * (1.0 + (state.tensions + w * lengths * vertical / 2.0) / ea)
    assert np.all(spans[~state.taut] <= stretched[~state.taut] + 1e-7)
    assert np.allclose(spans[state.taut], stretched[state.taut], atol=1e-7, rtol=0.0)


def test_rigid_truth_agrees_with_the_package_solver_on_random_lengths():
    """Same taut set (or no equilibrium of two or more ropes where the package finds a single-cable hang),
    poses within 1 mm, tensions within 1 N: rigid ropes at generic lengths fix both."""
    checked, states = 0, set()
    for lengths in random_lengths(150, seed=14):
        package = solve(PLANT, lengths, "energy")
        if package.status is SolveStatus.SINGLE_CABLE_INDETERMINATE:
            with pytest.raises(NoEquilibrium):
                equilibrium(rig(), lengths, PLANT.wrench)
            continue
        state = equilibrium(rig(), lengths, PLANT.wrench)
        assert_mechanics(state, lengths, PLANT.wrench)
        assert np.array_equal(state.taut, package.taut), (lengths, package.taut_set)
        assert np.abs(state.points_b - package.points_b).max() < 1e-3
        assert np.abs(state.tensions - package.tensions).max() < 1.0
        checked, states = checked + 1, states | {int(state.taut.sum())}
    assert checked > 100 and states == {2, 3}


@pytest.mark.parametrize("w", [0.0, 60.0])
def test_elastic_truth_agrees_with_the_package_solver_along_a_lowering(w):
    """Hooke ropes (EA/l), warm-started along a lowering with drifting winches. Both formulations solve
    the same balance to ~1e-9 of the weight, so they must agree as closely as rigid ones: pose within 1 mm,
    tensions within 1 N. With the ropes' weight the package lengthens each rope by w l^2 / (2 EA), the
    truth by its vertical share w l^2 cos(theta) / (2 EA): at rope angles below 1 deg that differs by
    less than 2e-4 of the stretch (< 0.1 mm, < 0.1 N), inside the same bounds."""
    trajectory = Trajectory(rig(EA=EA, rope_weight=w))
    drift = 0.01 * np.sin(np.outer(np.linspace(0.0, 6.0, 200), [1.0, 1.3, 0.7, 1.9]))
    evaluations = []
    for step, payout in enumerate(np.linspace(50.0, 650.0, 200)):
        lengths = payout + drift[step]
        state = trajectory(step * 0.1, lengths, PLANT.wrench)
        evaluations.append(state.evaluations)
        assert_mechanics(state, lengths, PLANT.wrench, EA, w)
        package = solve_elastic(PLANT, lengths + w * lengths ** 2 / (2.0 * EA), EA)
        assert np.array_equal(state.taut, package.taut)
        assert np.abs(state.points_b - package.points_b).max() < 1e-3
        assert np.abs(state.tensions - package.tensions).max() < 1.0
    # warm starts: root's evaluations count its start twice, so 4-5 are two or three iterations
    assert np.median(evaluations[1:]) <= 5


def test_truth_mechanics_with_sheaves_load_and_body_effects(tmp_path):
    """Head sheaves (tangent point and wrap), the payout acceleration's load, the rope weight, a moved
    centre of gravity and extra mass: the truth still balances, and the ropes carry m (g - a)."""
    effects = {"sheave_geometry": {"r": 1.5}, "platform_acceleration": {}, "cog_offset": {"dx": 0.2, "dy": -0.1},
               "payload_mass": {"dm": 500.0}, "rope_weight": {"w": 40.0}}
    truth = truth_model(tmp_path, effects, {"model": "elastic", "EA": EA})
    for t, acceleration in ((0.0, 0.0), (0.1, 0.1), (0.2, -0.1)):
        lengths = np.array([30.0, 30.02, 30.01, 29.99]) + t
        solution, channels = truth(lengths, Sample(t, np.full(4, 0.5), acceleration, 15.0))
        state = truth.trajectory.history[-1][1]
        load = np.array([0.0, 0.0, -10500.0 * (PLANT.g - acceleration), 0.0, 0.0, 0.0])
        assert_mechanics(state, state.free_lengths, load, EA, 40.0)
        vertical = sum(solution.tensions * (state.exits[:, 2] - state.points_b[:, 2]) / state.spans)
        assert vertical == pytest.approx(10500.0 * (PLANT.g - acceleration), rel=1e-9)
        assert solution.force_residual < 1e-9 and solution.moment_residual < 1e-9


def test_sheave_truth_matches_the_package_description():
    """The same tangent-point geometry, formulated apart (root finding with the exit point inside the
    equations, against the package's fixed-point refinement): poses within 1 mm, tensions within 1 N."""
    model = PlantModel(PLANT, (effect_class("sheave_geometry")({"r": 2.0}),))
    from cable_winch_monitor.sim.truth import head_sheaves
    trajectory = Trajectory(rig(pulleys=head_sheaves(PLANT, 2.0)))
    for step, lengths in enumerate([np.array([12.0, 12.3, 12.1, 11.9]), np.array([12.5, 12.6, 12.4, 12.45])]):
        state = trajectory(float(step), lengths, PLANT.wrench)
        package = model.solve(lengths)
        assert np.array_equal(state.taut, package.taut)
        assert np.abs(state.points_b - package.points_b).max() < 1e-3
        assert np.abs(state.tensions - package.tensions).max() < 1.0


def test_measurement_physics(tmp_path):
    """Load pins: rope weight below the sheave, friction by direction of motion held through a stop,
    the bending sensor, calibration; inclinometer offset; encoder and temperature lengths."""
    effects = {"rope_weight": {"w": 50.0}, "sheave_friction": {"mu": 0.04, "wrap": 1.5},
               "tension_sensor_bending": {"B": 150.0, "span": 2.0},
               "load_pin_calibration": {"zero_1": 300.0, "gain_2": 0.01},
               "inclinometer_offset": {"roll": 0.002, "pitch": -0.001},
               "encoder_scale": {"k_3": 0.003}, "encoder_offset": {"d_1": 0.04},
               "rope_temperature": {"alpha": 1.2e-5, "T_ref": 10.0}}
    truth = truth_model(tmp_path, effects, {"model": "elastic", "EA": EA})
    reported = np.array([100.0, 100.01, 100.02, 99.99])
    readings = []
    for t, speed in ((0.0, 0.5), (0.1, 0.01), (0.2, -0.5)):  # lowering, within the dead band, hoisting
        solution, channels = truth(reported, Sample(t, np.full(4, speed), 0.0, 25.0))
        state = truth.trajectory.history[-1][1]
        expected_lengths = (np.array([1.0, 1.0, 1.003, 1.0]) * reported + [0.04, 0, 0, 0]) * (1 + 1.2e-5 * 15.0)
        assert np.allclose(state.free_lengths, expected_lengths, rtol=1e-14)
        top = solution.tensions + 50.0 * state.free_lengths * (state.exits[:, 2] - state.points_b[:, 2]) / state.spans
        friction = top * np.exp(-np.sign(speed if abs(speed) > 0.02 else 0.5) * 0.04 * 1.5)
        bent = friction * 2.0 / (2.0 - 3.0 * np.sqrt(150.0 / friction))
        pins = (1.0 + np.array([0, 0.01, 0, 0])) * bent + [300.0, 0, 0, 0]
        assert [channels[f"tension_cable_{i}"] for i in range(1, 5)] == pytest.approx(pins.tolist(), rel=1e-12)
        assert channels["roll"] == pytest.approx(state.angles[0] + 0.002)
        assert channels["pitch"] == pytest.approx(state.angles[1] - 0.001)
        readings.append(channels["tension_cable_1"])
    assert readings[0] == pytest.approx(readings[1]) and readings[2] > readings[0] * 1.1  # held, then e^(2 mu wrap)


@pytest.mark.parametrize("effects, message", [
    ({"rope_wieght": {"w": 3}}, "key 'effects.rope_wieght': unknown effect 'rope_wieght'"),
    ({"rope_weight": {"W": 3}}, "unknown key 'effects.rope_weight.W' (known: w)"),
    ({"rope_temperature": {"alpha": "warm"}}, "key 'effects.rope_temperature.alpha' must be a number"),
    ({"rope_elasticity": {"EA": 0}}, "key 'effects.rope_elasticity.EA' must be positive"),
    ({"payload_mass": {"enabled": "yes"}}, "key 'effects.payload_mass.enabled' must be true or false"),
])
def test_effect_errors_name_the_key(tmp_path, effects, message):
    path = tmp_path / "scenario.yaml"
    path.write_text(yaml.safe_dump({"effects": effects}))
    with pytest.raises(ScenarioError) as error:
        load_scenario(path)
    assert message in str(error.value)


SHIFTED_ANCHORS = """
from cable_winch_monitor.effects import Effect


class ShiftedAnchors(Effect):
    name = "test_shifted_anchors"
    acts = "geometry"
"""
PIN_BIAS = """
from cable_winch_monitor.effects import Effect, Parameter


class PinBias(Effect):
    name = "test_pin_bias"
    acts = "measurement"
    parameters = (Parameter("b", "N", 0.0, (-1e4, 1e4), 100.0),)

    def measure(self, channels, solution, plant, conditions):
        channels["tension_cable_2"] += self["b"] + conditions.inputs["/shaft/temperature.temperature"]
"""


def test_a_users_geometry_effect_cannot_enter_the_truth(tmp_path):
    """Only measurement effects of a user's module are applied to the truth's channels: a geometry effect
    would make the truth the package's model again."""
    (tmp_path / "anchors.py").write_text(SHIFTED_ANCHORS)
    path = tmp_path / "scenario.yaml"
    path.write_text(yaml.safe_dump({"effects": {"test_shifted_anchors": {}}, "effect_modules": ["anchors.py"]}))
    with pytest.raises(ScenarioError, match="only measurement effects of a user's module .* acts on the geometry"):
        load_scenario(path)


def test_a_users_effect_needs_its_module_named(tmp_path):
    path = tmp_path / "scenario.yaml"
    path.write_text(yaml.safe_dump({"effects": {"test_pin_bias": {"b": 1.0}}}))
    with pytest.raises(ScenarioError, match="unknown effect 'test_pin_bias'.*effect_modules or --effect-module"):
        load_scenario(path)


def test_a_users_measurement_effect_edits_the_truths_channels(tmp_path):
    """A user's measurement effect is applied after the built-in ones, seeing the sample's conditions."""
    (tmp_path / "bias.py").write_text(PIN_BIAS)
    plain = truth_model(tmp_path, {"rope_weight": {"w": 50.0}})
    biased = truth_model(tmp_path, {"rope_weight": {"w": 50.0}, "test_pin_bias": {"b": 700.0}})
    sample = Sample(0.0, np.zeros(4), 0.0, 12.0)
    lengths = np.array([40.0, 40.01, 40.0, 39.99])
    (_, want), (_, got) = plain(lengths, sample), biased(lengths, sample)
    assert got["tension_cable_2"] == pytest.approx(want["tension_cable_2"] + 712.0)
    assert got["tension_cable_1"] == want["tension_cable_1"]
