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

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Prior:
    """Per sample (N rows): expected length corrections (N, 4) [m] and their covariance (N, 4, 4) [m^2],
    encoder noise included; expected load-pin errors (N, 4) [N] and their covariance (N, 4, 4) [N^2],
    pin noise included."""

    lengths: np.ndarray
    length_covariance: np.ndarray
    pins: np.ndarray
    pin_covariance: np.ndarray

    def __len__(self) -> int:
        return len(self.lengths)

    def take(self, rows: np.ndarray) -> Prior:
        return Prior(self.lengths[rows], self.length_covariance[rows], self.pins[rows], self.pin_covariance[rows])

    @staticmethod
    def stacked(priors: Sequence[Prior]) -> Prior:
        """The rows of every prior, in order."""
        return Prior(*(np.concatenate([getattr(prior, name) for prior in priors])
                       for name in ("lengths", "length_covariance", "pins", "pin_covariance")))

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
            transposed = np.swapaxes(value, 1, 2)
            if not np.all(np.abs(value - transposed) <= 1e-9 * np.abs(transposed)):  # np.allclose's test, rtol 1e-9
                raise ValueError(f"prior {name} must be symmetric")
            try:
                np.linalg.cholesky(value)  # a Cholesky factor exists for a positive definite matrix only
            except np.linalg.LinAlgError:
                raise ValueError(f"prior {name} must be positive definite") from None


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
