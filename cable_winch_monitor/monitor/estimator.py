"""The monitor's estimator: each sample's state from its sensors and the model, the model's error carried
from window to window, and a sensor that contradicts the others left out.

Measurements win over the model. Each sample is estimated from its lengths, its load pins
and the latest readings of the other sensors, under the model's equilibrium, with the
model's error as part of the state (`model.model_error`): the lengths and load pins are
weighed by what the model is expected to be off by, not by the sensors' noise alone, so
a plant file that is centimetres or kilonewtons off is corrected by the sensors instead
of the sensors being judged against it. The model fills in what no sensor measures and
predicts: `forward` is its own prediction of each sample, the equilibrium of the reported
lengths corrected by the expected error, which the alarm compares with the estimate.

A sensor is a fault when it contradicts the other sensors, not the model: a sample whose
sensors fail their Mahalanobis gates (or whose lengths leave the model's expected error)
is estimated again without each of its sensors in turn, and the sensor whose leaving
out makes the rest agree is rejected at that sample. A sensor rejected on most samples
of an update window is left out of the next ones, and tried again on every
`RETRY_EVERY`-th sample until it agrees again.

Everything here is a function of the samples in order: the node estimates one sample at a
time and replay a window's samples at once, and both update the model's error at the
same sample stamps, so they give the same states.
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from ..effects import PlantModel
from ..effects.estimate import length_noise, observations_for
from ..model.conditions import Conditions, line_slopes
from ..model.estimator import (
    BatchEstimate,
    ErrorState,
    ModelError,
    Prior,
    Problem,
    Rows,
    chi_square_threshold,
    estimate_batch,
    forward_kinematics,
    unfused,
)
from ..model.solvers.batched import BatchSolution
from ..model.statics.geometry import roll_pitch_yaw
from ..model.statics.result import Solution
from .sensitivity import WindowSamples
from .tracking import ParameterTracker, ParameterView, TrackState

if TYPE_CHECKING:  # the node's process for the window updates: replay, which works them out at once, need not import it
    from .updates import PendingUpdate, UpdateProcess

CARRIED = ("roll", "pitch")  # readings carried to the sample's stamp by the model's own rate of change
CARRY_WINDOW = 1.0    # [s] of the model's predictions that give that rate
LEFT_OUT_SHARE = 0.5  # a sensor rejected on more than this share of a window's samples is left out of the next ones
RETRY_EVERY = 10      # a sensor left out is tried again on every this-many-th sample
TAKEN_BACK_SHARE = 0.9  # and taken back when it agrees on at least this share of its tries in a window
FOLLOW = 10.0  # how many times less a sample the model cannot explain weighs the model's lengths
# Runs of at most this many samples (the node's) after one the model could not explain are estimated under the
# model loosely held too, in the same batch: a sample that fails its gates is estimated again so (`_screen`),
# which during a swing the model cannot follow is every sample, and one batch of two rows costs the node little
# more than one of one (its cost is numpy's per call); replay's runs are mostly its windows' hundreds of samples,
# which estimate their failing samples again alone (the same bits either way)
SPECULATED = 4
_THRESHOLDS = np.array([np.inf] + [chi_square_threshold(dof) for dof in range(1, 17)])  # by channels measured


@dataclass
class Trial:
    """Samples estimated again, each without one of its sensors (`sensors`: the ones left out; None: each of
    theirs in turn): the (sample, sensor) pairs, the readings kept, the estimates, and whether the other sensors
    then agree -- under the model as it is (`with_lengths`: the lengths agreeing too) or loosely held."""

    sensors: tuple[str, ...] | None
    with_lengths: bool
    pairs: list[tuple[int, str]]
    readings: list[dict[str, float]]
    without: BatchEstimate | None
    agrees: np.ndarray
    _agreeing: dict[int, list[int]] = field(init=False)

    def __post_init__(self) -> None:
        self._agreeing = {}
        for k, (i, _) in enumerate(self.pairs):
            if self.agrees[k]:
                self._agreeing.setdefault(i, []).append(k)

    def agreeing(self, i: int) -> list[int]:
        """The pairs of sample i whose leaving out made the other sensors agree."""
        return self._agreeing.get(i, [])

    def cost(self, k: int) -> float:
        assert self.without is not None and self.without.cost is not None  # estimated wherever there were pairs
        return float(self.without.cost[k])


class SampleInput(NamedTuple):
    """What the estimator needs of a complete sample."""

    stamp: float
    reported: np.ndarray               # (4,) the encoders' lengths [m]
    measured: Mapping[str, float]      # every sensor's reading at the sample, by channel
    taken: Mapping[str, float]         # the stamp of each reading [s] (a load pin's is the sample's)
    conditions: Conditions


@dataclass
class Estimated:
    """What the estimator made of consecutive samples of one update window (arrays over them)."""

    batch: BatchEstimate                  # the fused states (`batch.estimate(i)`)
    forward: BatchSolution                # the model's own prediction of each sample
    prior: Prior                          # the model's expected error at each sample, sensors' noise included
    rejected: list[tuple[str, ...]]       # sensors rejected at each sample (they contradict the others)
    left_out: tuple[str, ...]             # sensors left out of the whole window (found faulty before)
    length_error: np.ndarray              # (N, 4) the model's estimated length error [m] (model minus reported)
    length_sigma: np.ndarray              # (N, 4) its 1-sigma [m]
    pin_error: np.ndarray                 # (N, 4) the load pins' estimated error [N] (reading minus model)
    pin_sigma: np.ndarray                 # (N, 4) its 1-sigma [N]
    model: PlantModel                     # the model they were estimated under (the tracked values then in use)
    parameters: ParameterView | None = None  # the tracked plant parameters (None: the plant file tracks none)
    parameters_due: list[bool] | None = None  # which samples publish them

    def __len__(self) -> int:
        return len(self.batch)


@dataclass
class _Window:
    """The samples of the current update window, kept for its update."""

    index: int
    reported: list[np.ndarray] = field(default_factory=list)
    lengths: list[np.ndarray] = field(default_factory=list)
    measured: list[dict[str, float]] = field(default_factory=list)
    conditions: list[Conditions] = field(default_factory=list)
    stamps: list[float] = field(default_factory=list)
    states: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None] = field(default_factory=list)
    followed: list[bool] = field(default_factory=list)  # the state follows the sensors: the model could not explain it
    rejected: dict[str, int] = field(default_factory=dict)     # sensor -> samples it was rejected at
    measuring: dict[str, int] = field(default_factory=dict)    # sensor -> samples it was measured at
    tried: dict[str, list[bool]] = field(default_factory=dict)  # left-out sensor -> did it agree at each try
    misfits: list[float] = field(default_factory=list)  # each estimated sample's length misfit (`_length_misfit`)

    def __getstate__(self) -> dict[str, Any]:
        """Its samples stacked, for the update process: pickled one by one, a window of 500 samples' small
        arrays and conditions took the node's worker 16-30 ms at each window's end."""
        present = [state for state in self.states if state is not None]
        return {**self.__dict__, "reported": np.array(self.reported).reshape(-1, 4),
                "lengths": np.array(self.lengths).reshape(-1, 4), "conditions": _packed(self.conditions),
                "states": (np.array([state is not None for state in self.states], bool),
                           *(np.array([state[j] for state in present]) for j in range(4)))}

    def __setstate__(self, state: dict[str, Any]) -> None:
        present, *stacked = state["states"]
        rows = iter(zip(*stacked))
        self.__dict__.update({**state, "reported": list(state["reported"]), "lengths": list(state["lengths"]),
                              "conditions": _unpacked(state["conditions"]),
                              "states": [next(rows) if there else None for there in present.tolist()]})


def _packed(conditions: list[Conditions]) -> tuple[np.ndarray, list[Mapping[str, float]]]:
    """Conditions as one array (n, 13: time, speeds, accelerations, directions) and their inputs."""
    return (np.array([[c.time, *c.speeds, *c.accelerations, *c.direction] for c in conditions]).reshape(-1, 13),
            [c.inputs for c in conditions])


def _unpacked(packed: tuple[np.ndarray, list[Mapping[str, float]]]) -> list[Conditions]:
    values, inputs = packed
    return [Conditions(float(row[0]), row[1:5], row[5:9], row[9:13], extra) for row, extra in zip(values, inputs)]


class MonitorEstimator:
    """The estimator of one stream of samples (a live node's, a replay's), with its model error and faults."""

    def __init__(self, model: PlantModel, background: UpdateProcess | None = None):
        self.base = model  # the plant file's; `model` is it with the tracked values in use
        self.tracker = ParameterTracker.of(model)
        # the node works each window's update out in a process of its own beside the samples (`background`)
        self.background = background
        # the last window's update (the model's error, the tracker's state), taken at the next window's end
        self.pending: PendingUpdate | tuple[ErrorState, TrackState | None] | None = None
        sigma_length = length_noise(model)
        if sigma_length is None:
            raise ValueError("the plant file gives the encoders no noise (noise.length): the lengths are taken "
                             "as exact and nothing is estimated")
        self.sigma_length = sigma_length
        sigma_pin = float(model.plant.noise.get("tension", math.nan))
        self.error = ModelError(model.plant.model_error, sigma_length, sigma_pin if sigma_pin > 0.0 else 1.0)
        self._use(model)
        self.origin: float | None = None
        self.window: _Window | None = None
        self.left_out: dict[str, float] = {}   # sensor -> the stamp from which it is left out
        self.last_rejected: tuple[str, ...] = ()  # the sensors rejected at the sample before
        # every forward solve of a window starts from the last sample solved before the window (the first
        # window's: from the first of its samples that solved alone), so that a sample's start does not depend
        # on which samples the node or the replay solves with it, and no window starts cold
        self.seed: Solution | None = None
        self.last_solved: tuple[BatchSolution, int] | None = None  # the latest forward solve's last solved row
        self.predictions: list[tuple[float, float, float]] = []  # the model's stamp, roll, pitch lately
        self.failing = False  # whether the latest sample failed its gates (the model could not explain it)

    def __getstate__(self) -> dict[str, Any]:
        """What it has learnt, without the model (a user's effects need not pickle: whoever restores it gives
        the model back) and without the node's update process (its pending update taken)."""
        return {**self.__dict__, "model": None, "base": None, "background": None, "pending": self._settled()}

    def _settled(self) -> tuple[ErrorState, TrackState | None] | None:
        """The pending window update's result: worked out already, or awaited from the node's update process."""
        pending = self.pending
        return pending if pending is None or isinstance(pending, tuple) else pending.result(self.base)

    def _last_solution(self) -> Solution | None:
        """The last sample that the forward kinematics solved, where one has been."""
        return None if self.last_solved is None else self.last_solved[0].solution(self.last_solved[1])

    def attach(self, model: PlantModel) -> None:
        """Give the plant file's model back to an estimator restored from a pickle."""
        self.base = model
        self._use(model if self.tracker is None else self.tracker.model(model))

    def _use(self, model: PlantModel) -> None:
        """Estimate with `model` (the plant file's, or it with tracked values in use) from now on."""
        self.model = model
        self.ropes = model.ropes

    def run(self, samples: Sequence[SampleInput]) -> list[tuple[Estimated, int]]:
        """Estimate consecutive samples (in stamp order); returns, for each run of them in one update window,
        what was estimated and the index of its first sample in `samples`. The window's end updates the
        model's error before the next one is estimated."""
        out = []
        start = 0
        while start < len(samples):
            if self.origin is None:
                self.origin = samples[start].stamp
                self.error.start(self.origin)
            index = self._window_of(samples[start].stamp)
            if self.window is not None and index != self.window.index:
                self._close(index)
            if self.window is None:
                self.window, self.seed = _Window(index), self._last_solution()
            stop = start + 1
            while stop < len(samples) and self._window_of(samples[stop].stamp) == index:
                stop += 1
            out.append((self._estimate(samples[start:stop]), start))
            start = stop
        return out

    def _window_of(self, stamp: float) -> int:
        """The update window of a sample: the window its stamp falls in, or the open one where that is later (a
        sample made at another winch's message may be stamped a little before the one before it, across a
        window's start: it is not taken back to the window closed already)."""
        assert self.origin is not None  # set by the first sample
        index = self.error.window(stamp, self.origin)
        return index if self.window is None else max(index, self.window.index)

    # -- one run of samples in the current window ------------------------------------------------------------
    def _estimate(self, samples: Sequence[SampleInput]) -> Estimated:
        model = self.model
        stamps = np.array([s.stamp for s in samples])
        reported = np.array([s.reported for s in samples], dtype=float)
        conditions = [s.conditions for s in samples]
        lengths, loads, hooked = model.batch_inputs(reported, conditions)
        lengths[hooked] = reported[hooked]  # estimated as reported, published as the hook's failure (below)
        prior = self.error.prior(stamps, lengths)
        forward = forward_kinematics(model.physical, lengths + prior.lengths, self.ropes, loads, self.seed)
        solved = np.flatnonzero(forward.ok)
        if solved.size:
            self.seed = forward.solution(int(solved[0])) if self.seed is None else self.seed
            self.last_solved = forward, int(solved[-1])
        measured = self._carried(samples, forward)
        left_out = tuple(sorted(self.left_out))
        sensor_of = model.channels.sensor_of
        kept = [{name: value for name, value in row.items() if sensor_of(name) not in self.left_out} for row in measured] \
            if self.left_out else list(measured)
        if self.failing and len(samples) <= SPECULATED:
            batch, loosely = self._batches(lengths, kept, conditions, loads, (prior, _loosened(prior)), forward)
        else:
            batch, loosely = self._batch(lengths, kept, conditions, loads, prior, forward), None
        for k in hooked:  # an effect's hook failed on this sample: the model's own solve says why
            batch.fallback[k] = unfused(model.solve(reported[k], None, samples[k].conditions), reported[k],
                                        self.sigma_length)
        rejected, followed = self._screen(batch, lengths, kept, samples, loads, prior, forward, loosely)
        self._try_left_out(lengths, measured, kept, samples, loads, prior, forward, batch)
        self._remember(samples, lengths, kept, rejected, followed, batch, prior)
        length_error, length_sigma = self.error.length_errors(lengths)
        pin_error, pin_sigma = self.error.pin_errors(lengths)
        tracked = (None, None) if self.tracker is None else (self.tracker.view(), self.tracker.due(stamps.tolist()))
        return Estimated(batch, forward, prior, rejected, left_out, length_error, length_sigma, pin_error, pin_sigma,
                         model, *tracked)

    def _batch(self, lengths: np.ndarray, measured: Sequence[Mapping[str, float]], conditions: Sequence[Conditions],
               loads: np.ndarray, prior: Prior, forward: BatchSolution) -> BatchEstimate:
        """The fused states of samples with these readings (NaN-free mappings, any channels)."""
        names = sorted({name for row in measured for name in row})
        values = {name: np.array([row.get(name, np.nan) for row in measured]) for name in names}
        observations = observations_for(self.model, values, conditions)
        return estimate_batch(self.model.physical, lengths, observations, self.sigma_length,
                              self.ropes.axial_stiffness, self.ropes.weight, loads=loads, prior=prior, forward=forward)

    def _batches(self, lengths: np.ndarray, measured: Sequence[Mapping[str, float]],
                 conditions: Sequence[Conditions], loads: np.ndarray, priors: Sequence[Prior],
                 forward: BatchSolution) -> list[BatchEstimate]:
        """`_batch` under each of `priors`, in one batch: the same states as one batch each (every row is worked
        out on its own), for numpy's cost per call once."""
        count = len(lengths)
        rows = np.tile(np.arange(count), len(priors))
        batch = self._batch(lengths[rows], [measured[i] for i in rows], [conditions[i] for i in rows], loads[rows],
                            Prior.stacked(priors), _take(forward, rows))
        return [batch.take(np.arange(k * count, (k + 1) * count)) for k in range(len(priors))]

    def _carried(self, samples: Sequence[SampleInput], forward: BatchSolution) -> list[dict[str, float]]:
        """Each sample's readings, the inclinometer's carried from its stamp to the sample's by the rate at
        which the model's own roll and pitch have been changing (a line through its predictions of the last
        CARRY_WINDOW seconds): its readings come tens of milliseconds after the winches', so the latest one
        at a sample is most of a sample period old, which during a swing towards the wall is millimetres of
        clearance. A line, not the last two predictions: those differ by the encoders' noise.

        A sample's line runs through the predictions of the samples up to it, in their order, from the first
        stamped within CARRY_WINDOW before it: samples made at each winch's message are not quite in stamp
        order, and a window found by time alone would take a later sample's prediction, or not, as the
        samples estimated with it went (the node's one, replay's many)."""
        stamps = np.array([s.stamp for s in samples])
        ok = forward.ok
        angles = np.array([roll_pitch_yaw(r)[:2] for r in forward.rotation[ok]]).reshape(-1, 2)
        earlier = np.array(self.predictions).reshape(-1, 3)
        times = np.concatenate([earlier[:, 0], stamps[ok]])
        values = np.concatenate([earlier[:, 1:], angles])
        reached = np.maximum.accumulate(times) if times.size else times  # the first within a window: the first to reach it
        stop = len(earlier) + np.cumsum(ok)  # the predictions of the samples up to each
        start = np.minimum(np.searchsorted(reached, stamps - CARRY_WINDOW, side="left"), stop)
        rates = line_slopes(times, values, start, stop, least=3)
        # kept for the samples to come: from the first that reaches CARRY_WINDOW before the latest stamp, and as
        # much again for samples stamped before the latest
        kept = int(np.searchsorted(reached, reached[-1] - 2.0 * CARRY_WINDOW, side="left")) if times.size else 0
        self.predictions = [tuple(row) for row in np.column_stack([times[kept:], values[kept:]]).tolist()]
        out = []
        for k, sample in enumerate(samples):
            row = {name: value for name, value in sample.measured.items() if math.isfinite(value)}
            for c, name in enumerate(CARRIED):
                taken = sample.taken.get(name)
                if name in row and taken is not None and math.isfinite(rates[k, c]):
                    row[name] += rates[k, c] * (sample.stamp - taken)
            out.append(row)
        return out

    # -- faults ----------------------------------------------------------------------------------------------
    def _failing(self, batch: BatchEstimate, prior: Prior, lengths: bool = True) -> np.ndarray:
        """(N,) samples whose sensors or lengths disagree beyond their gates: the whole estimate's cost beyond
        the gate of its measurements (the load pins are weighed together: an error common to them all is
        the model's, one pin's own is not), a sensor's channels beyond theirs, or (`lengths`) the lengths
        beyond the model's expected error."""
        assert batch.cost is not None  # the estimator's batches are all weighed by the model's prior (`_batch`)
        measured = np.isfinite(batch.residuals).sum(axis=1)
        verdict = np.nan_to_num(batch.cost, nan=0.0) > _THRESHOLDS[np.minimum(measured, len(_THRESHOLDS) - 1)]
        groups: dict[str, list[int]] = {}
        sensor_of = self.model.channels.sensor_of
        for k, name in enumerate(batch.names):
            groups.setdefault(sensor_of(name), []).append(k)
        for columns in groups.values():
            values = batch.residuals[:, columns]
            dof = np.isfinite(values).sum(axis=1)
            chi_square = np.nansum(values ** 2, axis=1)
            limit = _THRESHOLDS[np.minimum(dof, len(_THRESHOLDS) - 1)]
            verdict |= chi_square > limit
        if lengths:
            verdict |= self._length_misfit(batch, prior) > chi_square_threshold(4)
        return verdict & np.array([i not in batch.fallback for i in range(len(batch))])

    @staticmethod
    def _length_misfit(batch: BatchEstimate, prior: Prior) -> np.ndarray:
        """(N,) the corrections' Mahalanobis distance squared from the model's expected error."""
        deviation = np.nan_to_num(batch.corrections - prior.lengths)
        return np.einsum("ni,ni->n", deviation, np.linalg.solve(prior.length_covariance, deviation[..., None])[..., 0])

    def _screen(self, batch: BatchEstimate, lengths: np.ndarray, measured: list[dict[str, float]],
                samples: Sequence[SampleInput], loads: np.ndarray, prior: Prior, forward: BatchSolution,
                loosely: BatchEstimate | None = None) -> tuple[list[tuple[str, ...]], np.ndarray]:
        """Each sample's rejected sensors, and which samples the model could not explain. A sample that fails
        its gates is estimated again with the model's lengths weighed FOLLOW times less: where its
        sensors then agree with each other, the model is what was wrong (faster than its error is learnt),
        and the state follows the sensors. Where they still do not, it is estimated again without each of
        its sensors in turn, under the model as it is (the lengths agreeing too), then under the model
        loosely held; of those whose leaving out makes the others agree, the one rejected at the sample
        before if it is one of them (a fault lasts, and where four rigid ropes can share the load any way,
        two pins may each be the odd one out at one sample), else the one whose leaving out lowers the
        cost most, is rejected. A sensor is a fault where it contradicts the other sensors, never where it
        contradicts the model alone. `loosely`: the samples estimated under the model loosely held already,
        where they were (SPECULATED). In place on `batch` and `measured`."""
        rejected: list[tuple[str, ...]] = [() for _ in samples]
        followed = np.zeros(len(samples), bool)
        failing = np.flatnonzero(self._failing(batch, prior))
        self.failing = bool(failing.size and failing[-1] == len(samples) - 1)
        if not failing.size:
            self.last_rejected = ()
            return rejected, followed
        loose = _loosened(prior)
        again = loosely.take(failing) if loosely is not None else \
            self._batch(lengths[failing], [measured[i] for i in failing],
                        [samples[i].conditions for i in failing.tolist()], loads[failing], loose.take(failing),
                        _take(forward, failing))
        disagree = self._failing(again, loose.take(failing), lengths=False)
        for k, i in enumerate(failing.tolist()):
            if k not in again.fallback:
                _put(batch, i, again, k)
                followed[i] = not disagree[k]
        suspects = failing[disagree]
        # the sensor rejected at the sample before, left out alone first: where the others then agree it is the
        # one rejected, whatever leaving out the others would do (a fault lasts for a window of samples)
        lasting = self._trials(suspects, lengths, measured, samples, loads, prior, forward, self.last_rejected)
        tiers: list[Trial] | None = None
        suspect = set(suspects.tolist())
        for i in range(len(samples)):  # in order: what was rejected at the sample before is preferred
            if i in suspect:
                if lasting.agreeing(i) and self.last_rejected == lasting.sensors:
                    self._reject(batch, measured, rejected, followed, i, lasting, lasting.agreeing(i)[0])
                else:
                    if tiers is None:  # the suspects from here on, each of their sensors left out in turn
                        tiers = self._without_each(suspects[suspects >= i], lengths, measured, samples, loads,
                                                   (prior, loose), forward)
                    for trial in tiers:  # the model as it is, then loosely held
                        agreeing = trial.agreeing(i)
                        if agreeing:
                            preferred = [k for k in agreeing if trial.pairs[k][1] in self.last_rejected]
                            best = preferred[0] if preferred else min(agreeing, key=trial.cost)
                            self._reject(batch, measured, rejected, followed, i, trial, best)
                            break
            self.last_rejected = rejected[i]
        return rejected, followed

    @staticmethod
    def _reject(batch: BatchEstimate, measured: list[dict[str, float]], rejected: list[tuple[str, ...]],
                followed: np.ndarray, i: int, trial: Trial, k: int) -> None:
        """Sample i takes pair k of `trial`: its estimate without that pair's sensor, which is rejected."""
        assert trial.without is not None  # estimated wherever there were pairs
        _put(batch, i, trial.without, k)
        measured[i] = trial.readings[k]
        rejected[i] = (trial.pairs[k][1],)
        followed[i] = not trial.with_lengths

    def _without_each(self, suspects: np.ndarray, lengths: np.ndarray, measured: list[dict[str, float]],
                      samples: Sequence[SampleInput], loads: np.ndarray, priors: tuple[Prior, Prior],
                      forward: BatchSolution) -> list[Trial]:
        """The suspect samples estimated again without each of their sensors under the model as it is (the
        lengths agreeing too), then, those none of whose leavings-out made the others agree, under it loosely
        held (`priors`). A sample that found its sensor under the first is not tried under the second
        (`_screen` takes the first's): a sensor disagreeing for a window of samples cost the lab robot's
        replay a third of its estimating process, tried under both."""
        out: list[Trial] = []
        for prior, with_lengths in zip(priors, (True, False)):
            trial = self._trials(suspects, lengths, measured, samples, loads, prior, forward, None, with_lengths)
            out.append(trial)
            suspects = np.array([i for i in suspects.tolist() if not trial.agreeing(i)], dtype=int)
        return out

    def _trials(self, suspects: np.ndarray, lengths: np.ndarray, measured: list[dict[str, float]],
                samples: Sequence[SampleInput], loads: np.ndarray, prior: Prior, forward: BatchSolution,
                sensors: tuple[str, ...] | None, with_lengths: bool = True) -> Trial:
        """The suspect samples estimated again without each of `sensors` that they measure (None: each of theirs)
        in turn, under `prior`; whether the other sensors then agree (`with_lengths`: the lengths too)."""
        sensor_of = self.model.channels.sensor_of
        pairs = [(i, sensor) for i in suspects.tolist() for sensor in sorted({sensor_of(n) for n in measured[i]})
                 if sensors is None or sensor in sensors]
        if not pairs:
            return Trial(sensors, with_lengths, [], [], None, np.zeros(0, bool))
        rows = np.array([i for i, _ in pairs], dtype=int)
        readings = [{n: v for n, v in measured[i].items() if sensor_of(n) != sensor} for i, sensor in pairs]
        weight = prior.take(rows)
        without = self._batch(lengths[rows], readings, [samples[i].conditions for i in rows], loads[rows], weight,
                              _take(forward, rows))
        agrees = ~self._failing(without, weight, lengths=with_lengths) & \
            np.array([k not in without.fallback for k in range(len(pairs))])
        return Trial(sensors, with_lengths, pairs, readings, without, agrees)

    def _try_left_out(self, lengths: np.ndarray, measured: list[dict[str, float]], kept: list[dict[str, float]],
                      samples: Sequence[SampleInput], loads: np.ndarray, prior: Prior, forward: BatchSolution,
                      batch: BatchEstimate) -> None:
        """Every RETRY_EVERY-th sample (by its place in the window), each sensor left out is tried: the
        sample estimated with it too; whether it agrees is kept for the window's end."""
        if not self.left_out:
            return
        window = self.window
        assert window is not None  # `run` opens the window before estimating its samples
        offset, sensor_of = len(window.stamps), self.model.channels.sensor_of
        tries = [(k, sensor) for k in range(len(samples)) if (offset + k) % RETRY_EVERY == 0 and k not in batch.fallback
                 for sensor in sorted(self.left_out) if any(sensor_of(n) == sensor for n in measured[k])]
        if not tries:
            return
        rows = np.array([k for k, _ in tries])
        trial = [{**kept[k], **{n: v for n, v in measured[k].items() if sensor_of(n) == sensor}} for k, sensor in tries]
        again = self._batch(lengths[rows], trial, [samples[k].conditions for k in rows], loads[rows],
                            prior.take(rows), _take(forward, rows))
        agrees = ~self._failing(again, prior.take(rows))
        for (_, sensor), verdict in zip(tries, agrees.tolist()):
            window.tried.setdefault(sensor, []).append(bool(verdict))

    # -- the window's samples, and its end --------------------------------------------------------------------
    def _remember(self, samples: Sequence[SampleInput], lengths: np.ndarray, measured: list[dict[str, float]],
                  rejected: list[tuple[str, ...]], followed: np.ndarray, batch: BatchEstimate, prior: Prior) -> None:
        """Keep the samples of the window for its update: those the model could not explain (`followed`)
        only for how far it was off, not for what its error is (the tracked parameters are learnt from
        their states, which the sensors agree on)."""
        window = self.window
        assert window is not None  # `run` opens the window before estimating its samples
        estimated = batch.status == "solved"
        estimated[list(batch.fallback)] = False
        window.misfits += self._length_misfit(batch, prior)[estimated].tolist()
        solved = (estimated & self._plausible(batch)).tolist()
        window.reported += [sample.reported for sample in samples]
        window.lengths += list(lengths)
        window.measured += measured
        window.conditions += [sample.conditions for sample in samples]
        window.stamps += [sample.stamp for sample in samples]
        window.states += [(batch.taut[k], batch.rotation[k], batch.position[k], batch.tensions[k]) if solved[k] else None
                          for k in range(len(samples))]
        window.followed += followed.tolist()
        sensors: dict[tuple[str, ...], frozenset[str]] = {}  # of each set of channels measured (a few in a run)
        sensor_of = self.model.channels.sensor_of
        for channels, rejects in zip(measured, rejected):
            names = tuple(channels)
            if names not in sensors:
                sensors[names] = frozenset(map(sensor_of, names))
            for sensor in sensors[names].union(rejects):
                window.measuring[sensor] = window.measuring.get(sensor, 0) + 1
            for sensor in rejects:
                window.rejected[sensor] = window.rejected.get(sensor, 0) + 1

    @staticmethod
    def _plausible(batch: BatchEstimate) -> np.ndarray:
        """(N,) whether each sample's estimate is one the model's error may be learnt from: its cost within the
        gate of its measurements (a sample the search could only explain badly would pull the error astray)."""
        if batch.cost is None:
            return np.ones(len(batch), bool)
        dof = (4 + np.isfinite(batch.residuals).sum(axis=1)).tolist()
        gates = {d: chi_square_threshold(d) for d in set(dof)}
        return batch.cost <= np.array([gates[d] for d in dof])

    def _close(self, next_index: int) -> None:
        """The window's end: the update the window before worked out taken (so the next window's samples
        are estimated with the error learnt up to two windows back: the node works an update out beside
        the samples of the window after, and replay does as the node); this window's update started; its
        sensors rejected on most of its samples left out, those left out that agreed again taken back."""
        window, self.window = self.window, None
        assert window is not None and self.origin is not None  # `run` closes only a window it opened
        end = self.origin + (window.index + 1) * self.error.spec.period
        settled = self._settled()
        if settled is not None:
            self._apply(*settled, end)
        update = self._update(window, end)
        self.pending = self.background.submit(update) if self.background is not None else update.run(self.base)
        if window.misfits:
            self.error.rescale(float(np.mean(window.misfits)) / 4.0)
        for sensor, count in window.rejected.items():
            if count > LEFT_OUT_SHARE * window.measuring.get(sensor, count):
                self.left_out.setdefault(sensor, end)
        for sensor, verdicts in window.tried.items():
            if verdicts and sum(verdicts) >= TAKEN_BACK_SHARE * len(verdicts):
                self.left_out.pop(sensor, None)

    def _apply(self, error: ErrorState, tracked: TrackState | None, end: float) -> None:
        """A window's update taken at `end` [s]: the model's error, and the tracked parameters; where their
        values in use moved, the model changes and its error moves by what the model now explains."""
        self.error.apply(error)
        if tracked is not None:
            assert self.tracker is not None  # only a tracker's update has a tracked state
            moved = self.tracker.apply(tracked, end)
            if np.any(moved != 0.0):
                self.error.shift(-tracked.signature @ moved)
                self._use(self.tracker.model(self.base))

    def _update(self, window: _Window, end: float) -> WindowUpdate:
        """The work of a window's update, with the error and the tracker as they are now."""
        estimated = any(state is not None for state in window.states)
        prior = self.error.white(np.array(window.stamps), np.array(window.lengths)) if estimated else None
        return WindowUpdate(window, end, prior, self.error, self.tracker, self.sigma_length)


