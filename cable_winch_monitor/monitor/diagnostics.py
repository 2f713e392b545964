"""/diagnostics from the monitor's counters, as the field values of a diagnostic_msgs/DiagnosticArray.

Five statuses: the solver (with input and solve rates, and on the node the samples skipped
because a newer one came first), the inputs (per cable stamp, age and rate; rejections),
the collision alarm (with what its clearance is based on), model-versus-measurement
residuals and the sensor fusion (the sensors the estimate used, those it rejected or left
out because they contradict the others, those stuck or silent, the model's estimated error
per rope); a sixth where the plant file tracks parameters (each one's value, sigma, use,
whether it is held, and a WARNING naming a parameter that drifted from the plant file).
Ages and rates are taken against the caller's clock: the node's (under
`use_sim_time` the bag's /clock), or replay's log time: a reading stamped further ahead of
the clock than the stamp window allows is an error like a stale one, the alarm of a sample
older than the staleness limit is no data (STALE) rather than its last level, and a clock
that went back (a bag played again) is said for a while after the node forgot its stamps.
The live node publishes them, and replay writes them once a second of log time, so that a
recording's faults can be read back from its output bag.
"""
from __future__ import annotations

import math
from collections import deque
from collections.abc import Mapping
from functools import lru_cache
from typing import Any, NamedTuple

import numpy as np

from ..channels import ChannelRegistry
from ..model.plantfile.plant import CABLE_NAMES
from ..model.statics.result import SolveStatus
from .alarm import AlarmLevel
from .judged import MonitorOutput
from .pipeline import MonitorPipeline
from .residuals import Residuals
from .tracking import ParameterView

OK, WARN, ERROR, STALE = 0, 1, 2, 3  # diagnostic_msgs/DiagnosticStatus levels
Fields = dict[str, Any]
RATE_WINDOW = 2.0          # [s] of node time over which input rates are counted
REJECTION_HOLD = 10.0      # [s] inputs stay WARN this long after a rejection or a jump of the clock back
RESIDUAL_WINDOW = 200      # latest residuals per channel in the RMS
RESIDUAL_WARN = 3.0        # RMS / noise above which the model vs measurement status warns
ALARM_DIAGNOSTIC = {AlarmLevel.OK: OK, AlarmLevel.WARNING: WARN, AlarmLevel.CRITICAL: ERROR,
                    AlarmLevel.COLLISION: ERROR}
SOLVER_DIAGNOSTIC = {SolveStatus.SOLVED: OK, SolveStatus.SINGLE_CABLE_INDETERMINATE: WARN,
                     SolveStatus.NO_EQUILIBRIUM: WARN, SolveStatus.INVALID_INPUT: ERROR,
                     SolveStatus.SOLVER_FAILED: ERROR}


def _status(name: str, level: int, message: str, values: dict[str, object], hardware_id: str) -> Fields:
    return {"level": level, "name": f"winch_monitor: {name}", "message": message, "hardware_id": hardware_id,
            "values": [{"key": k, "value": str(v)} for k, v in values.items()]}


