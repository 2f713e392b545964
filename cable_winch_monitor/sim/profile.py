"""The commanded payout (lowering and hoisting moves within speed and acceleration limits, and stops),
and the shaft air temperature over time.

Each move is a trapezoidal speed profile (triangular when too short to reach the speed
limit); the payout is then piecewise quadratic in time and evaluated exactly.
"""
from __future__ import annotations

import bisect
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class Phase:
    """Constant acceleration from `start` [s]: payout `length` [m] and speed [m/s] at its start."""

    start: float
    length: float
    speed: float
    accel: float


class Profile:
    """Payout L(t) and its speed for a list of segments ({move, speed, accel} or {stop})."""

    def __init__(self, start_length: float, segments: Sequence[Mapping[str, Any]]):
        self.phases: list[Phase] = []
        t, length, speed = 0.0, start_length, 0.0
        for segment in segments:
            for duration, accel in self._pieces(segment):
                self.phases.append(Phase(t, length, speed, accel))
                length += speed * duration + 0.5 * accel * duration ** 2
                speed += accel * duration
                t += duration
        self.end = t
        self.phases.append(Phase(t, length, 0.0, 0.0))
        self.starts = [p.start for p in self.phases]

    @staticmethod
    def _pieces(segment: Mapping[str, Any]) -> list[tuple[float, float]]:
        """(duration, acceleration) of the phases of one segment."""
        if "stop" in segment:
            pieces = [(float(segment["stop"]), 0.0)]
        else:
            distance, speed, accel = float(segment["move"]), float(segment["speed"]), float(segment["accel"])
            sign, distance = (1.0 if distance >= 0.0 else -1.0), abs(distance)
            if distance >= speed ** 2 / accel:
                ramp, cruise = speed / accel, (distance - speed ** 2 / accel) / speed
            else:
                ramp, cruise = (distance / accel) ** 0.5, 0.0
            pieces = [(ramp, sign * accel), (cruise, 0.0), (ramp, -sign * accel)]
        return [(d, a) for d, a in pieces if d > 0.0]

    def __call__(self, t: float) -> tuple[float, float, float]:
        """Payout [m], payout speed [m/s] and acceleration [m/s^2] at time t [s] (held after the end)."""
        phase = self.phases[max(bisect.bisect_right(self.starts, t) - 1, 0)]
        tau = max(t - phase.start, 0.0)
        return (phase.length + phase.speed * tau + 0.5 * phase.accel * tau ** 2, phase.speed + phase.accel * tau,
                phase.accel if t >= phase.start else 0.0)


def air_temperature(shaft_air: Mapping[str, float], t: float) -> float:
    """The shaft air temperature [deg C] at time t [s]: a slow drift and a ventilation cycle."""
    return (shaft_air["temperature"] + shaft_air["drift"] * t
            + shaft_air["amplitude"] * math.sin(2.0 * math.pi * t / shaft_air["period"]))
