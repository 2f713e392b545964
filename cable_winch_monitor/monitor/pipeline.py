"""The monitor as one object: winch samples in, solved pose, tensions, alarm and residuals out.

The live node and bag replay both feed this object, so both give the same answers. It
knows nothing of ROS: winch messages arrive as plain values with their header stamps,
other sensors as message objects read by their declared channels (channels.py), extra
inputs (a shaft temperature) by the effects' declared `Input`s. Every sample is solved
through the plant's one model (effects.PlantModel: its effects, its load, its solver)
at the sample's conditions (time, payout speeds and accelerations, direction, inputs).

Where the plant file gives the encoders a noise (`noise.length`), a sample is not solved
from its lengths alone but estimated (monitor.estimator): its lengths, its load pins and
the latest readings of the other sensors within the staleness limit, with the model's
error as part of the state, so that what is measured wins over what the model says.
The model's own prediction comes with it, and the alarm is based on the measured tilt,
or on the model where it is more dangerous beyond their spread (monitor.basis).

Consecutive samples go through the stages together, as a run (the node's taken together, replay's
window; one sample is a run of one): `solve_samples` gives their `SolvedRun`, `judge_samples` a
`Judged` run, a column per quantity (monitor.judged).
"""
from __future__ import annotations

import math
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import lru_cache
from typing import TYPE_CHECKING, Any, NamedTuple, cast

import numpy as np
from numpy.typing import ArrayLike

from ..channels import TENSION_CHANNELS, ChannelRegistry, Input
from ..effects import PlantModel
from ..effects.estimate import fuses
from ..effects.model import NO_CONDITIONS
from ..model.conditions import Conditions, ConditionsTracker
from ..model.estimator import Estimate
from ..model.plantfile.plant import Plant
from ..model.statics.result import Solution, SolveStatus
from .alarm import Alarm, AlarmPolicy, AlarmTracker
from .basis import CORROBORATING_PINS, Basis, judged, tilt_sigmas
from .clearance import Clearance, batch_clearances, solution_clearance, solution_clearances
from .estimator import Estimated, MonitorEstimator, SampleInput
from .inputs import (
    CableLengthMerger,
    CableReading,
    InputLimits,
    InputSeries,
    JointSample,
    StampWindow,
    measurement_reason,
    small_mean,
)
from .judged import Judged, ModelViews, MonitorOutput, Outcome, SolvedRun
from .residuals import Residuals, noise_levels, residuals
from .sensors import READING_LAG, LatestReadings, PayoutHistory, StuckReadings

if TYPE_CHECKING:  # the node's process for the window updates: replay need not import it
    from .updates import UpdateProcess

CONTRADICTS = "contradicts the other sensors"  # why a sensor the estimator rejects or leaves out is not fused
SILENT = 2.0  # a sensor heard before is silent when its last reading is this many staleness limits old


class CompleteSample(NamedTuple):
    """Four fresh cable lengths at a winch message's stamp, with what the merger knew then."""

    stamp: float
    lengths: np.ndarray
    accepted: list[int]  # the cables this message updated
    tensions: list[float]  # load pins of the four cables [N] (NaN: not measured)
    speeds: list[float]  # payout speeds [m/s] (NaN: not reported)
    sensors: dict[str, float] = {}  # what every sensor read then: the load pins, the latest other readings
    taken: dict[str, float] = {}  # the stamp of each of those readings [s]
    faults: dict[str, str] = {}  # sensors whose readings are not there: stuck at a constant, or silent (why)


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
    winch: int = 0  # winch messages merged or refused
    winch_topics: set[str] = field(default_factory=set)  # the topics they came on
    last_winch_rejection: str = ""
    faults: dict[str, list] = field(default_factory=dict)  # sensor -> [samples left out, first, last stamp, why]
    bases: Counter[str] = field(default_factory=Counter)  # what the alarms were based on
    last_error: tuple[tuple[float, ...], tuple[float, ...]] | None = None  # the model's error at the last estimated sample

    def note(self, outcome: Outcome) -> None:
        """A solved sample's counts."""
        self.solved += int(outcome.status is SolveStatus.SOLVED)
        self.failures += int(outcome.status in (SolveStatus.SOLVER_FAILED, SolveStatus.NO_EQUILIBRIUM))
        self.states[outcome.tension_state] += 1
        self.levels[outcome.level] += 1
        if outcome.basis:
            self.bases[outcome.basis] += 1
        if outcome.error is not None:
            self.last_error = outcome.error
        self.note_faults(outcome.stamp, outcome.faults)

    def note_faults(self, stamp: float, faults: Mapping[str, str]) -> None:
        """The sensors left out at a sample stamped `stamp` [s], with why (the latest why is kept)."""
        for sensor, why in faults.items():
            entry = self.faults.get(sensor)
            if entry is None:
                self.faults[sensor] = [1, stamp, stamp, why]
            else:
                entry[0] += 1
                entry[2], entry[3] = stamp, why


