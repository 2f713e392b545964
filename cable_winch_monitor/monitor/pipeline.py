"""The monitor as one object: winch samples in, solved pose, tensions, alarm and residuals out.

The live node and bag replay both feed this object, so both give the same answers. It
knows nothing of ROS: messages arrive as plain values with their header stamps.
"""
from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field
from typing import NamedTuple, Sequence

import numpy as np

from ..effects import Conditions, PlantModel
from ..effects.sheave import motion_direction
from ..model.plant import Plant
from ..model.result import Solution, SolveStatus
from ..model.solve import METHODS, solve
from .alarm import Alarm, AlarmPolicy, AlarmTracker
from .clearance import Clearance, solution_clearance
from .inputs import CableLengthMerger, InputLimits, JointSample, StampWindow, orientation_reason, position_reason
from .residuals import TENSION_CHANNELS, Residuals, imu_channels, noise_levels, position_channels, predicted_channels, residuals


@dataclass(frozen=True)
class MonitorOutput:
    """Everything the monitor publishes for one solved sample, stamped with its input stamp."""

    stamp: float
    solution: Solution
    clearance: Clearance | None
    alarm: Alarm
    residuals: Residuals | None


class CompleteSample(NamedTuple):
    """Four fresh cable lengths at a winch message's stamp, with what the merger knew then."""

    stamp: float
    lengths: np.ndarray
    accepted: list[int]  # the cables this message updated
    tensions: list[float]  # load pins of the four cables [N] (NaN: not measured)
    speeds: list[float]  # payout speeds [m/s] (NaN: not reported)


@dataclass
class MonitorStats:
    """Counts for diagnostics and replay summaries.

    Every message read is either used or rejected with a reason: for each topic,
    messages[topic] == used[topic] + the rejected counts keyed "topic: reason".
    """

    messages: Counter[str] = field(default_factory=Counter)
    used: Counter[str] = field(default_factory=Counter)
    rejected: Counter[str] = field(default_factory=Counter)
    ignored_names: Counter[str] = field(default_factory=Counter)
    states: Counter[str] = field(default_factory=Counter)
    levels: Counter[str] = field(default_factory=Counter)
    solved: int = 0
    failures: int = 0
    last_rejection: str = ""
    waiting: str = ""