class DiagnosticsReporter:
    """Keeps what the pipeline does not (arrival times, residual history, recent rejections)
    and turns it with the pipeline's counters into a DiagnosticArray."""

    def __init__(self, hardware_id: str = "winch_monitor"):
        self.hardware_id = hardware_id
        self.arrivals: list[deque[float]] = [deque() for _ in CABLE_NAMES]
        self.residuals: dict[str, tuple[deque[float], float]] = {}
        self.callback_errors = 0
        self.last_callback_error = ""
        self._rejected_seen = 0
        self._last_rejection_time = -np.inf
        self.throughput: deque[tuple[float, int, int]] = deque()  # node time, winch messages, samples solved
        self.clock_jumps = 0
        self.last_clock_jump = ""
        self._last_clock_jump_time = -np.inf

    def note_readings(self, cables: list[int], now: float) -> None:
        """Cables whose reading was just accepted, at node time `now` [s] (NaN: the clock has not started)."""
        if not math.isfinite(now):
            return
        for cable in cables:
            self.arrivals[cable].append(now)
            self._prune(cable, now)

    def note_clock_jump(self, back: float, now: float) -> None:
        """The node clock went `back` seconds back to `now` and the pipeline forgot its stamps: the arrival
        times and rates kept are from that future too."""
        for arrivals in self.arrivals:
            arrivals.clear()
        self.throughput.clear()
        self._last_rejection_time = -np.inf
        self.clock_jumps += 1
        self.last_clock_jump = f"clock went back {back:.3f} s to {now:.3f} s: stamp history reset"
        self._last_clock_jump_time = now

    def note_residuals(self, residuals: Residuals) -> None:
        """A message's residuals, into each channel's latest RESIDUAL_WINDOW (a channel's noise as first seen)."""
        kept = self.residuals
        # measured - predicted, as Residuals.values gives it, without building that tuple (15,000 messages a replay)
        for channel, measured, predicted, noise in zip(residuals.channels, residuals.measured, residuals.predicted,
                                                       residuals.noise):
            entry = kept.get(channel)
            if entry is None:
                entry = kept[channel] = (deque(maxlen=RESIDUAL_WINDOW), float(noise))
            entry[0].append(float(measured - predicted))

    def note_callback_error(self, where: str, error: BaseException) -> None:
        self.callback_errors += 1
        self.last_callback_error = f"{where}: {type(error).__name__}: {error}"

    def rates(self, now: float) -> tuple[float, ...]:
        """Each cable's accepted readings per second over the last RATE_WINDOW of the clock."""
        for cable in range(len(self.arrivals)):
            self._prune(cable, now)
        return tuple(len(arrivals) / RATE_WINDOW for arrivals in self.arrivals)

    def _prune(self, cable: int, now: float) -> None:
        arrivals = self.arrivals[cable]
        while arrivals and arrivals[0] < now - RATE_WINDOW:
            arrivals.popleft()

    def build(self, pipeline: MonitorPipeline, now: float, stamp: tuple[int, int],
              node: Mapping[str, object] | None = None, last: SampleView | None = None,
              winch: WinchView | None = None) -> Fields:
        """All five statuses at time `now` [s], and a sixth where the plant file tracks parameters (from the
        start, so that a reader finds it in every message), stamped `stamp` (sec, nanosec); `node`: the live
        node's own counters (complete samples, skipped, winch messages, lost before the node, waiting); `last`:
        what they say of the latest sample (default: the pipeline's own latest output); `winch`: the winches'
        inputs as they were at `now` (default: the pipeline's now; replay merges them ahead)."""
        last = last if last is not None else sample_view(pipeline.last, pipeline.fusing, pipeline.model.channels)
        winch = winch or winch_view(pipeline, self.rates(now))
        statuses = [self._solver(pipeline, now, node, last, winch), self.inputs(pipeline, now, winch),
                    self._alarm(pipeline, last, now), self._model(), self._status("sensor fusion", *last.fusion)]
        if last.tracking is not None:
            statuses.append(self._status("parameter tracking", *last.tracking))
        elif pipeline.estimator is not None and pipeline.estimator.tracker is not None:
            statuses.append(self._status("parameter tracking", OK, "no estimate yet", {}))
        return {"header": {"stamp": {"sec": stamp[0], "nanosec": stamp[1]}, "frame_id": ""}, "status": statuses}

    def _status(self, name: str, level: int, message: str, values: dict[str, object]) -> Fields:
        return _status(name, level, message, values, self.hardware_id)

    def throughput_rates(self, pipeline: MonitorPipeline, now: float, winch: WinchView) -> tuple[float, float]:
        """Winch messages and samples solved per second over the last RATE_WINDOW of the clock."""
        samples = sum(pipeline.stats.states.values())
        offered = sum(winch.messages.values())
        self.throughput.append((now, offered, samples))
        while len(self.throughput) > 2 and self.throughput[1][0] <= now - RATE_WINDOW:
            self.throughput.popleft()
        start, first, solved = self.throughput[0]
        span = now - start
        if span <= 0.0:
            return float("nan"), float("nan")
        return (offered - first) / span, (samples - solved) / span

    def _solver(self, pipeline: MonitorPipeline, now: float, node: Mapping[str, object] | None,
                last: SampleView, winch: WinchView) -> Fields:
        stats = pipeline.stats
        input_rate, solve_rate = self.throughput_rates(pipeline, now, winch)
        values: dict[str, object] = {"solver": pipeline.solver, "solved": stats.solved, "failed": stats.failures,
                                     "samples": sum(stats.states.values()), **(node or {}),
                                     "input rate [Hz]": f"{input_rate:.1f}", "solve rate [Hz]": f"{solve_rate:.1f}"}
        values.update({f"state {state}": count for state, count in stats.states.items()})
        level, message, latest = last.solver
        return self._status("solver", level, f"{message} ({pipeline.solver})", {**values, **latest})

    def inputs(self, pipeline: MonitorPipeline, now: float, winch: WinchView | None = None) -> Fields:
        """The inputs' status at `now` [s]: each cable's stamp, age and rate, the messages used and rejected
        (the winches' as `winch` saw them, where replay merged them ahead of the other messages)."""
        stats, staleness, ahead = pipeline.stats, pipeline.staleness, pipeline.merger.window.ahead
        winch = winch or winch_view(pipeline, self.rates(now))
        values: dict[str, object] = {}
        missing, stale, early = [], [], []
        for name, reading, rate in zip(CABLE_NAMES, winch.readings, winch.rates):
            values[f"{name} rate [Hz]"] = f"{rate:.1f}"
            if reading is None:
                missing.append(name)
                values[f"{name} last stamp"] = "never"
                continue
            age = now - reading.stamp
            values[f"{name} last stamp"] = f"{reading.stamp:.6f}"
            values[f"{name} age [s]"] = f"{age:.3f}"
            if age > staleness:
                stale.append(f"{name} ({age:.3f} s old)")
            elif age < -ahead:
                early.append(f"{name} ({-age:.3f} s after the clock)")
        # the winch topics only as `winch` saw them: one replay merges later is not counted yet
        messages = {**{t: n for t, n in stats.messages.items() if t not in stats.winch_topics}, **winch.messages}
        used = {**{t: n for t, n in stats.used.items() if t not in stats.winch_topics}, **winch.used}
        rejected = {**{key: n for key, n in stats.rejected.items()
                       if key.split(": ", 1)[0] not in stats.winch_topics}, **winch.rejected}
        for topic, count in sorted(messages.items()):
            values[f"{topic} messages"] = count
            values[f"{topic} used"] = used.get(topic, 0)
        values.update({f"rejected {reason}": count for reason, count in sorted(rejected.items())})
        values.update({f"ignored name {name!r}": count for name, count in sorted(winch.ignored.items())})
        last_rejection = stats.last_rejection if winch is None else winch.last_rejection or stats.last_rejection
        values["last rejection"] = last_rejection
        values["callback errors"] = self.callback_errors
        values["last callback error"] = self.last_callback_error
        values["waiting"] = winch.waiting
        values["clock jumps back"] = self.clock_jumps
        values["last clock jump"] = self.last_clock_jump
        total = sum(rejected.values()) + self.callback_errors
        if total > self._rejected_seen:
            self._rejected_seen, self._last_rejection_time = total, now
        problems = []
        if missing:
            problems.append("missing: " + ", ".join(missing))
        if stale:
            problems.append(f"stale (> {staleness:g} s): " + ", ".join(stale))
        if early:
            problems.append(f"stamped ahead of the clock (> {ahead:g} s): " + ", ".join(early))
        jumped = now - self._last_clock_jump_time <= REJECTION_HOLD
        if jumped:
            problems.append(self.last_clock_jump)
        recent = now - self._last_rejection_time <= REJECTION_HOLD
        if recent:
            problems.append(f"inputs rejected: {last_rejection or self.last_callback_error}")
        level = ERROR if missing or stale or early else WARN if recent or jumped else OK
        return _status("inputs", level, "; ".join(problems) or "all four cables fresh", values, self.hardware_id)

    def _alarm(self, pipeline: MonitorPipeline, last: SampleView, now: float) -> Fields:
        """The last sample's alarm; no data (STALE) once that sample is older than the staleness limit, or
        stamped further ahead of the clock than the stamp window allows: a level is never held without data."""
        values: dict[str, object] = {f"samples {level}": count for level, count in pipeline.stats.levels.items()}
        level, message, latest = last.alarm
        values = {**values, **latest}
        if last.stamp is not None:
            age = now - last.stamp
            values["age [s]"] = f"{age:.3f}"
            if not -pipeline.merger.window.ahead <= age <= pipeline.staleness:
                when = f"{age:.3f} s old" if age > 0.0 else f"stamped {-age:.3f} s ahead of the clock"
                return self._status("collision alarm", STALE, f"no data: the last sample is {when} (it was {message})",
                                    values)
        return self._status("collision alarm", level, message, values)

    def _model(self) -> Fields:
        if not self.residuals:
            return _status("model vs measurement", OK, "no measurements", {}, self.hardware_id)
        values: dict[str, object] = {}
        worst_channel, worst = "", 0.0
        for channel, (history, noise) in sorted(self.residuals.items()):
            rms = float(np.sqrt(np.mean(np.square(np.fromiter(history, float, len(history))))))
            normalised = rms / noise if noise > 0.0 else float("nan")
            values[f"{channel} last"] = f"{history[-1]:.6g}"
            values[f"{channel} rms"] = f"{rms:.6g}"
            values[f"{channel} noise"] = f"{noise:.6g}"
            values[f"{channel} rms/noise"] = f"{normalised:.3g}"
            if normalised > worst:
                worst_channel, worst = channel, normalised
        message = f"worst {worst_channel}: rms {worst:.2f} x noise" if worst_channel else "no noise levels to compare"
        return _status("model vs measurement", WARN if worst > RESIDUAL_WARN else OK, message, values,
                       self.hardware_id)


