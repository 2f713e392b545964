"""The compiled inner loops: their Jacobians are the derivatives of their residuals, their weighing, moves and
slack pins' bounds the matrix products they stand for, and a row's answer does not depend on the rows solved with
it (a singular or undefined row beside it included)."""
from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from cable_winch_monitor.model.solvers import compiled
from cable_winch_monitor.model.solvers.ropes import Ropes
from cable_winch_monitor.model.statics.geometry import rotations_from_vectors, skew

EA = np.array([6.8e7, 7.0e7, 6.5e7, 7.2e7])
H = 1e-5  # central-difference step [m, rad, mu]: smaller, rounding of 600 m spans shows


def _terms(plant, state: np.ndarray, taut: np.ndarray, lengths: np.ndarray, ea: np.ndarray, rope_weight: float,
           tilt: np.ndarray):
    """Rope residuals (4,), imbalance (6,), their Jacobians (4, 10), (6, 10) at `state` (10,): position, a rotation
    vector applied on the left of the rotation `tilt` (1, 3, 3), mu."""
    rotation = rotations_from_vectors(state[None, 3:6]) @ tilt
    residual, constraint = np.empty((1, 4)), np.empty((1, 6))
    jacobian, balance = np.empty((1, 4, 10)), np.empty((1, 6, 10))
    weight = 1e5
    load = np.array([[0.0, 0.0, -1.0, 0.0, 0.0, 0.0]])
    compiled.equilibrium_terms(rotation, state[None, :3].copy(), state[None, 6:].copy(), taut[None].view(np.uint8),
                               np.array([weight]), lengths[None], np.ascontiguousarray(plant.anchors[None]),
                               plant.attachments, plant.cog, load, ea, rope_weight, plant.moment_scale, 1e-3,
                               residual, constraint, jacobian, balance, True)
    return residual[0], constraint[0], jacobian[0], balance[0]


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2 ** 31 - 1), st.booleans(), st.sampled_from([0.0, 60.0]))
def test_the_jacobians_are_the_residuals_derivatives(plant, seed, elastic, rope_weight):
    rng = np.random.default_rng(seed)
    depth = rng.uniform(50.0, 600.0)
    taut = rng.random(4) < 0.75
    tilt = rotations_from_vectors(rng.normal(0.0, 0.01, (1, 3)))
    state = np.concatenate([rng.normal(0.0, 0.05, 3) + [0.0, 0.0, -depth], np.zeros(3),
                            np.where(taut, rng.uniform(0.1, 0.4, 4), 0.0)])
    ea = EA if elastic else np.zeros(4)
    spans = _terms(plant, state, np.ones(4, bool), np.zeros(4), np.zeros(4), 0.0, tilt)[0] * 1e-3  # rigid: spans
    lengths = spans + np.where(taut, rng.normal(0.0, 0.01, 4), -0.5)  # slack ropes overstretched by 0.5 m
    residual, constraint, jacobian, balance = _terms(plant, state, taut, lengths, ea, rope_weight, tilt)
    for k in range(10):
        step = np.zeros(10)
        step[k] = H
        if k >= 6 and not taut[k - 6]:
            continue  # a slack rope's tension is not a coordinate of its residuals
        up, down = (_terms(plant, state + s, taut, lengths, ea, rope_weight, tilt) for s in (step, -step))
        np.testing.assert_allclose(jacobian[:, k], (up[0] - down[0]) / (2 * H), rtol=1e-5, atol=1e-4)
        np.testing.assert_allclose(balance[:, k], (up[1] - down[1]) / (2 * H), rtol=1e-5, atol=1e-7)
    assert np.all(residual[~taut] > 0.0)  # an overstretched slack rope has a residual, a one-sided one


def _newton(plant, lengths: np.ndarray, taut: np.ndarray):
    n = len(lengths)
    rotation = np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
    position = np.zeros((n, 3))
    position[:, 2] = -lengths.mean(axis=1)
    mu = np.zeros((n, 4))
    mu[:, taut] = 1.0 / taut.size
    steps, converged = np.zeros(n, np.int64), np.zeros(n, np.uint8)
    loads = np.tile([0.0, 0.0, -1.0, 0.0, 0.0, 0.0], (n, 1))
    compiled.newton_taut_set(lengths, rotation, position, mu, loads, steps, taut, plant.attachments, plant.cog,
                             plant.anchors, plant.moment_scale, np.full(n, 1e-12), 15, converged, 0.2,
                             0.2 * plant.moment_scale)
    return rotation, position, mu, converged.astype(bool)


