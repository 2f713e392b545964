"""Property-based tests (hypothesis), with a bounded budget per property so that the suite stays fast.

- solvers: whatever the lengths, a result with status solved passes the physics check;
- input merger: whatever the stamps, names and values, every message is taken or refused with
  a reason, what is kept is plausible, and no refused or kept message blocks a good one later;
- bag reader: whatever the cut or the corruption, no exception, no hang, nothing invented,
  everything before the damage delivered and the loss counted exactly.
"""
from __future__ import annotations

import math
import tempfile
from pathlib import Path

import numpy as np
import pytest
from bagdamage import check_replayed, locate, read_damaged, write_bag
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cable_winch_monitor.model.paper.traversal import solve_traversal
from cable_winch_monitor.model.plantfile.plant import CABLE_NAMES, load_plant
from cable_winch_monitor.model.solvers.batched import solve_batch
from cable_winch_monitor.model.solvers.energy import solve_energy
from cable_winch_monitor.model.statics.result import SolveStatus, check_physics
from cable_winch_monitor.monitor.inputs import CableLengthMerger, InputLimits, JointSample, StampWindow

PLANT = load_plant()
BUDGET = settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])

payout = st.floats(min_value=1.0, max_value=PLANT.max_payout - 5.0)
offsets = st.lists(st.floats(min_value=-2.0, max_value=2.0), min_size=4, max_size=4)
anything = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-10 ** 6, 10 ** 6),
                     st.just(1e300), st.just(-1e300))


def lengths_from(base: float, deltas: list[float]) -> np.ndarray:
    return np.maximum(base + np.array(deltas), 0.5)


def assert_honest(solution) -> None:
    """The solver's contract: a status, and solved only with the physics to show for it."""
    assert isinstance(solution.status, SolveStatus)
    if solution.ok:
        check = check_physics(PLANT, solution)
        assert check.passes(), (solution.lengths, check.failure())


@BUDGET
@given(base=payout, deltas=offsets)
def test_energy_solves_cold_and_warm_only_what_balances(base, deltas):
    lengths = lengths_from(base, deltas)
    cold = solve_energy(PLANT, lengths)
    assert_honest(cold)
    warm_from = solve_energy(PLANT, lengths + 0.05)
    assert_honest(solve_energy(PLANT, lengths, warm_start=warm_from if warm_from.ok else None))


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(base=st.floats(min_value=5.0, max_value=800.0), deltas=offsets)
def test_traversal_solves_only_what_balances(base, deltas):
    assert_honest(solve_traversal(PLANT, lengths_from(base, deltas)))


@BUDGET
@given(rows=st.lists(st.tuples(payout, offsets), min_size=1, max_size=12))
def test_batches_solve_only_what_balances(rows):
    lengths = np.array([lengths_from(base, deltas) for base, deltas in rows])
    for solution in solve_batch(PLANT, lengths).solutions():
        assert_honest(solution)


@BUDGET
@given(values=st.lists(anything, min_size=4, max_size=4))
def test_any_four_numbers_give_a_status_never_an_exception(values):
    for solution in (solve_energy(PLANT, values), solve_batch(PLANT, np.array([values], dtype=float)).solution(0)):
        assert_honest(solution)
        finite = all(math.isfinite(v) and 0.0 < v <= PLANT.max_payout for v in map(float, values))
        assert finite or solution.status is SolveStatus.INVALID_INPUT


names = st.lists(st.one_of(st.sampled_from(CABLE_NAMES), st.sampled_from(["winch_9", "drum_brake", ""])),
                 min_size=0, max_size=6)
message = st.builds(
    lambda stamp_offset, late, names, values, speeds: (stamp_offset, late, names, values, speeds),
    stamp_offset=st.one_of(st.floats(-5.0, 5.0), st.sampled_from([1e6, -1e6, 2.0 ** 31, float("nan"),
                                                                  float("inf"), -float("inf")])),
    late=st.floats(0.0, 0.2), names=names,
    values=st.lists(st.one_of(st.floats(1.0, 100.0), anything), min_size=0, max_size=6),
    speeds=st.lists(st.one_of(st.floats(-1.0, 1.0), anything), min_size=0, max_size=6))


@settings(max_examples=60, deadline=None)
@given(burst=st.lists(message, min_size=1, max_size=40), gaps=st.lists(st.floats(0.0, 0.05), min_size=40,
                                                                       max_size=40))
def test_the_merger_takes_or_refuses_every_message_and_is_never_blocked(burst, gaps):
    window = StampWindow()
    merger = CableLengthMerger(0.5, window, InputLimits(PLANT.max_payout, PLANT.max_payout_speed))
    now = latest_arrival = 1.7e9
    for (offset, late, names, values, speeds), gap in zip(burst, gaps):
        now += gap
        latest_arrival = max(latest_arrival, now + late)
        result = merger.add(JointSample(now + offset, names, values, speeds, received=now + late))
        assert bool(result.accepted) != bool(result.rejected), result
        for cable in result.accepted:
            reading = merger.readings[cable]
            assert math.isfinite(reading.length) and 0.0 < reading.length <= PLANT.max_payout
            assert reading.stamp - reading.received <= window.ahead
            assert math.isnan(reading.velocity) or abs(reading.velocity) <= PLANT.max_payout_speed
        lengths, _ = merger.complete(now)
        assert lengths is None or np.all(np.isfinite(lengths))
    # whatever came before, a good message stamped past the window of every earlier arrival is taken, and solves
    later = latest_arrival + window.ahead + 0.001
    good = merger.add(JointSample(later, list(CABLE_NAMES), [20.3, 20.1, 20.5, 20.2], received=later))
    assert good.accepted == [0, 1, 2, 3], good.rejected
    lengths, why = merger.complete(later)
    assert lengths is not None and solve_energy(PLANT, lengths).ok, why


@pytest.fixture(scope="module")
def damaged_bag():
    with tempfile.TemporaryDirectory() as scratch:
        bag = write_bag(Path(scratch) / "bag", seconds=6.0)
        content = next(bag.glob("*.mcap")).read_bytes()
        yield bag, content, locate(content), Path(scratch)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(fraction=st.floats(0.0, 1.0, exclude_max=True))
def test_any_cut_keeps_every_message_before_it(damaged_bag, fraction):
    bag, content, located, scratch = damaged_bag
    cut = max(8, int(fraction * len(content)))
    delivered, report = read_damaged(bag, scratch, content[:cut])
    assert check_replayed(located, delivered, report, (cut, len(content))) == 0  # a cut alters no byte


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(fraction=st.floats(0.0, 1.0, exclude_max=True), noise=st.binary(min_size=1, max_size=64))
def test_any_corruption_costs_at_most_the_chunks_it_touches(damaged_bag, fraction, noise):
    bag, content, located, scratch = damaged_bag
    place = max(8, int(fraction * len(content)))
    damaged = bytearray(content)
    end = min(place + len(noise), len(content))
    damaged[place:end] = bytes(a ^ (b or 0xFF) for a, b in zip(content[place:end], noise))
    delivered, report = read_damaged(bag, scratch, bytes(damaged))
    check_replayed(located, delivered, report, (place, end))
    untouched = {(m.topic, m.log_time, m.data) for m in located if m.chunk[1] <= place or m.chunk[0] >= end}
    assert untouched <= set(delivered)
