"""Wall-collision alarm levels with hysteresis, so that an alarm does not chatter."""
from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from enum import IntEnum

import numpy as np

from ..frozen import fast_init
from ..model.plantfile.plant import CABLE_NAMES, Plant, PlantConfigError
from ..model.statics.result import Solution, SolveStatus
from .clearance import Clearance


class AlarmLevel(IntEnum):
    """Levels of the CollisionAlarm message (same numbers)."""

    OK = 0
    WARNING = 1
    CRITICAL = 2
    COLLISION = 3


@dataclass(frozen=True)
class AlarmPolicy:
    """Clearance margins [m] below which a level is raised, and the hysteresis to clear it.

    slack_tolerance [m]: a cable whose span falls short of its length by more than this
    hangs visibly loose and raises a WARNING. Rigid ropes leave one cable at zero tension
    almost everywhere (four taut ropes need l1 + l3 = l2 + l4 to the micrometre); a real
    rope that is loose by less than its elastic stretch still carries load.
    """

    warning_margin: float = 0.15
    critical_margin: float = 0.05
    hysteresis: float = 0.02
    slack_tolerance: float = 0.02

    @classmethod
    def from_plant(cls, plant: Plant) -> AlarmPolicy:
        policy = cls(**plant.alarm)
        if not (policy.warning_margin > policy.critical_margin > 0.0 and policy.hysteresis >= 0.0
                and policy.slack_tolerance >= 0.0):
            raise PlantConfigError("plant file: 'plant.alarm' needs warning_margin > critical_margin > 0 and "
                                   "hysteresis, slack_tolerance >= 0")
        return policy

    def thresholds(self) -> dict[AlarmLevel, float]:
        """Clearance at or below which each level is entered."""
        return {AlarmLevel.WARNING: self.warning_margin, AlarmLevel.CRITICAL: self.critical_margin,
                AlarmLevel.COLLISION: 0.0}


@fast_init
@dataclass(frozen=True)
class Alarm:
    level: AlarmLevel
    clearance: Clearance | None
    sync_error_pairs: tuple[str, ...]
    sync_errors: np.ndarray
    reason: str


@dataclass(frozen=True)
class Alarms:
    """The alarms of a run of samples, a column each (row k is sample k's `Alarm`): what the judge makes and
    the encoders read, without an object per sample."""

    levels: list[AlarmLevel]
    clearances: list[Clearance | None]  # what each level is based on
    sync_errors: np.ndarray             # (n, len(SYNC_PAIR_NAMES)) [m]
    reasons: list[str]

    def __len__(self) -> int:
        return len(self.levels)

    def __getitem__(self, k: int) -> Alarm:
        return Alarm(self.levels[k], self.clearances[k], SYNC_PAIR_NAMES, self.sync_errors[k], self.reasons[k])

    def __iter__(self) -> Iterator[Alarm]:
        return (self[k] for k in range(len(self)))

    @classmethod
    def concatenated(cls, parts: Sequence[Alarms]) -> Alarms:
        """Consecutive runs' alarms as one run's."""
        return cls([level for part in parts for level in part.levels],
                   [clearance for part in parts for clearance in part.clearances],
                   np.concatenate([part.sync_errors for part in parts]) if parts else np.empty((0, len(SYNC_PAIR_NAMES))),
                   [reason for part in parts for reason in part.reasons])


SYNC_PAIRS = tuple((i, j) for i in range(4) for j in range(i + 1, 4))
SYNC_PAIR_NAMES = tuple(f"{CABLE_NAMES[i]}-{CABLE_NAMES[j]}" for i, j in SYNC_PAIRS)
_FIRST, _SECOND = (np.array(side) for side in zip(*SYNC_PAIRS))


class AlarmTracker:
    """Turns each sample's clearance into a level; a level is left only when the clearance
    has recovered by the hysteresis above the threshold that raised it."""

    def __init__(self, policy: AlarmPolicy):
        self.policy = policy
        self.level = AlarmLevel.OK
        self._thresholds = sorted(policy.thresholds().items())  # (level, clearance limit), the levels rising

    def _clearance_level(self, clearance: float) -> AlarmLevel:
        """The highest level whose limit the clearance is within, or the one held while the clearance has not
        recovered by the hysteresis above the limit (a plain loop: it runs at every sample)."""
        raised = held = AlarmLevel.OK
        hysteresis, level = self.policy.hysteresis, self.level
        for lvl, limit in self._thresholds:
            if clearance <= limit:
                raised = lvl
            if lvl <= level and clearance <= limit + hysteresis:
                held = lvl
        return raised if raised >= level else max(raised, held)

    def update(self, solution: Solution, clearance: Clearance | None, basis: str = "") -> Alarm:
        """The alarm for one solved sample; `basis` says what the clearance is based on (monitor.basis)."""
        return self.update_many([solution], [clearance], [basis])[0]

    def update_many(self, solutions: Sequence[Solution], clearances: Sequence[Clearance | None],
                    bases: Sequence[str]) -> Alarms:
        """The alarms of consecutive samples, in order (the hysteresis carries from each to the next), with
        what each clearance is based on (`bases`, monitor.basis); the sync errors and the slack ropes'
        looseness of all of them worked out together."""
        lengths = np.array([solution.lengths for solution in solutions], dtype=float).reshape(-1, 4)
        errors = lengths[:, _FIRST] - lengths[:, _SECOND]
        loose = self._loose(solutions, lengths)
        levels, reasons_of = [], []
        for k, (solution, clearance, basis) in enumerate(zip(solutions, clearances, bases)):
            reasons = []
            level = AlarmLevel.OK
            if clearance is not None:
                level = self._clearance_level(clearance.value)
                if level > AlarmLevel.OK:
                    reasons.append(f"clearance {clearance.value:.3f} m at {clearance.point_name}")
            if solution.status is SolveStatus.SINGLE_CABLE_INDETERMINATE:
                assert solution.single_cable is not None  # a single-cable solution names its cable
                level = max(level, AlarmLevel.WARNING)
                reasons.append(f"platform hangs from {CABLE_NAMES[solution.single_cable]} alone and can turn")
            elif solution.ok:
                if k in loose:
                    level = max(level, AlarmLevel.WARNING)
                    reasons.append("slack: " + ", ".join(f"{CABLE_NAMES[i]} loose by {by:.3f} m" for i, by in loose[k]))
            else:
                level = max(level, AlarmLevel.WARNING)
                reasons.append(f"no pose: {solution.tension_state}")
            self.level = level
            reason = "; ".join(reasons) or "clearance within margins"
            levels.append(level)
            reasons_of.append(f"{reason} ({basis})" if basis else reason)
        return Alarms(levels, list(clearances), errors, reasons_of)

    def _loose(self, solutions: Sequence[Solution], lengths: np.ndarray) -> dict[int, list[tuple[int, float]]]:
        """The solved samples with a rope whose span falls short of its length by more than the slack tolerance:
        each such rope and by how much [m], by sample."""
        posed = [k for k, solution in enumerate(solutions) if solution.ok]
        if not posed:
            return {}
        looseness = lengths[posed] - np.array([solutions[k].spans for k in posed], dtype=float)
        beyond = looseness > self.policy.slack_tolerance
        return {posed[row]: [(i, float(looseness[row, i])) for i in np.flatnonzero(beyond[row]).tolist()]
                for row in np.flatnonzero(beyond.any(axis=1)).tolist()}