@dataclass
class WindowUpdate:
    """What a window's update needs, and its work (`run`): a function of these alone and the plant file's model,
    so that it can be worked out at once (replay) or in a process of its own beside the node's samples
    (monitor.updates), and give the same update either way."""

    window: _Window
    end: float                            # [s] where the window ends
    white: Prior | None                   # its samples' weights (`ModelError.white`); None: no sample has a state
    error: ModelError
    tracker: ParameterTracker | None
    sigma_length: float

    def run(self, base: PlantModel) -> tuple[ErrorState, TrackState | None]:
        """The model's error and the tracker after the window, with `base` the plant file's model."""
        window, tracker = self.window, self.tracker
        states = [k for k, state in enumerate(window.states) if state is not None]
        solved = [k for k in states if not window.followed[k]]  # those the model's error is learnt from
        error = self._updated(base if tracker is None else tracker.model(base), solved) if solved else \
            ErrorState(self.error.mean.copy(), self.error.covariance.copy(), self.error.reference)
        if tracker is None:
            return error, None
        return error, tracker.updated(base, self._tracked_samples(states), self.end, self.error.spec.period)

    def _tracked_samples(self, states: list[int]) -> WindowSamples | None:
        """What the tracker learns from in a window: its estimated states and the readings they fused."""
        if not states:
            return None
        assert self.white is not None  # the samples are weighed wherever one has a state (`_update`)
        window = self.window
        return WindowSamples(np.array(window.reported), window.measured, window.conditions,
                             (np.array(states), *_stacked(window, states)), self.white, self.sigma_length)

    def _updated(self, model: PlantModel, solved: list[int]) -> ErrorState:
        window = self.window
        assert self.white is not None  # the solved samples are among those with a state, which are weighed
        lengths = np.array(window.lengths)
        names = sorted({name for row in window.measured for name in row})
        values = {name: np.array([row.get(name, np.nan) for row in window.measured]) for name in names}
        observations = observations_for(model, values, window.conditions)
        loads = np.array([model.load(c) for c in window.conditions])
        problem = Problem.build(model.physical, lengths, self.sigma_length, observations, model.ropes, loads,
                                prior=self.white)
        taut, rotation, position, tensions = _stacked(window, solved)
        rows = Rows(np.array(solved), taut, rotation, position, tensions / problem.scales[solved, None])
        return self.error.updated(problem, rows, lengths, self.end)


