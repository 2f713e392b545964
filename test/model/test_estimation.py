"""The estimator: lengths alone give today's forward kinematics; load pins resolve the rigid weak mode.

Truth on the weak mode comes from `weakmode_truth` (balance as forces and moments on the
platform, solved by scipy's root finder), with the realistic noise: encoders 1 mm, load
pins 150 N, inclinometer 0.01 deg, depth gauge 5 mm.
"""
from __future__ import annotations

import numpy as np
import pytest
from lengths import random_lengths
from root_truth import elastic_truth, weak_mode_samples, weak_mode_truth

from cable_winch_monitor.bench.node_latency import lowering
from cable_winch_monitor.bench.solvers import lowering_samples
from cable_winch_monitor.model.estimator import estimate, estimate_batch, estimation
from cable_winch_monitor.model.estimator import observations as obs
from cable_winch_monitor.model.estimator.prior import Prior
from cable_winch_monitor.model.solvers.elastic import solve_elastic
from cable_winch_monitor.model.solvers.energy import solve_energy
from cable_winch_monitor.model.statics.result import SolveStatus, check_physics

PIN, TILT, DEPTH, ENCODER = 150.0, np.radians(0.01), 5e-3, 1e-3


def assert_forward_kinematics(plant, got, want):
    assert got.solution.status is want.status
    if want.status is SolveStatus.SINGLE_CABLE_INDETERMINATE:
        assert got.solution.single_cable == want.single_cable
        return
    assert want.ok
    assert got.solution.taut_set == want.taut_set
    assert np.abs(got.solution.points_b - want.points_b).max() < 1e-6
    assert np.abs(got.solution.tensions - want.tensions).max() < 1.0
    assert np.abs(got.corrections).max() < 1e-9
    assert check_physics(plant, got.loaded_solution).passes()


def test_lengths_alone_give_forward_kinematics(plant):
    lengths = random_lengths(150, seed=1111)
    batch = estimate_batch(plant, lengths).estimates()
    for row, fused in zip(lengths, batch):
        want = solve_energy(plant, row)
        assert_forward_kinematics(plant, estimate(plant, row), want)
        assert_forward_kinematics(plant, fused, want)


def test_lengths_alone_warm_started_along_a_lowering(plant):
    previous = None
    sets = set()
    for row in lowering_samples(300):
        previous = estimate(plant, row, warm_start=previous)
        assert_forward_kinematics(plant, previous, solve_energy(plant, row))
        sets.add(previous.solution.taut_set)
    assert len(sets) >= 2  # the taut set changes along the lowering


def test_lengths_alone_elastic_ropes(plant):
    ea, weight = 75e6, 60.0
    lengths = random_lengths(60, seed=77)
    batch = estimate_batch(plant, lengths, axial_stiffness=ea, rope_weight=weight).estimates()
    for row, fused in zip(lengths, batch):
        want = solve_elastic(plant, row + weight * row ** 2 / (2.0 * ea), ea)
        for got in (estimate(plant, row, axial_stiffness=ea, rope_weight=weight), fused):
            assert_forward_kinematics(plant, got, want)
            if got.ok:  # a taut rope's span is its corrected length stretched by Hooke and its own weight
                stretched = (got.solution.lengths + weight * got.solution.lengths ** 2 / (2 * ea)) * (
                    1.0 + got.solution.tensions / ea)
                taut = got.solution.taut
                np.testing.assert_allclose(got.solution.spans[taut], stretched[taut], rtol=1e-12)


