"""The plant file's `model_error:` section: how far and how fast the model may be off, as the covariances of the
estimator's model-error states (model.estimator.model_error)."""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

SIZE = 16  # the model-error states: length offsets b0 (4), slopes b1 (4), pin offsets c0 (4), slopes c1 (4)
LENGTHS, PINS = slice(0, 8), slice(8, 16)


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