class SampleView(NamedTuple):
    """What /diagnostics says of the latest sample: the solver's, the alarm's and the sensor fusion's level,
    message and values, as strings (replay's second process sends these back at each second of stamps)."""

    solver: tuple[int, str, dict[str, object]]
    alarm: tuple[int, str, dict[str, object]]
    fusion: tuple[int, str, dict[str, object]]
    stamp: float | None = None  # [s] the sample's
    tracking: tuple[int, str, dict[str, object]] | None = None  # the tracked plant parameters (None: none)


def sample_view(output: MonitorOutput | None, fusing: bool, channels: ChannelRegistry) -> SampleView:
    """The diagnostics of a sample's outputs (None: no sample yet), its sensors those of `channels`."""
    if output is None:
        fusion: tuple[int, str, dict[str, object]] = (
            OK, "no estimate yet" if fusing else "lengths taken as exact (no noise.length in the plant file)", {})
        return SampleView((OK, "no complete sample yet", {}), (OK, "no sample yet", {}), fusion, None)
    solution, alarm = output.solution, output.alarm
    solver: tuple[int, str, dict[str, object]] = (SOLVER_DIAGNOSTIC[solution.status], solution.tension_state,
              {"last stamp": f"{output.stamp:.6f}", "last status": solution.status.value,
               "tension state": solution.tension_state, "iterations": solution.iterations,
               "last message": solution.message})
    values: dict[str, object] = {"level": alarm.level.name}
    if alarm.clearance is not None:
        values["clearance [m]"] = f"{alarm.clearance.value:.4f}"
        values["closest point"] = alarm.clearance.point_name
    values["reason"] = alarm.reason
    if output.basis is not None and output.basis.text:
        values["based on"] = output.basis.text
    values.update({f"sync error {pair} [m]": f"{error:.4f}"
                   for pair, error in zip(alarm.sync_error_pairs, alarm.sync_errors)})
    parameters = output.model.parameters if output.model is not None else None
    return SampleView(solver, (ALARM_DIAGNOSTIC[alarm.level], f"{alarm.level.name}: {alarm.reason}", values),
                      _fusion(output, fusing, channels), output.stamp, None if parameters is None else tracking(parameters))