def test_lengths_alone_under_another_load(plant):
    heavier = plant.with_changes(mass=1.3 * plant.mass)  # the same balance as 1.3 m g of gravity
    for row in random_lengths(30, seed=5):
        got = estimate(plant, row, load=1.3 * plant.wrench)
        want = solve_energy(heavier, row)
        assert got.solution.status is want.status
        if want.ok:
            assert got.solution.taut_set == want.taut_set
            assert np.abs(got.solution.points_b - want.points_b).max() < 1e-6
            assert np.abs(got.solution.tensions - want.tensions).max() < 1.0
            assert check_physics(plant, got.solution).passes()  # balanced against the load it was given
    lengths = random_lengths(30, seed=5)
    braking = np.outer(np.linspace(1.0, 1.3, len(lengths)), plant.wrench)  # one load per sample
    for row, load, got in zip(lengths, braking, estimate_batch(plant, lengths, loads=braking).estimates()):
        want = solve_energy(plant, row, load=load)
        assert got.solution.status is want.status
        if want.ok:
            assert got.solution.taut_set == want.taut_set
            assert np.abs(got.solution.tensions - want.tensions).max() < 1.0
            assert check_physics(plant, got.solution).passes()
    side_pull = plant.wrench + np.array([2e3, -1e3, 0.0, 0.0, 0.0, 500.0])
    for row in random_lengths(30, seed=6):
        got = estimate(plant, row, load=side_pull)
        want = solve_energy(plant, row, load=side_pull)
        assert got.solution.status is want.status
        if want.ok:
            assert got.solution.taut_set == want.taut_set
            assert np.abs(got.solution.points_b - want.points_b).max() < 1e-6
            assert check_physics(plant, got.solution).passes()


def measured(truth, rng: np.random.Generator, pins: bool = True) -> tuple[np.ndarray, list[obs.Observation]]:
    """Reported lengths and the sensors' readings of a truth, with the noise of the plant's sensors."""
    lengths = truth.lengths + rng.normal(0.0, ENCODER, 4)
    readings = [obs.roll(truth.roll + rng.normal(0.0, TILT), TILT), obs.pitch(truth.pitch + rng.normal(0.0, TILT), TILT),
                obs.position_component(2, truth.position[2] + rng.normal(0.0, DEPTH), DEPTH)]
    if pins:
        readings += [obs.load_pin(i, truth.tensions[i] + rng.normal(0.0, PIN), PIN) for i in range(4)]
    return lengths, readings


@pytest.fixture(scope="module")
def weak_mode(plant):
    truths = weak_mode_samples(plant, 400, seed=11)
    rng = np.random.default_rng(12)
    return truths, [measured(t, rng) for t in truths]


def stacked(samples) -> tuple[np.ndarray, list[obs.Observation]]:
    """The samples' lengths (N, 4) and their observations with (N,) values, for the batched estimator."""
    lengths = np.array([s[0] for s in samples])
    return lengths, [samples[0][1][k].with_value(np.array([s[1][k].value for s in samples]))
                     for k in range(len(samples[0][1]))]


def test_load_pins_resolve_the_weak_mode(plant, weak_mode):
    truths, samples = weak_mode
    lengths, readings = stacked(samples)
    truth = np.array([t.tensions for t in truths])
    fused = estimate_batch(plant, lengths, readings, sigma_length=ENCODER)
    for got in fused.estimates():
        assert got.ok and got.fused
        assert set(got.used) == {"roll", "pitch", "depth"} | {f"tension_cable_{i}" for i in range(1, 5)}
        assert check_physics(plant, got.solution).passes()
        assert np.abs(got.solution.lengths - got.reported - got.corrections).max() < 1e-12
    assert np.mean(np.abs(fused.tensions - truth).max(axis=1) <= 3.0 * PIN) >= 0.995
    assert np.median(np.abs(fused.corrections / ENCODER)) < 1.0  # the lengths move within their noise
    lengths_only = estimate_batch(plant, lengths)
    assert np.median(np.abs(lengths_only.tensions - truth).max(axis=1)) > 5e3  # they miss by kilonewtons