def _lstsq_step(plant, lengths: np.ndarray, rotation: np.ndarray, position: np.ndarray, mu: np.ndarray,
                taut: np.ndarray, load: np.ndarray):
    """One Newton step on the taut cables' KKT conditions, written in numpy, its system (6 + k unknowns) solved
    by numpy's lstsq: the rotation, position and mu after it."""
    scale = plant.moment_scale
    points = position + plant.attachments @ rotation.T
    arms, arm_c = points - position, rotation @ plant.cog
    spans = points - plant.anchors
    norms = np.linalg.norm(spans, axis=1)
    u, r, q, m = spans[taut] / norms[taut, None], arms[taut], (arms - arm_c)[taut], mu[taut, None, None]
    moments = np.cross(q, u)
    residual = np.concatenate([u.T @ mu[taut] - load[:3], (moments.T @ mu[taut] - load[3:]) / scale,
                               norms[taut] - lengths[taut]])
    projector = (np.eye(3) - u[:, :, None] * u[:, None, :]) / norms[taut, None, None]
    sr, sq, su = skew(r), skew(q), skew(u)
    weighted = m * projector
    jacobian = np.zeros((6 + taut.size, 6 + taut.size))
    jacobian[0:3, 0:3] = weighted.sum(axis=0)
    jacobian[0:3, 3:6] = -(weighted @ sr).sum(axis=0)
    jacobian[3:6, 0:3] = ((m * sq @ projector) / scale).sum(axis=0)
    jacobian[3:6, 3:6] = ((m * (su @ sq - sq @ projector @ sr)) / scale).sum(axis=0)
    jacobian[0:3, 6:], jacobian[3:6, 6:] = u.T, moments.T / scale
    jacobian[6:, 0:3], jacobian[6:, 3:6] = u, np.cross(r, u)
    step = np.linalg.lstsq(jacobian, -residual, rcond=1e-13)[0]
    step /= max(np.abs(step[3:6]).max() / 0.2, np.abs(step[0:3]).max() / (0.2 * scale), 1.0)
    moved = mu.copy()
    moved[taut] += step[6:]
    return rotations_from_vectors(step[None, 3:6])[0] @ rotation, position + step[:3], moved


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2 ** 31 - 1), st.sampled_from([(0, 1, 2, 3), (1,), (0, 2)]), st.booleans())
def test_a_minimum_norm_step_is_numpys_least_squares_step(plant, seed, taut, redundant):
    """Four taut ropes (or one) make a system that is singular where the set is redundant: four equal lengths
    at a level pose, or no rope loaded yet. A step of minimum norm is numpy lstsq's (rcond 1e-13) there and
    elsewhere, and an exact step stops such a row."""
    rng = np.random.default_rng(seed)
    taut = np.array(taut)
    depth = rng.uniform(50.0, 600.0)
    rotation = np.eye(3) if redundant else rotations_from_vectors(rng.normal(0.0, 0.01, (1, 3)))[0]
    position = np.array([0.0, 0.0, -depth]) + (0.0 if redundant else rng.normal(0.0, 0.05, 3))
    mu = np.zeros(4) if redundant else np.where(np.isin(np.arange(4), taut), rng.uniform(0.1, 0.4, 4), 0.0)
    lengths = np.full(4, depth + 0.01) if redundant else depth + rng.normal(0.0, 0.02, 4)
    load = np.array([0.0, 0.0, -1.0, 0.0, 0.0, 0.0])
    want = _lstsq_step(plant, lengths, rotation, position, mu, taut, load)
    got = rotation[None].copy(), position[None].copy(), mu[None].copy()
    steps, converged = np.zeros(1, np.int64), np.zeros(1, np.uint8)
    compiled.newton_taut_set(lengths[None], *got, load[None], steps, taut.astype(np.int64), plant.attachments,
                             plant.cog, plant.anchors, plant.moment_scale, np.array([0.0]), 1, converged, 0.2,
                             0.2 * plant.moment_scale, minimum_norm=True)
    assert steps[0] == 1
    for value, expected in zip(got, want):  # to the rounding of a system whose condition number is up to 1e8
        np.testing.assert_allclose(value[0], expected, rtol=1e-7, atol=1e-8)
    if redundant and taut.size == 4:
        exact = rotation[None].copy(), position[None].copy(), mu[None].copy()
        steps[0] = 0
        compiled.newton_taut_set(lengths[None], *exact, load[None], steps, taut.astype(np.int64), plant.attachments,
                                 plant.cog, plant.anchors, plant.moment_scale, np.array([0.0]), 1, converged, 0.2,
                                 0.2 * plant.moment_scale)
        assert steps[0] == 0  # singular: no exact step