class MonitorPipeline:
    """Merges inputs, solves each complete sample (warm-started), and derives alarm and residuals."""

    def __init__(self, plant: Plant, solver: str = "energy", staleness: float = 0.5,
                 stamp_window: StampWindow | None = None):
        if solver not in METHODS:
            raise ValueError(f"unknown solver {solver!r}; use one of {', '.join(METHODS)}")
        self.plant, self.solver = plant, solver
        self.limits = InputLimits(plant.max_payout, plant.max_payout_speed)
        self.merger = CableLengthMerger(staleness, stamp_window, self.limits)
        self.alarms = AlarmTracker(AlarmPolicy.from_plant(plant))
        self.stats = MonitorStats()
        self.last: MonitorOutput | None = None
        self.last_solved: MonitorOutput | None = None
        self.staleness = staleness
        # The plant file's physical effects (effects/): None keeps the plain rigid path and its speed.
        model = PlantModel.from_plant(plant)
        self.model = model if model.effects else None
        self.direction = np.zeros(4)
        self.last_predicted: dict[str, float] | None = None
        self.noise = noise_levels(plant)

    def _reject(self, topic: str, reason: str) -> None:
        self.stats.rejected[f"{topic}: {reason.split(':')[0]}"] += 1
        self.stats.last_rejection = f"{topic}: {reason}"

    def on_joint_state(self, sample: JointSample) -> MonitorOutput | None:
        """A winch message; returns the solved sample when the four lengths are complete and fresh."""
        complete = self._merge(sample)
        return None if complete is None else self._solve(complete)

    def _merge(self, sample: JointSample) -> CompleteSample | None:
        """Merge a winch message; the complete sample it makes, if it makes one."""
        self.stats.messages[sample.topic] += 1
        merged = self.merger.add(sample)
        self.stats.ignored_names.update(merged.ignored)
        if merged.rejected:
            self._reject(sample.topic, merged.rejected)
            return None
        self.stats.used[sample.topic] += 1
        lengths, waiting = self.merger.complete(sample.stamp)
        self.stats.waiting = waiting
        if lengths is None:
            return None
        readings = self.merger.readings
        return CompleteSample(sample.stamp, lengths, merged.accepted, [r.tension for r in readings],
                              [r.velocity for r in readings])

    def evaluate(self, lengths: object) -> tuple[Solution, Clearance | None, Alarm]:
        """What proposed cable lengths would give (for plant control), without touching the state."""
        solution = self._equilibrium(lengths)
        clearance = solution_clearance(self.plant, solution)
        return solution, clearance, AlarmTracker(self.alarms.policy).update(solution, clearance)

    def _warm_start(self) -> Solution | None:
        return self.last_solved.solution if self.last_solved is not None and self.solver == "energy" else None

    def _equilibrium(self, lengths: object) -> Solution:
        if self.model is not None:
            return self.model.solve(lengths, self._warm_start())
        return solve(self.plant, lengths, self.solver, warm_start=self._warm_start())

    def _predicted(self, solution: Solution, speeds: list[float]) -> dict[str, float] | None:
        """What the sensors should read for a solved sample (None without a pose), under the
        plant's measurement effects if it has any; kept for the measurements that follow."""
        if self.model is None:
            return predicted_channels(solution) if solution.ok else None
        payout = np.array(speeds)
        self.direction = motion_direction(payout, self.direction)
        if not solution.ok:
            return None
        return self.model.predict(solution, Conditions(payout, self.direction))

    def _solve(self, sample: CompleteSample, solved: tuple[Solution, Clearance | None] | None = None) -> MonitorOutput:
        """Solve a complete sample (or take its equilibrium and clearance as `solved` ahead), raise its
        alarm and compare its load pins with the model."""
        if solved is None:
            solution = self._equilibrium(sample.lengths)
            solved = solution, solution_clearance(self.plant, solution)
        solution, clearance = solved
        alarm = self.alarms.update(solution, clearance)
        measured = {TENSION_CHANNELS[i]: sample.tensions[i] for i in sample.accepted}
        predicted = self._predicted(solution, sample.speeds)
        resid = residuals(self.noise, sample.stamp, measured, predicted) if predicted is not None else None
        output = MonitorOutput(sample.stamp, solution, clearance, alarm, resid)
        self.stats.solved += int(solution.ok)
        self.stats.failures += int(solution.status in (SolveStatus.SOLVER_FAILED, SolveStatus.NO_EQUILIBRIUM))
        self.stats.states[solution.tension_state] += 1
        self.stats.levels[alarm.level.name] += 1
        self.last = output
        if solution.ok:
            self.last_solved, self.last_predicted = output, predicted
        return output

    def _measurement(self, topic: str, stamp: float, channels: dict[str, float]) -> Residuals | None:
        self.stats.messages[topic] += 1
        if not all(math.isfinite(v) for k, v in channels.items() if k not in ("x", "y")):
            self._reject(topic, "bad measurement: not finite")
            return None
        last = self.last_solved
        if last is None or abs(stamp - last.stamp) > self.staleness:
            self._reject(topic, "no solved pose within the staleness limit")
            return None
        self.stats.used[topic] += 1
        return residuals(self.noise, stamp, channels, self.last_predicted)

    def on_imu(self, stamp: float, quaternion_xyzw: Sequence[float], topic: str = "/platform/imu") -> Residuals | None:
        """An inclinometer reading: roll and pitch residuals against the latest solved pose."""
        quaternion = [float(v) for v in quaternion_xyzw]
        reason = orientation_reason(quaternion)
        if reason:
            self.stats.messages[topic] += 1
            self._reject(topic, reason)
            return None
        return self._measurement(topic, stamp, imu_channels(quaternion))

    def on_position(self, stamp: float, xyz: Sequence[float], topic: str = "/platform/position") -> Residuals | None:
        """A depth-gauge reading (x, y may be NaN): residuals against the latest solved pose."""
        reason = position_reason([float(v) for v in xyz], self.limits)
        if reason:
            self.stats.messages[topic] += 1
            self._reject(topic, reason)
            return None
        return self._measurement(topic, stamp, position_channels(xyz))