def test_batched_estimate_is_the_per_sample_one(plant, weak_mode):
    truths, samples = weak_mode
    truths, samples = truths[:150], samples[:150]
    lengths, readings = stacked(samples)
    readings[2] = readings[2].with_value(np.where(np.arange(150) % 5 == 0, readings[2].value, np.nan))  # depth at 2 Hz
    batch = estimate_batch(plant, lengths, readings, sigma_length=ENCODER)
    for i, (truth, got) in enumerate(zip(truths, batch.estimates())):
        one = estimate(plant, lengths[i], [r.with_value(r.value[i]) for r in readings], sigma_length=ENCODER)
        assert got.solution.taut_set == one.solution.taut_set
        assert np.abs(got.solution.tensions - one.solution.tensions).max() < 1.0
        assert np.abs(got.solution.points_b - one.solution.points_b).max() < 1e-6
        assert ("depth" in got.used) == (i % 5 == 0)
        assert np.abs(got.solution.tensions - truth.tensions).max() <= 3.0 * PIN
        assert got.chi_square == pytest.approx(one.chi_square, rel=1e-6, abs=1e-9)


def test_sets_the_load_pins_rule_out_are_not_solved_and_nothing_else_changes(plant, monkeypatch):
    """A set that leaves a rope slack whose pin reads kilonewtons costs at least (reading / sigma)^2
    whatever the pose: the search does not solve it where the best so far costs less. Live (each
    sample warm-started from the last) along the node benchmark's lowering, whose winches drift 2 mm
    against each other so that the taut set switches between three and four ropes, the estimates are
    those of the search that solves every such set, to the bit, with far fewer candidates solved."""
    readings = lowering(400, 50.0)
    solved_rows = []
    solve = estimation.solve_rows

    def counting(problem, rows):
        solved_rows.append(len(rows.sample))
        return solve(problem, rows)

    def along():
        solved_rows.clear()
        out, previous = [], None
        for row in readings:
            pins = [obs.load_pin(i, value, PIN) for i, value in enumerate(row[4:])]
            previous = estimate(plant, row[:4], pins, sigma_length=ENCODER, warm_start=previous)
            out.append(previous)
        return out, sum(solved_rows)

    monkeypatch.setattr(estimation, "solve_rows", counting)
    pruned, pruned_rows = along()
    monkeypatch.setattr(estimation, "_pinned_cost", lambda problem, samples, codes: np.zeros(len(samples)))
    every, every_rows = along()
    assert len({e.solution.taut_set for e in every}) >= 3
    for got, want in zip(pruned, every):
        assert got.fused and got.solution.taut_set == want.solution.taut_set
        assert got.solution.tensions.tobytes() == want.solution.tensions.tobytes()
        assert got.solution.points_b.tobytes() == want.solution.points_b.tobytes()
        assert check_physics(plant, got.solution).passes()
    assert pruned_rows < 0.75 * every_rows


def test_equal_lengths_with_load_pins_do_not_depend_on_history(plant):
    truth = weak_mode_truth(plant, 300.0, np.zeros(3), 12e3)
    np.testing.assert_allclose(truth.lengths, 300.0, atol=1e-9)
    rng = np.random.default_rng(3)
    readings = [obs.load_pin(i, truth.tensions[i] + rng.normal(0.0, PIN), PIN) for i in range(4)]
    histories = [None]
    for previous in ([300.02, 300.0, 300.01, 300.0], [300.0, 300.02, 300.0, 300.01], [299.0, 299.0, 299.0, 299.0]):
        histories.append(estimate(plant, previous))
        histories.append(estimate(plant, previous, measured(weak_mode_truth(plant, 300.0, np.zeros(3), -20e3), rng)[1]))
    results = [estimate(plant, truth.lengths, readings, warm_start=h) for h in histories]
    assert {r.solution.taut_set for r in results} == {(1, 2, 3, 4)}
    tensions = np.array([r.solution.tensions for r in results])
    assert np.abs(tensions - tensions[0]).max() < 1.0
    assert np.abs(tensions[0] - truth.tensions).max() <= 3.0 * PIN
    without_pins = [estimate(plant, truth.lengths, warm_start=h).solution.tensions for h in histories]
    assert np.ptp(np.array(without_pins), axis=0).max() > 1e3  # the lengths alone leave the share to the history


