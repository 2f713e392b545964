"""The model's error, estimated as part of the state: per rope, how far its length and its load pin are off.

A plant file is never exact: ropes stretch more than it says, an encoder's scale or zero is
off, a rope's own weight hangs on its load pin. Rather than believe the model and leave
out the sensors that contradict it, the estimator carries the model's error per rope as
slowly varying states, as fixed-lag smoothers carry sensor biases:

    length correction_i = b0_i + b1_i * l_i        [m]   (model length minus reported length)
    load-pin error_i    = c0_i + c1_i * l_i        [N]   (reading minus the model's prediction)

with l_i the rope's payout, so that errors that grow with the rope (elastic stretch,
thermal growth, an encoder's scale, the rope's own weight) are followed along a lowering.
The eight offsets and eight slopes are random walks whose sizes the plant file sets
(`model_error:`). Load-pin errors are mostly common to the four pins (the ropes' weight):
their spread is a common part and each pin's own, smaller part, so that the pins keep
telling how the load is shared.

Each sample is estimated with the error expected from the samples before its update
window (`prior`): the expected values, their uncertainty grown by the random walk since,
the sensors' noise, and a white part for what the error does faster than an update
(`length_unmodelled`, per metre of payout). At the end of a window of `period` seconds of
sample stamps, the window's samples update the error (`update`): one Gauss-Newton step
of all the window's samples together, each sample's own state re-optimised (its Schur
complement, `fusion.reduced_normal`), with the prior's information. The node and replay
update at the same stamps, so they estimate the same states.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ..plantfile.error_spec import LENGTHS, PINS, SIZE, ModelErrorSpec
from .fusion import Problem, Rows, prior_jacobian, reduced_normal
from .prior import Prior

MAX_STEP = 5.0  # [sigma of the prior] the largest move of the error at one update


def _design(payouts: np.ndarray) -> np.ndarray:
    """(N, 4, 8) the map from (offsets, slopes) to each rope's error at its payout: [I, diag(l)]."""
    out = np.zeros((len(payouts), 4, 8))
    out[:, np.arange(4), np.arange(4)] = 1.0
    out[:, np.arange(4), 4 + np.arange(4)] = payouts
    return out