def _fusion(output: MonitorOutput, fusing: bool, channels: ChannelRegistry) -> tuple[int, str, dict[str, object]]:
    """The sample's estimate: the sensors used, those left out (contradicting the others, stuck at a
    constant, silent) and why; the model's estimated error per rope."""
    if not fusing:
        return OK, "lengths taken as exact (no noise.length in the plant file)", {}
    estimate, view = output.estimate, output.model
    faults = dict(view.faults) if view is not None else {}
    values: dict[str, object] = {f"{sensor} left out": why for sensor, why in sorted(faults.items())}
    if estimate is None or view is None or not estimate.fused:
        message = "no estimate yet" if estimate is None else f"lengths only: {estimate.solution.tension_state}"
    else:
        used = channels.sensors_used(estimate.used)
        values["sensors used"] = ", ".join(used)
        for name, error, sigma, pin, pin_sigma in zip(CABLE_NAMES, view.length_error, view.length_sigma,
                                                       view.pin_error, view.pin_sigma):
            values[f"{name} model length error [m]"] = f"{error:+.4f} +- {sigma:.4f}"
            values[f"{name} load-pin error [N]"] = f"{pin:+.0f} +- {pin_sigma:.0f}"
        largest = int(np.argmax(np.abs(view.length_error)))
        message = f"fused {len(used)} sensors; the model's lengths are off by up to " \
                  f"{view.length_error[largest]:+.3f} m ({CABLE_NAMES[largest]})"
    if faults:
        message = "left out: " + "; ".join(f"{sensor} ({why})" for sensor, why in sorted(faults.items())) + \
            "; " + message
    return (WARN if faults else OK), message, values


