"""What the model is expected to be off by at each sample: the prior of the estimator's model-error terms.

The estimator explains a sample's measurements by an equilibrium state of the plant
model, and the model is never exact. Two terms carry its error, per rope:

- lengths: the model's rope length minus the length the encoder reports [m] -- elastic
  stretch the plant file does not know, an encoder's scale or zero, thermal growth --
  plus the encoder's own noise;
- pins: what a load pin reads beyond the model's prediction [N] -- the rope's own weight
  above the platform, a pin's zero or gain -- plus the pin's own noise.

A `Prior` gives, per sample, the expected value of each (4,) and its covariance (4, 4):
the estimator then weighs the lengths and load pins by these instead of by the sensors'
noise alone, so a model that is centimetres off is corrected rather than believed, and a
sensor is not judged against an exact model. `model_error.ModelError` keeps the expected
values up to date from the samples it has seen.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

SIZE = 16  # the model-error states: length offsets b0 (4), slopes b1 (4), pin offsets c0 (4), slopes c1 (4)
LENGTHS, PINS = slice(0, 8), slice(8, 16)


@dataclass(frozen=True)
class Prior:
    """Per sample (N rows): expected length corrections (N, 4) [m] and their covariance (N, 4, 4) [m^2],
    encoder noise included; expected load-pin errors (N, 4) [N] and their covariance (N, 4, 4) [N^2],
    pin noise included."""

    lengths: np.ndarray
    length_covariance: np.ndarray
    pins: np.ndarray
    pin_covariance: np.ndarray

    @classmethod
    def noise_only(cls, count: int, sigma_length: float, sigma_pin: float) -> Prior:
        """A model taken as exact: corrections expected zero with the sensors' own noise."""
        eye = np.broadcast_to(np.eye(4), (count, 4, 4))
        return cls(np.zeros((count, 4)), eye * sigma_length ** 2, np.zeros((count, 4)), eye * sigma_pin ** 2)

    def __len__(self) -> int:
        return len(self.lengths)

    def take(self, rows: np.ndarray) -> Prior:
        return Prior(self.lengths[rows], self.length_covariance[rows], self.pins[rows], self.pin_covariance[rows])

    def check(self, count: int) -> None:
        """ValueError naming what is wrong: shapes for `count` samples, finite values, covariances that are
        symmetric positive definite."""
        shapes = {"lengths": (count, 4), "length_covariance": (count, 4, 4), "pins": (count, 4),
                  "pin_covariance": (count, 4, 4)}
        for name, shape in shapes.items():
            value = getattr(self, name)
            if np.shape(value) != shape:
                raise ValueError(f"prior {name} must have shape {shape}, got {np.shape(value)}")
            if not np.all(np.isfinite(value)):
                raise ValueError(f"prior {name} must be finite")
        for name in ("length_covariance", "pin_covariance"):
            value = getattr(self, name)
            if not np.allclose(value, np.swapaxes(value, 1, 2), rtol=1e-9, atol=0.0):
                raise ValueError(f"prior {name} must be symmetric")
            if np.any(np.linalg.eigvalsh(value)[:, 0] <= 0.0):
                raise ValueError(f"prior {name} must be positive definite")


def whitening(covariance: np.ndarray, measured: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """W (N, 4, 4) with W C W^T = I for each covariance C (N, 4, 4), and the marginal sigmas sqrt(diag C);
    rows and columns not `measured` (N, 4 bool) are first decoupled (identity), so that W leaves them
    out of the measured ones' residuals."""
    covariance = np.array(covariance, dtype=float)
    if measured is not None:
        both = measured[:, :, None] & measured[:, None, :]
        covariance = np.where(both, covariance, np.eye(4))
    factor = np.linalg.cholesky(covariance)
    white = np.linalg.solve(factor, np.broadcast_to(np.eye(4), factor.shape))
    return white, np.sqrt(np.diagonal(covariance, axis1=1, axis2=2))


class ModelErrorConfigError(ValueError):
    """The plant file's `model_error:` section is wrong; the message names the key."""


@dataclass(frozen=True)
class ModelErrorSpec:
    """How far and how fast the model may be off (plant file `model_error:`, every key optional)."""

    period: float = 10.0                 # [s] of sample stamps between updates of the estimated error
    length_offset: float = 0.1           # [m] 1-sigma of a rope's length error at the start
    length_strain: float = 1e-3          # [-] 1-sigma of its length error per metre of payout at the start
    length_offset_walk: float = 3e-4     # [m/sqrt(s)] random walk of the length offset
    length_strain_walk: float = 2e-6     # [1/sqrt(s)] random walk of the length error per metre
    length_unmodelled: float = 3e-5      # [-] per metre of payout, each sample: what changes within a window
    pin_common: float = 3e4              # [N] 1-sigma of the error common to the load pins at the start
    pin_common_per_metre: float = 100.0  # [N/m] 1-sigma of the common error per metre of payout at the start
    pin_own: float = 500.0               # [N] 1-sigma of each pin's own error at the start
    pin_common_walk: float = 100.0       # [N/sqrt(s)] random walk of the common error
    pin_own_walk: float = 5.0            # [N/sqrt(s)] random walk of each pin's own error

    @classmethod
    def from_mapping(cls, section: Mapping[str, Any] | None) -> ModelErrorSpec:
        """The spec of a plant file's `model_error:` mapping; unknown keys and values that are not positive,
        finite numbers are refused, naming the key."""
        if section is None:
            return cls()
        if not isinstance(section, Mapping):
            raise ModelErrorConfigError("key 'plant.model_error' must be a mapping")
        known = [f.name for f in fields(cls)]
        values = {}
        for key, value in section.items():
            if key not in known:
                raise ModelErrorConfigError(f"unknown key 'plant.model_error.{key}' (known: {', '.join(known)})")
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) \
                    or value <= 0.0:
                raise ModelErrorConfigError(f"key 'plant.model_error.{key}' must be a positive number, got {value!r}")
            values[key] = float(value)
        return cls(**values)

    def initial_covariance(self) -> np.ndarray:
        """(16, 16) the error's spread before any sample."""
        return _covariance(self.length_offset, self.length_strain, self.pin_common, self.pin_own,
                           self.pin_common_per_metre, 0.01 * self.pin_common_per_metre)

    def walk(self) -> np.ndarray:
        """(16, 16) the random walk's covariance per second."""
        return _covariance(self.length_offset_walk, self.length_strain_walk, self.pin_common_walk, self.pin_own_walk,
                           0.0, 1e-3 * self.pin_common_per_metre)


def _covariance(length_offset: float, length_strain: float, pin_common: float, pin_own: float,
                pin_slope_common: float, pin_slope_own: float) -> np.ndarray:
    """(16, 16) over the error's terms (length offsets, length strains, pin offsets, pin slopes; four each): the
    length terms each rope's own, the pin terms a part common to the four pins and each pin's own [1-sigma each]."""
    ones, eye = np.ones((4, 4)), np.eye(4)
    out = np.zeros((SIZE, SIZE))
    out[0:4, 0:4] = eye * length_offset ** 2
    out[4:8, 4:8] = eye * length_strain ** 2
    out[8:12, 8:12] = ones * pin_common ** 2 + eye * pin_own ** 2
    out[12:16, 12:16] = ones * pin_slope_common ** 2 + eye * pin_slope_own ** 2
    return out
