"""Mahalanobis gate: does a sensor's reading agree with the estimate within reason?

As ROS sensor-fusion nodes do (robot_localization's rejection thresholds), a sensor's
innovation y (measured minus predicted, one entry per channel: four load pins, roll and
pitch, ...) is weighed by its covariance S: d^2 = y^T S^-1 y follows a chi-square
distribution with as many degrees of freedom as channels when the sensor and the model
agree. A reading with d^2 beyond the chi-square quantile of the gate probability is
rejected. With independent channels and normalised innovations (y_k / sigma_k) d^2 is
their sum of squares.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Mapping, Sequence

import numpy as np

DEFAULT_PROBABILITY = 0.999
# chdtri(k, 1 - DEFAULT_PROBABILITY) for k = 1..8 channels, to the bit as scipy gives them (a test holds them to
# it): every fused sample gates its sensors at the default probability, and scipy.special takes 0.2 s to import,
# a twentieth of a 10,000-sample replay.
DEFAULT_THRESHOLDS = (10.827566170662733, 13.815510557964274, 16.26623619623813, 18.46682695290317,
                      20.515005652432873, 22.457744484825323, 24.321886347856854, 26.12448155837614)


@dataclass(frozen=True)
class GateResult:
    """d^2 of one sensor, the threshold it was held against, and the verdict."""

    chi_square: float
    threshold: float
    dof: int

    @property
    def passed(self) -> bool:
        return self.chi_square <= self.threshold


@lru_cache(maxsize=64)  # every sample gates its sensors: the quantile is computed once per dof
def chi_square_threshold(dof: int, probability: float = DEFAULT_PROBABILITY) -> float:
    """The chi-square quantile a consistent sensor of `dof` channels stays below with `probability`."""
    if dof < 1 or not 0.0 < probability < 1.0:
        raise ValueError(f"gate needs dof >= 1 and 0 < probability < 1, got dof={dof}, probability={probability}")
    if probability == DEFAULT_PROBABILITY and dof <= len(DEFAULT_THRESHOLDS):
        return DEFAULT_THRESHOLDS[dof - 1]
    from scipy.special import chdtri  # the inverse survival function; scipy.stats takes 2 s to import

    return float(chdtri(dof, 1.0 - probability))


def mahalanobis_gate(innovation: Sequence[float], covariance: np.ndarray | Sequence[float] | None = None,
                     probability: float = DEFAULT_PROBABILITY) -> GateResult:
    """Gate one sensor: innovation (k,) with its covariance (k, k), or its variances (k,), or None when
    the innovation is already normalised (divided by its sigma). Channels not measured (NaN) are left out."""
    y = np.asarray(innovation, dtype=float).reshape(-1)
    measured = np.isfinite(y)
    if covariance is None:
        s = np.eye(y.size)
    else:
        s = np.asarray(covariance, dtype=float)
        s = np.diag(s) if s.ndim == 1 else s
    y, s = y[measured], s[np.ix_(measured, measured)]
    if not y.size:
        raise ValueError("gate needs at least one measured channel")
    d2 = float(y @ np.linalg.solve(s, y))
    return GateResult(d2, chi_square_threshold(y.size, probability), int(y.size))


def gate_sensors(residuals: Mapping[str, float], sensors: Mapping[str, Sequence[str]],
                 probability: float = DEFAULT_PROBABILITY) -> dict[str, GateResult]:
    """Gate each sensor (a name and its channels: the inclinometer's roll and pitch, one load pin) by
    the normalised residuals of its channels in an estimate ((measured - predicted) / sigma, as
    `Estimate.residuals`); sensors with no channel among them are left out. The estimate has used
    the sensor, so a residual is smaller than the sensor's own error: the gate errs towards trust."""
    out = {}
    for sensor, names in sensors.items():
        values = [residuals[name] for name in names if name in residuals]
        if values:
            out[sensor] = mahalanobis_gate(values, None, probability)
    return out


@dataclass
class HeldGate:
    """A sensor's trust over time: it is left out once its gate has failed for `hold` seconds without
    a pass, and taken back once it has passed for `hold` seconds without a failure, so that one
    outlier neither drops a sensor nor a flapping one keeps coming back."""

    hold: float
    trusted: bool = True
    since: float | None = None   # stamp of the first verdict against the current state, None: none pending

    def update(self, stamp: float, passed: bool) -> bool:
        """The verdict at `stamp`; returns whether the sensor is trusted after it."""
        if passed == self.trusted:
            self.since = None
        elif self.since is None:
            self.since = stamp
        if self.since is not None and stamp - self.since >= self.hold:
            self.trusted, self.since = passed, None
        return self.trusted