@lru_cache(maxsize=4)
def tracking(view: ParameterView) -> tuple[int, str, dict[str, object]]:
    """The tracked parameters: a WARNING naming each that drifted (value, sigma, since when), else how many are
    in use and which are held; each one's value, sigma, value in use and state. Worked out once for a view (one
    from a window's update to the next), which every second's diagnostics of the window then share."""
    values: dict[str, object] = {}
    drifts, held = [], []
    for k, name in enumerate(view.names):
        unit = "" if view.units[k] in ("", "-") else f" {view.units[k]}"
        state = "in use" if view.in_use[k] else "tracking (sigma above the bound: the file's value in use)"
        if not view.excited[k]:
            held.append(name)
            state += "; held: the motion did not excite it"
        values[name] = f"{view.values[k]:.6g} +- {view.sigmas[k]:.2g}{unit}"
        values[f"{name} in use"] = f"{view.used[k]:.6g}{unit} (file {view.files[k]:.6g})"
        values[f"{name} state"] = state
        if view.drifting[k]:
            drifts.append(f"{name} = {view.values[k]:.6g} +- {view.sigmas[k]:.2g}{unit} (file {view.files[k]:.6g}, "
                          f"tolerance {view.tolerances[k]:.3g}) since {view.since[k]:.1f} s")
    values["updated at [s]"] = f"{view.stamp:.3f}"
    if drifts:
        return WARN, "drift: " + "; ".join(drifts), values
    message = f"{int(np.sum(view.in_use))} of {len(view.names)} tracked values in use, none drifted"
    return OK, message + (f"; held: {', '.join(held)}" if held else ""), values


class WinchView(NamedTuple):
    """The winches' inputs as merging left them at a moment: each cable's latest reading, the winch topics'
    counts, rejections and ignored names."""

    readings: tuple[Any, ...]
    rates: tuple[float, ...]          # each cable's accepted readings per second [Hz]
    messages: dict[str, int]
    used: dict[str, int]
    rejected: dict[str, int]
    ignored: dict[str, int]
    last_rejection: str
    waiting: str


def winch_view(pipeline: MonitorPipeline, rates: tuple[float, ...]) -> WinchView:
    """The winches' inputs of `pipeline` now (a copy), with each cable's reading rate [Hz]."""
    stats, topics = pipeline.stats, pipeline.stats.winch_topics
    return WinchView(tuple(pipeline.merger.readings), rates, {t: stats.messages[t] for t in topics},
                     {t: stats.used[t] for t in topics},
                     {key: n for key, n in stats.rejected.items() if key.split(": ", 1)[0] in topics},
                     dict(stats.ignored_names), stats.last_winch_rejection, stats.waiting)