class ModelError:
    """The estimated error of the model (16 states and their covariance), updated window by window."""

    def __init__(self, spec: ModelErrorSpec, sigma_length: float, sigma_pin: float):
        self.spec = spec
        self.sigma_length, self.sigma_pin = float(sigma_length), float(sigma_pin)
        self.mean = np.zeros(SIZE)
        self.covariance = spec.initial_covariance()
        self.walk = spec.walk()
        self.reference: float | None = None  # [s] the stamp the estimate holds at (None: no sample yet)
        self.updates = 0
        self.fast_scale = 1.0  # how much faster than `length_unmodelled` the error has lately changed in a window

    def window(self, stamp: float, origin: float) -> int:
        """The update window of a sample stamped `stamp` [s], windows counted from `origin` [s]."""
        return math.floor((stamp - origin) / self.spec.period)

    def expected(self, payouts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The expected length corrections and load-pin errors (N, 4) at the rows' payouts (N, 4) [m]."""
        design = _design(payouts)
        return design @ self.mean[LENGTHS], design @ self.mean[PINS]

    def prior(self, stamps: np.ndarray, payouts: np.ndarray) -> Prior:
        """The estimator's prior at samples stamped `stamps` (N,) [s] with payouts (N, 4) [m]: the expected
        errors, their spread grown by the random walk since the estimate, the sensors' noise and the
        error within a window."""
        return self._prior(stamps, payouts, with_state=True)

    def white(self, stamps: np.ndarray, payouts: np.ndarray) -> Prior:
        """The same expected errors with only the spread that is not the error states' own: the sensors'
        noise and the error within a window (the update's weighing of each sample)."""
        return self._prior(stamps, payouts, with_state=False)

    def _prior(self, stamps: np.ndarray, payouts: np.ndarray, with_state: bool) -> Prior:
        payouts = np.asarray(payouts, dtype=float).reshape(-1, 4)
        design = _design(payouts)
        lengths, pins = design @ self.mean[LENGTHS], design @ self.mean[PINS]
        eye = np.eye(4)
        fast = self.fast_scale ** 2 * (self.sigma_length ** 2 + (self.spec.length_unmodelled * payouts) ** 2)
        length_cov = fast[:, :, None] * eye
        pin_cov = np.broadcast_to(self.sigma_pin ** 2 * eye, (len(payouts), 4, 4)).copy()
        if with_state:
            elapsed = np.zeros(len(payouts)) if self.reference is None else \
                np.maximum(np.asarray(stamps, dtype=float) - self.reference, 0.0)
            grown = self.covariance[None] + elapsed[:, None, None] * self.walk[None]
            length_cov = length_cov + design @ grown[:, LENGTHS, LENGTHS] @ np.swapaxes(design, 1, 2)
            pin_cov = pin_cov + design @ grown[:, PINS, PINS] @ np.swapaxes(design, 1, 2)
        return Prior(lengths, length_cov, pins, pin_cov)

    def updated(self, problem: Problem, rows: Rows, payouts: np.ndarray, stamp: float) -> ErrorState:
        """The error after one Gauss-Newton step from a window's estimated samples: `problem` weighed by
        `white` at their stamps, `rows` their estimated states (one row per sample that was estimated),
        `payouts` (N, 4) of the problem's samples, `stamp` [s] where the window ends; the estimate then
        holds at the window's middle, the random walk grows it from there. Reads the error as it is now
        and changes nothing (`apply` takes it), so that the node can work it out beside its samples."""
        mean, covariance, reference = self.mean.copy(), self.covariance.copy(), self.reference
        middle = stamp - 0.5 * self.spec.period
        elapsed = 0.0 if reference is None else max(middle - reference, 0.0)
        predicted = covariance + elapsed * self.walk
        info, gradient = reduced_normal(problem, rows, state_jacobian(problem, rows, payouts))
        information = np.linalg.inv(predicted) + info.sum(axis=0)
        information = 0.5 * (information + information.T)
        step = -np.linalg.solve(information, gradient.sum(axis=0))
        reach = math.sqrt(max(float(step @ np.linalg.solve(predicted, step)), 0.0))
        if reach > MAX_STEP:  # a linearised step this far out of the prior is not to be trusted: go part of the way
            step *= MAX_STEP / reach
        covariance = np.linalg.inv(information)
        return ErrorState(mean + step, 0.5 * (covariance + covariance.T), middle)

    def apply(self, state: ErrorState) -> None:
        self.mean, self.covariance, self.reference = state
        self.updates += 1

    def shift(self, change: np.ndarray) -> None:
        """Move the expected error by `change` (16,): the model changed, and explains that much of it now."""
        self.mean = self.mean + change

    def rescale(self, consistency: float) -> None:
        """Match the part of the error that changes within a window to what a window's samples showed: the
        mean over them of their length corrections' squared Mahalanobis distance from the expected ones, per
        rope (1 where the prior's spread was right). Where the model is coarser than the plant file says
        (rigid ropes that stretch), the samples weigh the lengths less from the next window on; never below
        `length_unmodelled` (covariance matching of the normalised innovations, as adaptive Kalman filters
        tune their process noise)."""
        if math.isfinite(consistency):
            self.fast_scale = math.sqrt(max(1.0, self.fast_scale ** 2 * (0.5 + 0.5 * consistency)))

    def start(self, stamp: float) -> None:
        """The first sample's stamp: the initial spread holds from there."""
        if self.reference is None:
            self.reference = stamp

    def length_errors(self, payouts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Each rope's estimated length error (model minus reported) and its 1-sigma, (N, 4) [m], at payouts
        (N, 4) [m]."""
        return self._errors(payouts, LENGTHS)

    def pin_errors(self, payouts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Each load pin's estimated error (reading minus model) and its 1-sigma, (N, 4) [N], at payouts (N, 4)."""
        return self._errors(payouts, PINS)

    def _errors(self, payouts: np.ndarray, block: slice) -> tuple[np.ndarray, np.ndarray]:
        design = _design(np.asarray(payouts, dtype=float).reshape(-1, 4))
        covariance = design @ self.covariance[block, block] @ np.swapaxes(design, 1, 2)
        return design @ self.mean[block], np.sqrt(np.diagonal(covariance, axis1=1, axis2=2))


def state_jacobian(problem: Problem, rows: Rows, payouts: np.ndarray) -> np.ndarray:
    """(n, 4 + m, 16) derivative of the rows' weighed residuals with respect to the error's states, at the
    rows' states and the payouts (N, 4) [m] of the problem's samples."""
    return prior_jacobian(problem, rows) @ chain(payouts[rows.sample])


def chain(payouts: np.ndarray) -> np.ndarray:
    """(n, 8, 16) how the expected length corrections (4) and load-pin errors (4) at payouts (n, 4) [m] move
    with the error's states."""
    design = _design(payouts)
    out = np.zeros((len(payouts), 8, SIZE))
    out[:, 0:4, LENGTHS] = design
    out[:, 4:8, PINS] = design
    return out


class ErrorState(NamedTuple):
    """The error's estimate after an update: its mean (16,), covariance (16, 16), the stamp it holds at."""

    mean: np.ndarray
    covariance: np.ndarray
    reference: float | None