def _spans_and_balance(plant, rotation, position, mu, taut, lengths):
    """Each rigid row's span minus length per rope (4,) (a slack rope's only where overstretched) and its force
    and moment imbalance under gravity (6,), per |f|."""
    n = len(mu)
    residual, constraint = np.empty((n, 4)), np.empty((n, 6))
    compiled.equilibrium_terms(rotation, position, mu, taut.view(np.uint8), np.ones(n), lengths,
                               np.ascontiguousarray(np.broadcast_to(plant.anchors, (n, 4, 3))), plant.attachments,
                               plant.cog, np.tile([0.0, 0.0, -1.0, 0.0, 0.0, 0.0], (n, 1)), np.zeros(4), 0.0,
                               plant.moment_scale, 1.0, residual, constraint, np.empty((0, 4, 10)), np.empty((0, 6, 10)),
                               False)
    return residual, constraint


def test_a_rows_answer_does_not_depend_on_the_rows_beside_it(plant):
    rng = np.random.default_rng(3)
    lengths = 200.0 + rng.normal(0.0, 0.02, (6, 4))
    lengths[2] = np.nan        # undefined
    lengths[4] = 0.0           # no span can be this short: singular or not converging
    taut = np.array([0, 1, 2], np.int64)
    together = _newton(plant, lengths, taut)
    for row in (0, 1, 3, 5):
        alone = _newton(plant, lengths[row:row + 1].copy(), taut)
        assert together[3][row] and alone[3][0]
        for a, b in zip(together, alone):
            assert np.array_equal(a[row], b[0])
    assert not together[3][2]
    rotation, position, mu, converged = together  # where converged: force and moment balance, spans = lengths
    mask = np.zeros((len(mu), 4), bool)
    mask[:, taut] = True
    residual, constraint = _spans_and_balance(plant, rotation, position, mu, mask, lengths)
    assert np.abs(constraint[converged]).max() < 1e-12
    assert np.abs(residual[converged][:, taut]).max() < 1e-10


def _active_set(plant, lengths: np.ndarray, start: np.ndarray):
    """The compiled search over taut sets from the level pose at each row's mean length, with the taut set `start`."""
    n = len(lengths)
    rotation = np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
    position = np.zeros((n, 3))
    position[:, 2] = -np.nan_to_num(lengths).mean(axis=1)
    active = np.tile(start.astype(np.uint8), (n, 1))
    mu = np.tile(start / start.sum(), (n, 1))
    steps, done = np.zeros(n, np.int64), np.zeros(n, np.uint8)
    loads = np.tile([0.0, 0.0, -1.0, 0.0, 0.0, 0.0], (n, 1))
    compiled.active_set_rows(lengths, rotation, position, mu, active, loads, steps, done, plant.attachments, plant.cog,
                             plant.anchors, plant.moment_scale, np.full(n, 1e-12), 15, 12, 0.3, np.full(n, 1e-10),
                             1e-9, 0.2, 0.2 * plant.moment_scale)
    return rotation, position, mu, active.astype(bool), done.astype(bool)


