"""/diagnostics from the monitor's counters and the node clock.

Five statuses: the solver (with input and solve rates and the samples skipped because a
newer one came first), the inputs (per cable stamp, age and rate; rejections), the
collision alarm, model-versus-measurement residuals and the sensor fusion (the sensors
the estimate used, how far it moved the lengths, the sensors its gates left out). Ages and rates are taken
against the node clock, so under `use_sim_time` they follow the bag's /clock: a reading stamped further
ahead of the clock than the stamp window allows is an error like a stale one, the alarm of a sample
older than the staleness limit is no data (STALE) rather than its last level, and a clock that went
back (a bag played again) is said for a while after the node forgot its stamps.
"""
from __future__ import annotations

from collections import deque

import numpy as np
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from std_msgs.msg import Header

from ..model.plant import CABLE_NAMES
from ..model.result import SolveStatus
from ..monitor.alarm import AlarmLevel
from ..monitor.latest import LatestSamplePipeline
from ..monitor.residuals import Residuals
from ..monitor.sensors import sensors_used

OK, WARN, ERROR, STALE = DiagnosticStatus.OK, DiagnosticStatus.WARN, DiagnosticStatus.ERROR, DiagnosticStatus.STALE
RATE_WINDOW = 2.0          # [s] of node time over which input rates are counted
REJECTION_HOLD = 10.0      # [s] inputs stay WARN this long after a rejection or a jump of the clock back
RESIDUAL_WINDOW = 200      # latest residuals per channel in the RMS
RESIDUAL_WARN = 3.0        # RMS / noise above which the model vs measurement status warns
ALARM_DIAGNOSTIC = {AlarmLevel.OK: OK, AlarmLevel.WARNING: WARN, AlarmLevel.CRITICAL: ERROR,
                    AlarmLevel.COLLISION: ERROR}
SOLVER_DIAGNOSTIC = {SolveStatus.SOLVED: OK, SolveStatus.SINGLE_CABLE_INDETERMINATE: WARN,
                     SolveStatus.NO_EQUILIBRIUM: WARN, SolveStatus.INVALID_INPUT: ERROR,
                     SolveStatus.SOLVER_FAILED: ERROR}