def _stacked(window: _Window, rows: list[int]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The states of these samples of the window (each has one) stacked: taut sets, rotations, positions,
    tensions."""
    states = []
    for k in rows:
        state = window.states[k]
        assert state is not None  # the rows are samples with an estimated state
        states.append(state)
    taut, rotation, position, tensions = (np.array([state[j] for state in states]) for j in range(4))
    return taut, rotation, position, tensions


def _loosened(prior: Prior) -> Prior:
    """The prior with the model's lengths weighed FOLLOW times less (a sample the model could not explain)."""
    return Prior(prior.lengths, prior.length_covariance * FOLLOW ** 2, prior.pins, prior.pin_covariance)


def _take(forward: BatchSolution, rows: np.ndarray) -> BatchSolution:
    """The rows of a forward-kinematics batch (repeated rows allowed)."""
    return BatchSolution(forward.plant, forward.lengths[rows], forward.loads[rows], forward.status[rows],
                         forward.taut[rows], forward.tensions[rows], forward.rotation[rows], forward.position[rows],
                         forward.iterations[rows], {k: forward.fallback[int(i)] for k, i in enumerate(rows)
                                                    if int(i) in forward.fallback},
                         forward.method, None if forward.stretch is None else forward.stretch[rows])


def _put(batch: BatchEstimate, i: int, other: BatchEstimate, k: int) -> None:
    """Sample i of `batch` replaced by sample k of `other` (its residuals by channel name)."""
    for name in ("corrected", "loaded", "status", "taut", "tensions", "rotation", "position", "iterations"):
        getattr(batch, name)[i] = getattr(other, name)[k]
    column = {name: j for j, name in enumerate(other.names)}
    batch.residuals[i] = [other.residuals[k, column[name]] if name in column else np.nan for name in batch.names]
    if batch.cost is not None and other.cost is not None:
        batch.cost[i] = other.cost[k]
    batch.fallback.pop(i, None)
    if k in other.fallback:
        batch.fallback[i] = other.fallback[k]