@lru_cache(maxsize=256)
def _measured(used: tuple[str, ...]) -> tuple[bool, bool]:
    """Whether an estimate that used these channels measured the tilt, and enough load pins to corroborate it."""
    return "roll" in used and "pitch" in used, sum(name in used for name in TENSION_CHANNELS) >= CORROBORATING_PINS


def stuck_faults(stuck: Mapping[str, tuple[float, float]], channels: ChannelRegistry) -> dict[str, str]:
    """The sensors of channels stuck at a constant (channel: value, since when [s]), with why they are left out."""
    return {channels.sensor_of(name): f"stuck at {value:.6g} since {since:.3f} s" for name, (value, since) in stuck.items()}


class MonitorPipeline:
    """Merges inputs, estimates (or solves) each complete sample, and derives alarm and residuals."""

    def __init__(self, plant: Plant, solver: str = "energy", staleness: float = 0.5,
                 stamp_window: StampWindow | None = None, background: UpdateProcess | None = None,
                 lag: float = READING_LAG):
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
        self.last_solved_stamp = math.nan
        self.noise = noise_levels(plant, self.model.channels)
        self.fusing = solver == "energy" and fuses(self.model)
        self.readings = LatestReadings(staleness, lag)  # a sample fuses the readings stamped `lag` before it
        self.pins = StuckReadings()
        self.heard: dict[str, float] = {}  # load pin -> the stamp of its latest finite reading
        # background: where the window updates are worked out (None: at once, as replay does)
        self.estimator = MonitorEstimator(self.model, background) if self.fusing else None
        self.payouts = PayoutHistory()  # the recent complete samples' mean payouts, to carry readings by

    def _reject(self, topic: str, reason: str) -> None:
        self.stats.rejected[f"{topic}: {reason.split(':')[0]}"] += 1
        self.stats.last_rejection = f"{topic}: {reason}"

    def on_joint_state(self, sample: JointSample) -> MonitorOutput | None:
        """A winch message; returns the solved sample when the four lengths are complete and fresh, with what the
        sensors read then (the readings in so far: one due at it is not waited for)."""
        complete = self.merge_winch(sample)
        return None if complete is None else self.solve(self.read_sensors(complete))

    def merge_winch(self, sample: JointSample) -> CompleteSample | None:
        """Merge a winch message; the complete sample it makes, if it makes one, with its own load pins (but
        a stuck one) and the pins' faults. The other sensors' readings are `read_sensors`' to add: the node
        and replay first wait for those due at the sample (monitor.waiting)."""
        self.stats.messages[sample.topic] += 1
        self.stats.winch += 1
        self.stats.winch_topics.add(sample.topic)
        merged = self.merger.add(sample)
        if merged.ignored:
            self.stats.ignored_names.update(merged.ignored)
        if merged.rejected:
            self._reject(sample.topic, merged.rejected)
            self.stats.last_winch_rejection = self.stats.last_rejection
            return None
        self.stats.used[sample.topic] += 1
        readings = self.merger.readings
        if self.fusing:
            for cable in merged.accepted:
                reading = readings[cable]
                assert reading is not None  # the message just gave it
                if math.isfinite(reading.tension):
                    self.pins.add(TENSION_CHANNELS[cable], reading.tension, sample.stamp)
        lengths, waiting = self.merger.complete(sample.stamp)
        self.stats.waiting = waiting
        if lengths is None:
            return None
        cables = cast(list[CableReading], readings)  # the lengths are complete: every cable has a reading
        speeds = [r.velocity for r in cables]
        speed = small_mean(speeds)
        self.payouts.add(sample.stamp, small_mean(lengths.tolist()), speed if math.isfinite(speed) else 0.0)
        tensions = [r.tension for r in cables]
        if not self.fusing:
            return CompleteSample(sample.stamp, lengths, merged.accepted, tensions, speeds)
        pins, taken = {}, {}
        for name, value in zip(TENSION_CHANNELS, tensions):
            if math.isfinite(value):
                self.heard[name] = sample.stamp
                if not self.pins.is_stuck(name):
                    pins[name], taken[name] = value, sample.stamp
        faults = stuck_faults(self.pins.stuck(), self.model.channels)
        faults.update(self._silent(sample.stamp, pins, self.heard, faults))
        return CompleteSample(sample.stamp, lengths, merged.accepted, tensions, speeds, pins, taken, faults)

    def read_sensors(self, sample: CompleteSample) -> CompleteSample:
        """A complete sample from `merge_winch` with the latest other readings stamped at least the lag before it,
        within the staleness limit, and their sensors' faults."""
        if not self.fusing:
            return sample
        stamp = sample.stamp
        values, taken = self.readings.at(stamp, small_mean(sample.lengths.tolist()), self.payouts.at)
        faults = stuck_faults(self.readings.stuck_at(stamp), self.model.channels)
        faults.update(sample.faults)
        faults.update(self._silent(stamp, values, self.readings.latest(stamp), faults))
        return CompleteSample(stamp, sample.lengths, sample.accepted, sample.tensions, sample.speeds,
                              {**values, **sample.sensors}, {**taken, **sample.taken}, faults)

    def waits_for_readings(self, stamp: float) -> bool:
        """Whether a reading due at a sample stamped `stamp` has not come in yet (`LatestReadings.due`)."""
        return self.fusing and self.readings.due(stamp)

    def _silent(self, stamp: float, measured: Mapping[str, float], heard: Mapping[str, float],
                faulty: Mapping[str, str]) -> dict[str, str]:
        """The sensors heard before (`heard`: channel -> its latest stamp) with no reading at a sample stamped
        `stamp` for SILENT staleness limits (one reading late is not a fault), with why; those `faulty`
        already (stuck) left as they are."""
        out, sensor_of = {}, self.model.channels.sensor_of
        for name, when in heard.items():
            sensor = sensor_of(name)
            if name not in measured and sensor not in faulty and stamp - when > SILENT * self.staleness:
                out[sensor] = f"silent for {stamp - when:.1f} s"
        return out

    def keep_reading(self, stamp: float, values: dict[str, float]) -> None:
        """A sensor's readings, kept for the samples to come (where they are fused: the lengths taken
        as exact, only the residuals read them)."""
        if self.fusing:
            self.readings.add(stamp, values)

    def inputs_at(self, stamp: float) -> dict[str, float]:
        """The extra inputs' values at `stamp` (interpolated where later values are known, else the latest)."""
        return {key: series.value_at(stamp) for key, series in self.inputs.items()}

    def evaluate(self, lengths: ArrayLike) -> tuple[Solution, Clearance | None, Alarm]:
        """What proposed cable lengths would give at rest (for plant control), without touching the state."""
        conditions = Conditions(inputs=self.inputs_at(math.inf))
        solution = self.model.solve(lengths, self._warm_start(), conditions)
        clearance = solution_clearance(self.model.physical, solution)
        return solution, clearance, AlarmTracker(self.alarms.policy).update(solution, clearance)

    def _warm_start(self) -> Solution | None:
        return self.last_solved.solution if self.last_solved is not None and self.solver == "energy" else None

    def conditions(self, samples: Sequence[CompleteSample],
                   inputs: Sequence[Mapping[str, float]] | None = None) -> list[Conditions]:
        """The conditions of consecutive complete samples: their stamps, speeds, accelerations, directions and
        inputs (`inputs`: each one's, where taken ahead; else the inputs' values at its stamp), the same
        whether they come one at a time or a window at once; none where nothing reads them (no effect,
        no channel of a user's)."""
        if not self.model.reads_conditions:
            return [NO_CONDITIONS] * len(samples)
        if inputs is None:
            inputs = [self.inputs_at(sample.stamp) for sample in samples] if self.inputs else None
        return self.tracker.update(np.array([sample.stamp for sample in samples]),
                                   np.array([sample.lengths for sample in samples]),
                                   np.array([sample.speeds for sample in samples], dtype=float), inputs)

    def solve_samples(self, samples: Sequence[CompleteSample], conditions: Sequence[Conditions],
                      estimator: MonitorEstimator | None = None) -> SolvedRun:
        """Estimate (or solve) consecutive complete samples at their conditions: the node's as they come,
        replay's a window at once, with the same answers. `estimator`: the pipeline's, as it was taken."""
        estimator = estimator or self.estimator
        if estimator is not None:
            inputs = [SampleInput(s.stamp, s.lengths, s.sensors, s.taken, c) for s, c in zip(samples, conditions)]
            return SolvedRun.concatenated([
                self._estimated(estimated, samples[start:start + len(estimated)],
                                conditions[start:start + len(estimated)])
                for estimated, start in estimator.run(inputs)])
        lengths = np.array([s.lengths for s in samples]).reshape(-1, 4)
        solutions = self.model.solve_batch(lengths, conditions, self._warm_start())
        return self._solved(solutions, [None] * len(solutions), conditions)

    def _estimated(self, estimated: Estimated, samples: Sequence[CompleteSample],
                   conditions: Sequence[Conditions]) -> SolvedRun:
        """The solved samples of an estimator's run, with the model's own view of each (the clearance of its
        own equilibrium, its error, the sensors left out and why), and what each channel reads there under the
        model they were estimated with (the plant file's, with the tracked values then in use: a window's end
        within the samples of one call changes it)."""
        model = estimated.model
        estimates = estimated.batch.estimates()
        left_out = tuple(sorted(set(estimated.left_out)))
        contradicting = dict.fromkeys(estimated.left_out, CONTRADICTS)
        faults, left = [], []
        for sample, rejected in zip(samples, estimated.rejected):
            faulty = sample.faults
            faults.append({**faulty, **contradicting, **dict.fromkeys(rejected, CONTRADICTS)})
            left.append(tuple(sorted(set(left_out) | set(faulty))) if faulty else left_out)
        count = len(estimates)
        views = ModelViews(batch_clearances(model.physical, estimated.forward), estimated.length_error,
                           estimated.length_sigma, estimated.pin_error, estimated.pin_sigma,
                           tilt_sigmas(model.physical, estimated.prior.length_covariance).tolist(),
                           list(estimated.rejected), left, faults, [estimated.parameters] * count,
                           estimated.parameters_due or [False] * count)
        return self._solved([e.solution for e in estimates], estimates, conditions, model, views)

    def _solved(self, solutions: list[Solution], estimates: Sequence[Estimate | None], conditions: Sequence[Conditions],
                model: PlantModel | None = None, views: ModelViews | None = None) -> SolvedRun:
        """The solutions with their clearances, estimates and what every channel reads there (NaN where not
        solved), computed together, under `model` (None: the plant file's)."""
        model = model or self.model
        return SolvedRun(solutions, solution_clearances(model.physical, solutions), list(estimates),
                         model.predict_solutions(solutions, conditions), views)

    def solve(self, sample: CompleteSample) -> MonitorOutput:
        """Solve (or estimate, from what the sensors read) a complete sample, judge it and count it: the stages
        with one sample as a run of one."""
        judged = self.judge_samples([sample], self.solve_samples([sample], self.conditions([sample])))
        self.note(judged.outcomes().each()[0])
        return judged.output(0)

    def judge_samples(self, samples: Sequence[CompleteSample], solved: SolvedRun) -> Judged:
        """Consecutive samples, estimated (or solved) together by `solve_samples`, judged in order: what each
        alarm is based on, the alarms (their hysteresis carried from sample to sample, their sync errors and
        slack worked out together), each sample's load pins compared with the model. Replay's second process
        judges, the replay counts (`note` of the run's `outcomes`)."""
        views = solved.views
        if views is None:
            bases = [Basis(clearance, "") for clearance in solved.clearances]
        else:
            tilt_noise = max(self.noise.get("roll", math.nan), self.noise.get("pitch", math.nan))
            sigma = tilt_noise if math.isfinite(tilt_noise) else None
            bases = [self._basis(clearance, fused, model, tilt, sigma) for clearance, fused, model, tilt in
                     zip(solved.clearances, solved.estimates, views.clearances, views.tilt_sigma)]
        alarms = self.alarms.update_many(solved.solutions, [basis.clearance for basis in bases],
                                         [basis.text for basis in bases])
        predicted = {name: solved.predicted[name].tolist() for name in TENSION_CHANNELS if name in solved.predicted}
        pins_residuals = []
        for k, (sample, solution) in enumerate(zip(samples, solved.solutions)):
            resid = None
            if solution.ok:
                pins = {TENSION_CHANNELS[i]: sample.tensions[i] for i in sample.accepted}
                resid = residuals(self.noise, sample.stamp, pins,
                                  {name: predicted[name][k] for name in pins if name in predicted})
            pins_residuals.append(resid)
        judged = Judged([sample.stamp for sample in samples], solved, bases, alarms, pins_residuals)
        if samples:
            self.last = judged.output(len(samples) - 1)
            posed = [k for k, solution in enumerate(solved.solutions) if solution.ok]
            if posed:
                self.last_solved = self.last if posed[-1] == len(samples) - 1 else judged.output(posed[-1])
        return judged

    def note(self, outcome: Outcome) -> None:
        """A solved sample's counts, and its predictions for the residuals of the sensor messages after it
        (replay takes the outcomes of samples its second process solved)."""
        self.stats.note(outcome)
        if outcome.status is SolveStatus.SOLVED:
            self.last_solved_stamp, self.last_predicted = outcome.stamp, outcome.predicted

    @staticmethod
    def _basis(clearance: Clearance | None, fused: Estimate | None, model: Clearance | None, model_sigma: float,
               sigma: float | None) -> Basis:
        """What the alarm of an estimated sample is based on: the measured tilt's clearance, or the model's
        (`model`, its tilt's 1-sigma `model_sigma` [rad]) where it is more dangerous beyond their spread
        (`sigma`: the inclinometer's noise [rad], None where the plant file gives none: the model's tilt spread
        stands in)."""
        tilt, corroborated = _measured(fused.used if fused is not None else ())
        return judged(clearance if fused is not None and fused.ok else None, model, tilt, corroborated,
                      model_sigma if sigma is None else sigma, model_sigma)

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
        if not abs(stamp - self.last_solved_stamp) <= self.staleness:
            self._reject(topic, "no solved pose within the staleness limit")
            return None
        self.stats.used[topic] += 1
        assert self.last_predicted is not None  # kept with the stamp of the last solved sample (`note`)
        return residuals(self.noise, stamp, values, self.last_predicted)

    def read_channels(self, topic: str, message: Any) -> dict[str, float]:
        """What the channels read off a message of `topic` (NaN where a field holds no number)."""
        values = {}
        for c in self.model.channels.on_topic(topic):
            assert c.read is not None  # `on_topic` gives the channels with a reader of their own
            values[c.name] = c.read(message)
        return values

    def on_input(self, spec: Input, stamp: float, message: Any) -> None:
        """An extra input's message (e.g. the shaft temperature): kept for the samples' conditions."""
        self.stats.messages[spec.topic] += 1
        value = spec.read(message)
        if not math.isfinite(value) or not math.isfinite(stamp):
            self._reject(spec.topic, f"bad input: {spec.field} = {value}")
            return
        self.inputs[spec.key].add(stamp, value)
        self.stats.used[spec.topic] += 1