def _status(name: str, level: bytes, message: str, values: dict[str, object], hardware_id: str) -> DiagnosticStatus:
    return DiagnosticStatus(level=level, name=f"winch_monitor: {name}", message=message, hardware_id=hardware_id,
                            values=[KeyValue(key=k, value=str(v)) for k, v in values.items()])


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
        if not np.isfinite(now):
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
        for channel, value, noise in zip(residuals.channels, residuals.values, residuals.noise):
            history = self.residuals.setdefault(channel, (deque(maxlen=RESIDUAL_WINDOW), float(noise)))[0]
            history.append(float(value))

    def note_callback_error(self, where: str, error: BaseException) -> None:
        self.callback_errors += 1
        self.last_callback_error = f"{where}: {type(error).__name__}: {error}"

    def rate(self, cable: int, now: float) -> float:
        """Accepted readings per second over the last RATE_WINDOW of node time."""
        self._prune(cable, now)
        return len(self.arrivals[cable]) / RATE_WINDOW

    def _prune(self, cable: int, now: float) -> None:
        arrivals = self.arrivals[cable]
        while arrivals and arrivals[0] < now - RATE_WINDOW:
            arrivals.popleft()

    def build(self, pipeline: LatestSamplePipeline, now: float, stamp: Time) -> DiagnosticArray:
        """All five statuses at node time `now` [s], stamped `stamp`."""
        statuses = [self._solver(pipeline, now), self._inputs(pipeline, now), self._alarm(pipeline, now),
                    self._model(), self._fusion(pipeline)]
        return DiagnosticArray(header=Header(stamp=stamp), status=statuses)

    def throughput_rates(self, pipeline: LatestSamplePipeline, now: float) -> tuple[float, float]:
        """Winch messages and samples solved per second over the last RATE_WINDOW of node time."""
        samples = sum(pipeline.stats.states.values())
        self.throughput.append((now, pipeline.offered, samples))
        while len(self.throughput) > 2 and self.throughput[1][0] <= now - RATE_WINDOW:
            self.throughput.popleft()
        start, offered, solved = self.throughput[0]
        span = now - start
        if span <= 0.0:
            return float("nan"), float("nan")
        return (pipeline.offered - offered) / span, (samples - solved) / span

    def _solver(self, pipeline: LatestSamplePipeline, now: float) -> DiagnosticStatus:
        stats, last = pipeline.stats, pipeline.last
        input_rate, solve_rate = self.throughput_rates(pipeline, now)
        values: dict[str, object] = {"solver": pipeline.solver, "solved": stats.solved, "failed": stats.failures,
                                     "samples": sum(stats.states.values()), "complete samples": pipeline.complete,
                                     "skipped (a newer sample came first)": pipeline.skipped,
                                     "winch messages": pipeline.offered,
                                     "winch messages lost before the node": pipeline.unseen,
                                     "waiting": pipeline.waiting, "input rate [Hz]": f"{input_rate:.1f}",
                                     "solve rate [Hz]": f"{solve_rate:.1f}"}
        values.update({f"state {state}": count for state, count in stats.states.items()})
        if last is None:
            return _status("solver", OK, "no complete sample yet", values, self.hardware_id)
        solution = last.solution
        values.update({"last stamp": f"{last.stamp:.6f}", "last status": solution.status.value,
                       "tension state": solution.tension_state, "iterations": solution.iterations,
                       "last message": solution.message})
        return _status("solver", SOLVER_DIAGNOSTIC[solution.status], f"{solution.tension_state} ({pipeline.solver})",
                       values, self.hardware_id)

    def _inputs(self, pipeline: LatestSamplePipeline, now: float) -> DiagnosticStatus:
        stats, staleness, ahead = pipeline.stats, pipeline.staleness, pipeline.merger.window.ahead
        values: dict[str, object] = {}
        missing, stale, early = [], [], []
        for i, (name, reading) in enumerate(zip(CABLE_NAMES, pipeline.merger.readings)):
            values[f"{name} rate [Hz]"] = f"{self.rate(i, now):.1f}"
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
        for topic, count in sorted(stats.messages.items()):
            values[f"{topic} messages"] = count
            values[f"{topic} used"] = stats.used[topic]
        values.update({f"rejected {reason}": count for reason, count in sorted(stats.rejected.items())})
        values.update({f"ignored name {name!r}": count for name, count in sorted(stats.ignored_names.items())})
        values["last rejection"] = stats.last_rejection
        values["callback errors"] = self.callback_errors
        values["last callback error"] = self.last_callback_error
        values["waiting"] = stats.waiting
        values["clock jumps back"] = self.clock_jumps
        values["last clock jump"] = self.last_clock_jump
        rejected = sum(stats.rejected.values()) + self.callback_errors
        if rejected > self._rejected_seen:
            self._rejected_seen, self._last_rejection_time = rejected, now
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
            problems.append(f"inputs rejected: {stats.last_rejection or self.last_callback_error}")
        level = ERROR if missing or stale or early else WARN if recent or jumped else OK
        return _status("inputs", level, "; ".join(problems) or "all four cables fresh", values, self.hardware_id)

    def _alarm(self, pipeline: LatestSamplePipeline, now: float) -> DiagnosticStatus:
        """The last sample's alarm; no data (STALE) once that sample is older than the staleness limit, or
        stamped further ahead of the clock than the stamp window allows: a level is never held without data."""
        values: dict[str, object] = {f"samples {level}": count for level, count in pipeline.stats.levels.items()}
        last = pipeline.last
        if last is None:
            return _status("collision alarm", OK, "no sample yet", values, self.hardware_id)
        alarm, age = last.alarm, now - last.stamp
        values["level"] = alarm.level.name
        values["age [s]"] = f"{age:.3f}"
        if alarm.clearance is not None:
            values["clearance [m]"] = f"{alarm.clearance.value:.4f}"
            values["closest point"] = alarm.clearance.point_name
        values["reason"] = alarm.reason
        values.update({f"sync error {pair} [m]": f"{error:.4f}"
                       for pair, error in zip(alarm.sync_error_pairs, alarm.sync_errors)})
        if not -pipeline.merger.window.ahead <= age <= pipeline.staleness:
            when = f"{age:.3f} s old" if age > 0.0 else f"stamped {-age:.3f} s ahead of the clock"
            return _status("collision alarm", STALE, f"no data: the last sample is {when} (it was {alarm.level.name}: "
                           f"{alarm.reason})", values, self.hardware_id)
        return _status("collision alarm", ALARM_DIAGNOSTIC[alarm.level], f"{alarm.level.name}: {alarm.reason}", values,
                       self.hardware_id)

    def _fusion(self, pipeline: LatestSamplePipeline) -> DiagnosticStatus:
        """The last sample's estimate: sensors used and length corrections [sigma]; sensors refused by their gate."""
        if not pipeline.fusing:
            return _status("sensor fusion", OK, "lengths taken as exact (no noise.length in the plant file)", {},
                           self.hardware_id)
        gates = pipeline.gates
        refused = gates.refused
        values: dict[str, object] = {"gate hold [s]": gates.hold, "refused": ", ".join(refused)}
        values.update({f"{sensor} gate chi-square": f"{d2:.3g}"
                       for sensor, d2 in sorted(gates.last_chi_square.items())})
        last = pipeline.last
        estimate = last.estimate if last is not None else None
        if estimate is None or not estimate.fused:
            message = "no estimate yet" if estimate is None else f"lengths only: {estimate.solution.tension_state}"
        else:
            used = sensors_used(estimate)
            values["sensors used"] = ", ".join(used)
            values.update({f"{name} length correction [sigma]": f"{c:.3g}"
                           for name, c in zip(CABLE_NAMES, estimate.corrections_sigma)})
            message = f"fused {len(used)} sensors, largest length correction " \
                      f"{np.abs(estimate.corrections_sigma).max():.2f} sigma"
        if refused:
            message = "left out (gate): " + ", ".join(refused) + "; " + message
        return _status("sensor fusion", WARN if refused else OK, message, values, self.hardware_id)

    def _model(self) -> DiagnosticStatus:
        if not self.residuals:
            return _status("model vs measurement", OK, "no measurements", {}, self.hardware_id)
        values: dict[str, object] = {}
        worst_channel, worst = "", 0.0
        for channel, (history, noise) in sorted(self.residuals.items()):
            rms = float(np.sqrt(np.mean(np.square(history))))
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
