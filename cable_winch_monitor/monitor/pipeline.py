"""The monitor as one object: winch samples in, solved pose, tensions, alarm and residuals out.

The live node and bag replay both feed this object, so both give the same answers. It
knows nothing of ROS: winch messages arrive as plain values with their header stamps,
other sensors as message objects read by their declared channels (channels.py), extra
inputs (a shaft temperature) by the effects' declared `Input`s. Every sample is solved
through the plant's one model (effects.PlantModel: its effects, its load, its solver)
at the sample's conditions (time, payout speeds and accelerations, direction, inputs).

Where the plant file gives the encoders a noise (`noise.length`), a sample is not solved
from its lengths alone but estimated (effects.estimate): its lengths, its load pins and
the latest readings of the other sensors within the staleness limit, each weighted by
its noise, warm-started from the previous estimate. A sensor that disagrees beyond its
Mahalanobis gate for the hold time is left out (sensors.SensorGates).
"""
from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np

from .. import channels
from ..channels import Input
from ..effects import PlantModel
from ..effects.model import NO_CONDITIONS
from ..effects.estimate import estimate_sample, fuses
from ..model.conditions import Conditions, ConditionsTracker
from ..model.estimation import Estimate, gate_taken_in
from ..model.plant import Plant
from ..model.result import Solution, SolveStatus
from .alarm import Alarm, AlarmPolicy, AlarmTracker
from .clearance import Clearance, solution_clearance
from .inputs import (CableLengthMerger, InputLimits, InputSeries, JointSample, StampWindow, measurement_reason,
                     small_mean)
from .residuals import Residuals, noise_levels, residuals
from .sensors import DEFAULT_HOLD, LatestReadings, SensorGates


@dataclass(frozen=True)
class MonitorOutput:
    """Everything the monitor publishes for one solved sample, stamped with its input stamp."""

    stamp: float
    solution: Solution
    clearance: Clearance | None
    alarm: Alarm
    residuals: Residuals | None
    estimate: Estimate | None = None  # the fused estimate the solution is (None: the lengths taken as exact)
    refused: tuple[str, ...] = ()     # sensors left out by their gate


class Solved(NamedTuple):
    """A sample's equilibrium, wall clearance, fused estimate (None: the lengths taken as exact) and what
    the model says each channel reads (None: not solved), computed ahead (replay solves many at once)."""

    solution: Solution
    clearance: Clearance | None
    estimate: Estimate | None
    predicted: dict[str, float] | None