def test_the_search_over_taut_sets_settles_each_row_on_its_own(plant):
    """Rows whose winches paid out unevenly, started on the wrong taut set: each is done on an admissible set
    (balanced, taut tensions not negative, slack ropes not longer than their lengths), with the same bits
    alone as beside an undefined and a degenerate row."""
    rng = np.random.default_rng(5)
    lengths = 300.0 + rng.normal(0.0, 0.05, (7, 4))
    lengths[2] = np.nan
    lengths[5] = 0.0
    start = np.array([True, True, False, False])
    together = _active_set(plant, lengths, start)
    rotation, position, mu, taut, done = together
    good = np.array([0, 1, 3, 4, 6])
    assert done[good].all() and not done[2]
    for row in good:
        alone = _active_set(plant, lengths[row:row + 1].copy(), start)
        for a, b in zip(together, alone):
            assert np.array_equal(a[row], b[0])
    assert any(not np.array_equal(taut[row], start) for row in good)  # the search moved off the start's set
    residual, constraint = _spans_and_balance(plant, rotation, position, mu, taut, lengths)
    assert np.abs(constraint[good]).max() < 1e-12                        # force and moment balance
    assert np.abs(residual[good][taut[good]]).max() < 1e-10             # taut spans at their lengths
    assert (mu[good][taut[good]] >= -1e-9).all()                        # no rope pushes
    assert (residual[good][~taut[good]] <= 1e-10).all()                 # a slack rope's span within its length


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 2 ** 31 - 1), st.integers(0, 4))
def test_the_whitening_and_the_step_are_the_matrix_products(seed, pin_count):
    rng = np.random.default_rng(seed)
    n, samples, m = 5, 3, 8
    sample = rng.integers(0, samples, n)
    residual, jacobian = rng.normal(size=(n, 4 + m)), rng.normal(size=(n, 4 + m, 10))
    length_white, pin_white = rng.normal(size=(samples, 4, 4)), rng.normal(size=(samples, pin_count, pin_count))
    pins = rng.choice(np.arange(4, 4 + m), pin_count, replace=False)
    scale, expected = rng.uniform(100.0, 200.0, pin_count), rng.normal(size=(samples, pin_count))
    measured = rng.random((samples, pin_count)) < 0.7
    out_residual, out_jacobian = residual.copy(), jacobian.copy()
    compiled.whiten_rows(sample, out_residual, out_jacobian, True, length_white, pin_white, pins, scale,
                         measured.view(np.uint8), expected)
    want = residual.copy()
    want[:, :4] = np.einsum("nij,nj->ni", length_white[sample], residual[:, :4])
    raw = residual[:, pins] * scale + np.where(measured[sample], expected[sample], 0.0)
    want[:, pins] = np.einsum("nij,nj->ni", pin_white[sample], raw)
    np.testing.assert_allclose(out_residual, want, rtol=1e-12, atol=1e-12)
    want_jacobian = jacobian.copy()
    want_jacobian[:, :4] = length_white[sample] @ jacobian[:, :4]
    want_jacobian[:, pins] = pin_white[sample] @ (jacobian[:, pins] * scale[:, None])
    np.testing.assert_allclose(out_jacobian, want_jacobian, rtol=1e-12, atol=1e-12)

    rotation = rotations_from_vectors(rng.normal(0.0, 0.3, (n, 3)))
    position, mu, step = rng.normal(size=(n, 3)), rng.normal(size=(n, 4)), rng.normal(0.0, 0.01, (2, 16))
    step[1, 3:6] = 1e-13  # below the angle where the rotation is taken as I + [w]x
    index = np.array([3, 1], np.int64)
    moved, last, steps = (rotation.copy(), position.copy(), mu.copy()), np.zeros((n, 10)), np.zeros(n, np.int64)
    settled, out = np.zeros(n, np.uint8), np.empty(2, np.int64)
    count = compiled.gauss_newton_advance(index, step, np.zeros(0, np.int64), np.ones(n), np.ones(n), last, steps,
                                          settled, *moved, 0.2, 0.2, 1e-6, out)
    np.testing.assert_allclose(moved[0][index], rotations_from_vectors(step[:, 3:6]) @ rotation[index], atol=1e-14)
    np.testing.assert_allclose(moved[1][index], position[index] + step[:, :3], atol=1e-15)
    np.testing.assert_allclose(moved[2][index], mu[index] + step[:, 6:10], atol=1e-15)
    assert np.array_equal(last[index], step[:, :10]) and np.array_equal(steps[index], [1, 1])
    assert count == 2 and np.array_equal(out, index) and not settled.any()  # steps above the tolerance: moving
    others = np.setdiff1d(np.arange(n), index)
    assert np.array_equal(moved[0][others], rotation[others]) and np.array_equal(moved[2][others], mu[others])


def test_a_gauss_newton_step_is_shortened_and_a_row_whose_cost_rose_steps_half_back(plant):
    """A step that would turn 1 rad is shortened to the turn limit; the next evaluation finds the cost risen:
    the row takes half its step back and is retried with its scale halved; a row whose cost stopped falling
    after going too far is settled; a row whose step is below the tolerance is settled after it."""
    rotation, position, mu = np.broadcast_to(np.eye(3), (3, 3, 3)).copy(), np.zeros((3, 3)), np.zeros((3, 4))
    live, reach, scale = np.arange(3, dtype=np.int64), np.ones(3), np.ones(3)
    last, steps, settled, out = np.zeros((3, 10)), np.zeros(3, np.int64), np.zeros(3, np.uint8), np.empty(3, np.int64)
    step = np.zeros((3, 16))
    step[0, 3] = 1.0          # a turn of 1 rad: shortened to 0.2
    step[1, 0] = 0.05         # a shift within the limits
    step[2, 6] = 1e-9         # below the tolerance
    count = compiled.gauss_newton_advance(live, step, np.zeros(0, np.int64), reach, scale, last, steps, settled,
                                          rotation, position, mu, 0.2, 10.0, 1e-6, out)
    assert count == 2 and list(out[:2]) == [0, 1] and list(settled) == [0, 0, 1]
    np.testing.assert_allclose(last[0, 3], 0.2) and np.testing.assert_allclose(last[1, 0], 0.05)
    turned = rotation[0].copy()
    previous = np.array([1.0, 1.0, np.inf])
    scale[1] = 0.5  # row 1 went too far before
    kept, retry = np.empty(2, np.int64), np.empty(2, np.int64)
    going, retried = compiled.gauss_newton_verdict(
        live[:2], np.array([2.0, 1.0 - 1e-6]), np.zeros((2, 6)), reach, previous, last, scale, settled, rotation,
        position, mu, 1e-9, 1e-4, 1e-6, kept, retry)
    assert (going, retried) == (0, 1) and retry[0] == 0 and settled[1] == 1
    assert scale[0] == 0.5 and last[0, 3] == 0.1
    np.testing.assert_allclose(rotation[0], rotations_from_vectors(np.array([[-0.1, 0.0, 0.0]]))[0] @ turned,
                               atol=1e-15)