def test_elastic_ropes_fused(plant):
    ea, weight = 75e6, 60.0
    rng = np.random.default_rng(21)
    truths = [t for t in (elastic_truth(plant, rng.uniform(50.0, 650.0) + rng.uniform(-0.05, 0.05, 4), ea, weight)
                          for _ in range(160)) if t is not None]
    assert len(truths) >= 150
    lengths, readings = stacked([measured(t, rng) for t in truths])
    truth = np.array([t.tensions for t in truths])
    fused = estimate_batch(plant, lengths, readings, ENCODER, axial_stiffness=ea, rope_weight=weight)
    lengths_only = estimate_batch(plant, lengths, axial_stiffness=ea, rope_weight=weight)
    error = np.abs(fused.tensions - truth).max(axis=1)
    assert np.mean(error <= 3.0 * PIN) >= 0.995
    assert np.sqrt(np.mean(error ** 2)) < 0.7 * np.sqrt(np.mean(np.abs(lengths_only.tensions - truth).max(axis=1) ** 2))
    for got in fused.estimates():
        assert got.fused and check_physics(plant, got.loaded_solution).passes()


def test_declared_channel_with_numerical_gradient(plant, weak_mode):
    truths, samples = weak_mode
    lengths, readings = samples[0]
    built_in = estimate(plant, lengths, readings, sigma_length=ENCODER)
    declared = [obs.Observation(r.name, r.value, r.sigma, r.predict) for r in readings]  # no gradients
    got = estimate(plant, lengths, declared, sigma_length=ENCODER)
    assert np.abs(got.solution.tensions - built_in.solution.tensions).max() < 1.0
    assert np.abs(got.solution.points_b - built_in.solution.points_b).max() < 1e-6
    # a channel of the user's own: a hoist load cell reading the sum of the rope tensions
    total = obs.Observation("hoist_load", float(truths[0].tensions.sum()), 300.0, lambda s: s.tensions.sum(axis=1))
    with_total = estimate(plant, lengths, readings + [total], sigma_length=ENCODER)
    assert "hoist_load" in with_total.used and abs(with_total.residuals["hoist_load"]) < 3.0


def test_bad_input_is_a_status(plant):
    assert estimate(plant, [1.0, 2.0, float("nan"), 3.0]).solution.status is SolveStatus.INVALID_INPUT
    failed = estimate(plant, [20.0] * 4, axial_stiffness=-1.0)
    assert failed.solution.status is SolveStatus.INVALID_INPUT and "EA" in failed.solution.message
    upward = estimate(plant, [20.0] * 4, load=-plant.wrench)
    assert upward.solution.status is SolveStatus.INVALID_INPUT and "load" in upward.solution.message
    with pytest.raises(ValueError, match="'depth'.*sigma"):
        obs.position_component(2, -20.0, 0.0)
    wrong = obs.Observation("gauge", 1.0, 1.0, lambda s: 0.0)  # one number, not one per state
    message = estimate(plant, [20.0] * 4, [wrong]).solution.message
    assert "'gauge'" in message and "one value per state" in message
    two = estimate(plant, [20.0] * 4, [obs.roll(np.zeros(2), 1e-4)])
    assert two.solution.status is SolveStatus.INVALID_INPUT and "2 values for 1 samples" in two.solution.message


@pytest.mark.parametrize("covariance, message", [
    (np.array([[1.0, 0.1, 0.0, 0.0], [0.2, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]), "symmetric"),
    (-np.eye(4), "positive definite"),
    (np.diag([1.0, 1.0, 0.0, 1.0]), "positive definite"),
    (np.full((4, 4), np.nan), "finite"),
])
def test_a_prior_that_is_no_covariance_is_refused_by_name(plant, covariance, message):
    eye = np.stack([np.eye(4)] * 2)
    bad = Prior(np.zeros((2, 4)), eye * 1e-3 ** 2, np.zeros((2, 4)), np.stack([np.eye(4), covariance]))
    with pytest.raises(ValueError, match=f"prior pin_covariance must be {message}"):
        estimate_batch(plant, np.full((2, 4), 200.0), prior=bad)
