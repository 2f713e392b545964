"""The permissible synchronisation-error envelope at a payout: the figure plant control needs.

Starting from four equal lengths L, one cable (or an adjacent pair together) is paid
out further, or hauled in, by delta. The envelope is the largest delta that keeps
(a) the wall clearance above the WARNING margin and (b) every cable taut, meaning no
cable hangs looser than the alarm's slack tolerance. This is the purpose seed 002 states:
limit the length differences so that the tilted platform cannot reach the wall. Every
equilibrium is the plant model's (effects.PlantModel: its effects, load and solver).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..effects import PlantModel
from ..model.plantfile.plant import CABLE_NAMES, Plant
from ..model.statics.result import Solution
from .alarm import AlarmPolicy
from .clearance import solution_clearance

SCAN_STEP = 0.005      # [m]
SCAN_LIMIT = 3.0       # [m] largest synchronisation error examined
BISECTION_TOL = 1e-4   # [m]

ADJACENT_PAIRS = ((0, 1), (1, 2), (2, 3), (3, 0))


@dataclass(frozen=True)
class Limit:
    """Largest |delta| [m] for one way of going out of step; inf when nothing fails up to SCAN_LIMIT."""

    cables: tuple[int, ...]
    direction: int          # +1 paid out further (longer), -1 hauled in (shorter)
    clearance_limit: float
    taut_limit: float
    slack_cable: str        # the cable that goes slack first ('' if none)

    @property
    def label(self) -> str:
        names = "+".join(CABLE_NAMES[c] for c in self.cables)
        return f"{names} {'longer' if self.direction > 0 else 'shorter'}"

    @property
    def permissible(self) -> float:
        return min(self.clearance_limit, self.taut_limit)

    @property
    def binding(self) -> str:
        if not np.isfinite(self.permissible):
            return "none"
        return "clearance" if self.clearance_limit <= self.taut_limit else f"slack {self.slack_cable}"


def _failures(plant: Plant, policy: AlarmPolicy, solution: Solution) -> tuple[bool, str]:
    """(clearance below the WARNING margin, name of a loose cable or '')."""
    clearance = solution_clearance(plant, solution)
    too_close = clearance is None or clearance.value <= policy.warning_margin
    if solution.single_cable is not None:
        return too_close, f"all but {CABLE_NAMES[solution.single_cable]}"
    if not solution.ok:
        return True, solution.tension_state
    slack = solution.lengths - solution.spans > policy.slack_tolerance
    return too_close, CABLE_NAMES[int(np.argmax(slack))] if slack.any() else ""


def _first_failure(model: PlantModel, policy: AlarmPolicy, base: float, change: np.ndarray,
                   which: int) -> tuple[float, str]:
    """Smallest delta at which criterion `which` (0 clearance, 1 taut) fails: a warm-started
    scan in SCAN_STEP steps, then bisection."""
    def fails(delta: float, warm: Solution | None) -> tuple[bool, str, Solution]:
        solution = model.solve(base + delta * change, warm)
        failures = _failures(model.physical, policy, solution)
        return bool(failures[which]), failures[1], solution

    warm, previous = None, 0.0
    for delta in np.arange(SCAN_STEP, SCAN_LIMIT + SCAN_STEP / 2, SCAN_STEP):
        failed, name, solution = fails(delta, warm)
        if failed:
            lo, hi = previous, delta
            while hi - lo > BISECTION_TOL:
                mid = 0.5 * (lo + hi)
                mid_failed, mid_name, _ = fails(mid, warm)
                lo, hi, name = (lo, mid, mid_name) if mid_failed else (mid, hi, name)
            return lo, name
        warm, previous = (solution if solution.ok else None), delta
    return float("inf"), ""


def synchronisation_limits(model: PlantModel, length: float,
                           groups: list[tuple[int, ...]] | None = None) -> list[Limit]:
    """The envelope for every cable and every adjacent pair (or the cable `groups` given, 0-based), both
    directions, at payout `length`."""
    policy = AlarmPolicy.from_plant(model.plant)
    limits = []
    for cables in groups or [(c,) for c in range(4)] + list(ADJACENT_PAIRS):
        for direction in (1, -1):
            change = np.zeros(4)
            change[list(cables)] = direction
            clearance_limit, _ = _first_failure(model, policy, length, change, 0)
            taut_limit, slack_cable = _first_failure(model, policy, length, change, 1)
            limits.append(Limit(tuple(cables), direction, clearance_limit, taut_limit, slack_cable))
    return limits


def format_limits(plant: Plant, length: float, limits: list[Limit]) -> str:
    policy = AlarmPolicy.from_plant(plant)
    lines = [f"Permissible synchronisation errors at payout L = {length:.3f} m ({plant.name})",
             f"clearance must stay above the WARNING margin {policy.warning_margin:.3f} m; a cable is slack "
             f"when looser than {policy.slack_tolerance:.3f} m",
             f"{'change':<26}{'clearance [m]':>14}{'taut [m]':>10}{'permissible [m]':>17}  binding"]
    for limit in limits:
        lines.append(f"{limit.label:<26}{limit.clearance_limit:>14.4f}{limit.taut_limit:>10.4f}"
                     f"{limit.permissible:>17.4f}  {limit.binding}")
    return "\n".join(lines)
