"""Per-winch synchronisation errors: a random drift of each winch plus scripted lag events.

The drift is an Ornstein-Uhlenbeck process (stationary standard deviation sigma,
correlation time tau), sampled exactly at whatever times are asked for, in order. A lag
event makes one winch pay out `lag` metres less than commanded: it ramps in over
`duration` from `start`, and ramps out again after `hold` seconds if `hold` is given.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np


def _ramp(t: float, event: Mapping[str, Any]) -> tuple[float, float]:
    """Fraction of an event's lag in effect at t, and its rate [1/s]."""
    start, duration = event["start"], event["duration"]
    ends = [start] if event.get("hold") is None else [start, start + duration + event["hold"]]
    fraction, rate = 0.0, 0.0
    for sign, begin in zip((1.0, -1.0), ends):
        if duration <= 0.0:
            fraction += sign * float(t >= begin)
        elif t > begin:
            fraction += sign * min((t - begin) / duration, 1.0)
            rate += sign / duration if t < begin + duration else 0.0
    return fraction, rate


class SyncErrors:
    """Each winch's payout error [m] (positive: paid out more than commanded)."""

    def __init__(self, sigma: float, tau: float, events: Sequence[Mapping[str, Any]], rng: np.random.Generator):
        self.sigma, self.tau, self.events, self.rng = sigma, tau, list(events), rng
        self.drift = rng.normal(0.0, sigma, 4) if sigma > 0.0 else np.zeros(4)
        self.t = 0.0

    def _advance(self, t: float) -> None:
        dt = t - self.t
        if dt < 0.0:
            raise ValueError(f"synchronisation errors are sampled in time order: {t} after {self.t}")
        if self.sigma > 0.0 and dt > 0.0:
            decay = np.exp(-dt / self.tau)
            self.drift = self.drift * decay + self.sigma * np.sqrt(1.0 - decay ** 2) * self.rng.normal(size=4)
        self.t = t

    def __call__(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Errors [m] and their scripted rates [m/s] at time t (t never decreasing between calls)."""
        self._advance(t)
        errors, rates = self.drift.copy(), np.zeros(4)
        for event in self.events:
            fraction, rate = _ramp(t, event)
            errors[event["winch"] - 1] -= event["lag"] * fraction
            rates[event["winch"] - 1] -= event["lag"] * rate
        return errors, rates