class CompleteSample(NamedTuple):
    """Four fresh cable lengths at a winch message's stamp, with what the merger knew then."""

    stamp: float
    lengths: np.ndarray
    accepted: list[int]  # the cables this message updated
    tensions: list[float]  # load pins of the four cables [N] (NaN: not measured)
    speeds: list[float]  # payout speeds [m/s] (NaN: not reported)
    sensors: dict[str, float] = {}  # what every sensor read then: the load pins, the latest other readings


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
                 stamp_window: StampWindow | None = None, gate_hold: float = DEFAULT_HOLD):
        self.model = PlantModel.from_plant(plant, solver)  # the one solve path: effects, load, solver
        self.plant, self.solver = plant, solver
        self.limits = InputLimits(plant.max_payout, plant.max_payout_speed)
        self.merger = CableLengthMerger(staleness, stamp_window, self.limits)
        self.alarms = AlarmTracker(AlarmPolicy.from_plant(plant))
        self.stats = MonitorStats()
        self.last: MonitorOutput | None = None
        self.last_solved: MonitorOutput | None = None
        self.staleness = staleness
        self.tracker = ConditionsTracker()
        self.inputs = {spec.key: InputSeries() for spec in self.model.inputs}
        self.last_predicted: dict[str, float] | None = None
        self.noise = noise_levels(plant)
        self.fusing = solver == "energy" and fuses(self.model)
        self.readings = LatestReadings(staleness)
        self.gates = SensorGates(gate_hold)
        self.last_estimate: Estimate | None = None
        self.payout: tuple[float, float, float] = (math.nan, math.nan, 0.0)  # stamp, mean length, mean speed

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
        speeds = [r.velocity for r in readings]
        speed = small_mean(speeds)
        self.payout = (sample.stamp, small_mean(lengths.tolist()), speed if math.isfinite(speed) else 0.0)
        complete = CompleteSample(sample.stamp, lengths, merged.accepted, [r.tension for r in readings], speeds)
        return complete._replace(sensors=self.measured(complete)) if self.fusing else complete

    def measured(self, sample: CompleteSample) -> dict[str, float]:
        """What the sensors read at a complete sample: its load pins and the latest other readings
        within the staleness limit (every sensor: the gates pick the trusted ones when it is solved)."""
        pins = {name: value for name, value in zip(channels.TENSION_CHANNELS, sample.tensions) if math.isfinite(value)}
        return {**self.readings.at(sample.stamp, small_mean(sample.lengths.tolist())), **pins}

    def payout_at(self, stamp: float) -> float:
        """The mean payout [m] at `stamp`, carried from the latest complete sample by its payout speed."""
        taken, length, speed = self.payout
        return length + speed * (stamp - taken)

    def keep_reading(self, stamp: float, values: dict[str, float]) -> None:
        """A sensor's readings, kept for the samples to come (where they are fused: the lengths taken
        as exact, only the residuals read them)."""
        if self.fusing:
            self.readings.add(stamp, values, self.payout_at(stamp))

    def inputs_at(self, stamp: float) -> dict[str, float]:
        """The extra inputs' values at `stamp` (interpolated where later values are known, else the latest)."""
        return {key: series.value_at(stamp) for key, series in self.inputs.items()}

    def evaluate(self, lengths: object) -> tuple[Solution, Clearance | None, Alarm]:
        """What proposed cable lengths would give at rest (for plant control), without touching the state."""
        conditions = Conditions(inputs=self.inputs_at(math.inf))
        solution = self.model.solve(lengths, self._warm_start(), conditions)
        clearance = solution_clearance(self.model.physical, solution)
        return solution, clearance, AlarmTracker(self.alarms.policy).update(solution, clearance)

    def _warm_start(self) -> Solution | None:
        return self.last_solved.solution if self.last_solved is not None and self.solver == "energy" else None

    def conditions(self, sample: CompleteSample) -> Conditions:
        """The conditions of a complete sample: its stamp, speeds, accelerations, direction and inputs
        (none where nothing reads them: no effect, no channel of a user's)."""
        if not self.model.reads_conditions:
            return NO_CONDITIONS
        return self.tracker.update(sample.stamp, sample.lengths, np.array(sample.speeds), self.inputs_at(sample.stamp))

    def estimate(self, sample: CompleteSample, measured: dict[str, float], conditions: Conditions) -> Estimate:
        """The fused state of a sample from its trusted sensors, warm-started from the previous estimate."""
        return estimate_sample(self.model, sample.lengths, self.gates.trusted(measured), conditions, self.last_estimate)

    def _solve(self, sample: CompleteSample, solved: Solved | None = None,
               conditions: Conditions | None = None) -> MonitorOutput:
        """Solve (or estimate, from what the sensors read) a complete sample, or take it `solved` ahead
        with its `conditions`; raise its alarm, gate its sensors and compare its load pins with the model."""
        conditions = conditions or self.conditions(sample)
        if solved is None:
            fused = self.estimate(sample, sample.sensors, conditions) if self.fusing else None
            solution = fused.solution if fused is not None else \
                self.model.solve(sample.lengths, self._warm_start(), conditions)
            solved = Solved(solution, solution_clearance(self.model.physical, solution), fused,
                            self.model.predict(solution, conditions) if solution.ok else None)
        solution, clearance, fused, predicted = solved
        alarm = self.alarms.update(solution, clearance)
        pins = {channels.TENSION_CHANNELS[i]: sample.tensions[i] for i in sample.accepted}
        resid = residuals(self.noise, sample.stamp, pins, predicted) if predicted is not None else None
        if fused is not None and predicted is not None:
            self._gate(sample, fused, conditions)
        output = MonitorOutput(sample.stamp, solution, clearance, alarm, resid, fused, self.gates.refused)
        self.stats.solved += int(solution.ok)
        self.stats.failures += int(solution.status in (SolveStatus.SOLVER_FAILED, SolveStatus.NO_EQUILIBRIUM))
        self.stats.states[solution.tension_state] += 1
        self.stats.levels[alarm.level.name] += 1
        self.last = output
        if solution.ok:
            self.last_solved, self.last_predicted = output, predicted
            self.last_estimate = fused
        return output

    def _gate(self, sample: CompleteSample, fused: Estimate, conditions: Conditions) -> None:
        """Each sensor's verdict: a used one by its channels' residuals in the estimate, a left-out one
        when its turn comes (`SensorGates.trial`) by what taking it back in would cost (the sample
        estimated again with it: `gate_taken_in`)."""
        taken_in = {}
        tried = self.gates.trial(sample.stamp, sample.sensors)
        if tried is not None:
            sensor, readings = tried
            trial = estimate_sample(self.model, sample.lengths, {**self.gates.trusted(sample.sensors), **readings},
                                    conditions, fused)
            gate = gate_taken_in(fused, trial, list(readings), self.gates.probability)
            if gate is not None:
                taken_in[sensor] = gate
        self.gates.update(sample.stamp, fused.residuals, taken_in)

    def on_measurement(self, topic: str, stamp: float, message: Any, keep: bool = True,
                       values: dict[str, float] | None = None) -> Residuals | None:
        """A sensor message (inclinometer, depth gauge, a declared channel's topic): its readings kept
        for the samples to come (unless `keep` is False: replay keeps them ahead, with the `values` it
        read off the message then), the residuals of its channels against the latest solved pose."""
        self.stats.messages[topic] += 1
        reason = measurement_reason(message, self.limits)
        if reason:
            self._reject(topic, reason)
            return None
        if values is None:
            values = self.read_channels(topic, message)
        if not any(math.isfinite(v) for v in values.values()):
            self._reject(topic, "bad measurement: no finite value in " + ", ".join(values))
            return None
        if keep:
            self.keep_reading(stamp, values)
        last = self.last_solved
        if last is None or abs(stamp - last.stamp) > self.staleness:
            self._reject(topic, "no solved pose within the staleness limit")
            return None
        self.stats.used[topic] += 1
        return residuals(self.noise, stamp, values, self.last_predicted)

    @staticmethod
    def read_channels(topic: str, message: Any) -> dict[str, float]:
        """What the channels read off a message of `topic` (NaN where a field holds no number)."""
        return {c.name: c.read(message) for c in channels.on_topic(topic)}

    def on_input(self, spec: Input, stamp: float, message: Any) -> None:
        """An extra input's message (e.g. the shaft temperature): kept for the samples' conditions."""
        self.stats.messages[spec.topic] += 1
        value = spec.read(message)
        if not math.isfinite(value) or not math.isfinite(stamp):
            self._reject(spec.topic, f"bad input: {spec.field} = {value}")
            return
        self.inputs[spec.key].add(stamp, value)
        self.stats.used[spec.topic] += 1
