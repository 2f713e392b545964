"""The synchronisation-error envelope: at each reported limit the criterion that binds really binds."""
from __future__ import annotations

import numpy as np
import pytest

from cable_winch_monitor.effects import PlantModel
from cable_winch_monitor.model.solvers.solve import solve
from cable_winch_monitor.monitor.alarm import AlarmPolicy
from cable_winch_monitor.monitor.clearance import solution_clearance
from cable_winch_monitor.monitor.limits import BISECTION_TOL, synchronisation_limits

PAYOUT = 300.0


@pytest.fixture(scope="module")
def limits(plant):
    return synchronisation_limits(PlantModel.from_plant(plant), PAYOUT)


def lengths_for(limit, delta):
    change = np.zeros(4)
    change[list(limit.cables)] = limit.direction
    return PAYOUT + delta * change


def test_envelope_covers_every_cable_and_adjacent_pair_both_ways(limits):
    labels = {limit.label for limit in limits}
    assert len(limits) == 16 and len(labels) == 16
    assert {"cable_1 longer", "cable_4+cable_1 shorter"} <= labels


def test_clearance_limit_is_where_the_clearance_reaches_the_warning_margin(plant, limits):
    margin = AlarmPolicy.from_plant(plant).warning_margin
    for limit in limits:
        if not np.isfinite(limit.clearance_limit):
            continue
        inside = solution_clearance(plant, solve(plant, lengths_for(limit, limit.clearance_limit)))
        beyond = solution_clearance(plant, solve(plant, lengths_for(limit, limit.clearance_limit + 2 * BISECTION_TOL)))
        assert inside.value > margin >= beyond.value, limit.label


def test_taut_limit_is_where_a_cable_goes_loose(plant, limits):
    tolerance = AlarmPolicy.from_plant(plant).slack_tolerance
    for limit in limits:
        inside = solve(plant, lengths_for(limit, limit.taut_limit))
        beyond = solve(plant, lengths_for(limit, limit.taut_limit + 2 * BISECTION_TOL))
        assert np.all(inside.lengths - inside.spans <= tolerance), limit.label
        assert not beyond.ok or np.any(beyond.lengths - beyond.spans > tolerance), limit.label


def test_a_longer_cable_that_only_goes_slack_never_moves_the_platform(limits):
    """Paying out a lightly loaded cable just slackens it: no clearance limit within the scan."""
    assert not np.isfinite(next(lim for lim in limits if lim.label == "cable_3 longer").clearance_limit)