@settings(max_examples=20, deadline=None)
@given(st.floats(50.0, 650.0), st.floats(0.0, 4e5), st.sampled_from([0.0, 60.0]))
def test_the_compiled_rope_law_is_the_ropes(plant, depth, tension, rope_weight):
    """`compiled.equilibrium_terms` reads a taut rope's unstretched length through the same law as `Ropes`."""
    ropes = Ropes.of(EA, rope_weight)
    state = np.concatenate([[0.0, 0.0, -depth], np.zeros(3), np.full(4, tension / 1e5)])
    spans = _terms(plant, state, np.ones(4, bool), np.zeros(4), np.zeros(4), 0.0, np.eye(3)[None])[0] * 1e-3
    residual = _terms(plant, state, np.ones(4, bool), np.zeros(4), EA, rope_weight, np.eye(3)[None])[0] * 1e-3
    np.testing.assert_allclose(residual, ropes.unstretched(spans, np.full(4, tension))[0], rtol=1e-14)


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2 ** 31 - 1), st.integers(0, 4))
def test_the_slack_pins_bound_is_their_quadratic_form(seed, pin_count):
    """The bound of a candidate is d^T C^-1 d over the pins on the ropes it leaves slack and read at its sample,
    the pins not read left out."""
    rng = np.random.default_rng(seed)
    ropes = np.sort(rng.choice(4, pin_count, replace=False)).astype(np.int64)
    factor = rng.normal(0.0, 1.0, (3, 4, 4))
    covariance = factor @ np.swapaxes(factor, 1, 2) + 0.1 * np.eye(4)
    deviation = rng.normal(0.0, 3.0, (3, pin_count))
    deviation[rng.random((3, pin_count)) < 0.25] = np.nan
    samples = rng.integers(0, 3, 40).astype(np.int64)
    codes = rng.integers(0, 16, 40).astype(np.int64)
    bound = np.empty(40)
    compiled.slack_pin_bounds(samples, codes, ropes, deviation, covariance, bound)
    for i, (sample, code) in enumerate(zip(samples, codes)):
        slack = [a for a, rope in enumerate(ropes) if not code >> rope & 1 and np.isfinite(deviation[sample, a])]
        d = deviation[sample, slack]
        block = covariance[sample][np.ix_(ropes[slack], ropes[slack])]
        assert np.isclose(bound[i], d @ np.linalg.solve(block, d) if slack else 0.0, rtol=1e-9, atol=1e-12)


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 2 ** 31 - 1), st.integers(1, 30))
def test_the_responses_solve_each_rows_system_for_every_column(seed, columns):
    """`kkt_responses` is numpy's solve of each row's 16 x 16 system for its columns (a KKT system's zero block
    needs the row exchanges), and flags a singular row without touching the others."""
    rng = np.random.default_rng(seed)
    system = rng.normal(size=(6, 16, 16))
    system[:, 10:, 10:] = 0.0  # the balance's multipliers: no diagonal of their own
    rhs = rng.normal(size=(6, 16, columns))
    system[4, :, 7] = 0.0  # a column of zeros: singular
    out, singular = np.empty_like(rhs), np.empty(6, np.uint8)
    compiled.kkt_responses(system, rhs, out, singular)
    assert singular.tolist() == [0, 0, 0, 0, 1, 0]
    for row in [0, 1, 2, 3, 5]:
        want = np.linalg.solve(system[row], rhs[row])
        error = 1e-13 * np.linalg.cond(system[row]) * np.abs(want).max()  # both to the system's conditioning
        np.testing.assert_allclose(out[row], want, rtol=0.0, atol=error)
