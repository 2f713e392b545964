"""What one update window's samples say of the tracked plant parameters, the model's error taken along.

At the window's estimated states (each sample's pose and tensions, from the readings the
estimate fused), the estimator's problem is set up under the plant model at the
parameters' estimates, with the model's error expected zero and weighed as in the model
error's own update (`Prior` of the window: the sensors' noise and what the error does
within a window). Each parameter's sensitivity is the change of every weighed residual
-- rope lengths, load pins, inclinometer, depth, a user's channel -- per unit of it, by a
forward difference of the model with that one value changed. The model's change is
followed through where its effect acts: the lengths an encoder effect reports, the rope
length a rope law implies at the state's span and tension, what a sensor effect makes a
sensor read (each chained through the residuals' own weighing); an effect that changes
the plant or its load is evaluated through the whole problem, the balance included.

One Gauss-Newton step's normal equations of all the window's samples then follow, each
sample's own state optimised again for any change (its Schur complement,
`fusion.reduced_normal`), for the model's error (16 states) and the parameters jointly;
the error is marginalised with the information of its random walk over one window
(`nuisance`), so that what it does within a window is not put on the parameters.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace
from functools import cached_property
from typing import Any, NamedTuple

import numpy as np

from ..channels import TENSION_CHANNELS
from ..effects import PlantModel
from ..effects.estimate import observations_for
from ..effects.model import overrides
from ..effects.tracked import TrackedParameter
from ..model.conditions import Conditions, StackedConditions
from ..model.estimator import (
    Prior,
    Problem,
    Rows,
    States,
    chain,
    implied_lengths,
    prior_jacobian,
    reduced_normal,
    residuals_and_balance,
)
from ..model.plantfile.error_spec import SIZE

MAX_ROWS = 50      # a window's estimated samples the parameters are learnt from, at most
DERIVATIVE = 1e-3  # the numerical derivative's step, per max(|value|, the parameter's fit step)
WHOLE = ("plant", "load", "refine", "refine_states")  # hooks whose change is followed through the whole problem


class WindowSamples(NamedTuple):
    """An update window as the tracker needs it: the samples' reported lengths (N, 4), the readings the
    estimate fused (a sensor left out as a fault is not among them), their conditions, the estimated states
    of some of them (`rows`: sample index, taut set, rotation, position, tensions [N]), the sensors' weights
    (`white`: its expected errors are not used) and the encoders' noise."""

    reported: np.ndarray
    measured: Sequence[Mapping[str, float]]
    conditions: Sequence[Conditions]
    rows: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]
    white: Prior
    sigma_length: float


class Information(NamedTuple):
    """A window's information (k, k) and gradient (k,) on the parameters at the values they were evaluated
    at, the model's error marginalised; how the error moves per unit of each where the model takes it on
    (16, k)."""

    information: np.ndarray
    gradient: np.ndarray
    signature: np.ndarray


def window_information(base: PlantModel, parameters: Sequence[TrackedParameter], values: np.ndarray,
                       samples: WindowSamples, nuisance: np.ndarray) -> Information:
    """The window's information on `parameters` at `values`, under the plant file's model `base`, the model's
    error marginalised with the information `nuisance` (16, 16) of its spread within a window."""
    window = _Window(_thinned(samples), base.with_tracked(parameters, values, every=True))
    columns, balances = zip(*(window.sensitivity(parameter, value) for parameter, value in zip(parameters, values)))
    errors = window.prior @ chain(window.nominal.lengths[window.rows.sample])
    jacobian = np.concatenate([errors, np.stack(columns, axis=2)], axis=2)
    balance = np.concatenate([np.zeros((len(window.rows.sample), 6, SIZE)), np.stack(balances, axis=2)], axis=2)
    info, grad = reduced_normal(window.nominal, window.rows, jacobian, balance)
    info, grad = info.sum(axis=0), grad.sum(axis=0)
    e, p = slice(0, SIZE), slice(SIZE, None)
    solved = np.linalg.solve(info[e, e] + nuisance, np.column_stack([info[e, p], grad[e]]))
    signature = solved[:, :-1]
    return Information(info[p, p] - info[p, e] @ signature, grad[p] - info[p, e] @ solved[:, -1], signature)


def _thinned(samples: WindowSamples) -> WindowSamples:
    """At most MAX_ROWS of a window's estimated samples, evenly spread: beyond half a window at 10 Hz the
    model error's spread within the window, not the samples' noise, bounds what they say of the parameters."""
    index = samples.rows[0]
    if len(index) <= MAX_ROWS:
        return samples
    # more than MAX_ROWS: the rounded places are more than one apart before rounding, so none repeats (no
    # np.unique, whose first call imports numpy.ma: 10 ms of the window that starts a replay)
    keep = np.linspace(0, len(index) - 1, MAX_ROWS).round().astype(int)
    chosen = index[keep]
    return WindowSamples(samples.reported[chosen], [samples.measured[i] for i in chosen],
                         [samples.conditions[i] for i in chosen],
                         (np.arange(len(chosen)), *(part[keep] for part in samples.rows[1:])),
                         samples.white.take(chosen), samples.sigma_length)


class _Window:
    """The window's problem under the model at the parameters' estimates, and each parameter's sensitivity."""

    def __init__(self, samples: WindowSamples, model: PlantModel):
        self.samples, self.model = samples, model
        white = samples.white
        self.zero = Prior(np.zeros_like(white.lengths), white.length_covariance, np.zeros_like(white.pins),
                          white.pin_covariance)
        names = sorted({name for row in samples.measured for name in row})
        self.values = {name: np.array([row.get(name, np.nan) for row in samples.measured]) for name in names}
        self.nominal = self.problem(model)
        index, taut, rotation, position, tensions = samples.rows
        self.rows = Rows(index, taut, rotation, position, tensions / self.nominal.scales[index, None])
        self.prior = prior_jacobian(self.nominal, self.rows)  # (n, 4 + m, 8): per length and per load-pin reading
        self.states = States(self.nominal.plant, rotation, position, tensions)
        self.conditions = self.stacked.take(index)
        self._cache: dict[str, Any] = {}

    @cached_property
    def stacked(self) -> StackedConditions:
        """The window's samples' conditions, stacked once for every model the derivatives set up."""
        return StackedConditions.of(self.samples.conditions)

    def problem(self, model: PlantModel) -> Problem:
        lengths, loads, _ = model.batch_inputs(self.samples.reported, self.stacked)
        observations = observations_for(model, self.values, self.stacked)
        return Problem.build(model.physical, lengths, self.samples.sigma_length, observations, model.ropes, loads,
                             prior=self.zero)

    def sensitivity(self, parameter: TrackedParameter, value: float) -> tuple[np.ndarray, np.ndarray]:
        """The change of the weighed residuals (n, 4 + m) and of the balance (n, 6) per unit of `parameter`."""
        step = DERIVATIVE * max(abs(value), parameter.step)
        step = step if value + step <= parameter.bounds[1] else -step
        effect = self.model.get(parameter.effect)
        assert effect is not None  # the window's model has every tracked effect on (`with_tracked(..., every=True)`)
        moved = self.model.with_effects([effect.replaced(**{parameter.name: value + step})])
        hooks = type(effect)
        if any(overrides(hooks, hook) for hook in WHOLE):
            residual, balance = residuals_and_balance(self.problem(moved), self.rows)
            nominal = self._once("balance", lambda: residuals_and_balance(self.nominal, self.rows))
            return (residual - nominal[0]) / step, (balance - nominal[1]) / step
        change = np.zeros((len(self.rows.sample), 4 + len(self.nominal.observations)))
        per_length, per_pin = self.prior[:, :, :4], self.prior[:, :, 4:]
        if overrides(hooks, "lengths"):
            lengths = moved.batch_inputs(self.samples.reported, self.stacked)[0]
            change += np.einsum("nkj,nj->nk", per_length, (lengths - self.nominal.lengths)[self.rows.sample])
        if overrides(hooks, "rope"):
            implied = self._once("implied", lambda: implied_lengths(self.nominal, self.rows))
            stretched = implied_lengths(replace(self.nominal, ropes=moved.ropes), self.rows)
            change -= np.einsum("nkj,nj->nk", per_length, stretched - implied)
        if overrides(hooks, "measure") or overrides(hooks, "measure_states"):
            change += self._readings(moved, per_pin)
        return change / step, np.zeros((len(self.rows.sample), 6))

    def _readings(self, moved: PlantModel, per_pin: np.ndarray) -> np.ndarray:
        """The weighed residuals' change where `moved` makes the sensors read otherwise at the same states."""
        nominal = self._once("readings", lambda: self.model.predict_states(self.states, self.conditions))
        readings = moved.predict_states(self.states, self.conditions)
        pins = np.stack([readings[name] - nominal[name] for name in TENSION_CHANNELS], axis=1)
        change = np.einsum("nkj,nj->nk", per_pin, np.nan_to_num(pins))
        measured = np.isfinite(self.nominal.values[self.rows.sample])
        for k, observation in enumerate(self.nominal.observations):
            if observation.name not in TENSION_CHANNELS:
                moved_by = (readings[observation.name] - nominal[observation.name]) / observation.sigma
                change[:, 4 + k] += np.where(measured[:, k], moved_by, 0.0)
        return change

    def _once(self, key: str, compute: Callable[[], Any]) -> Any:
        """What `compute` gives, worked out at the first parameter that needs it."""
        if key not in self._cache:
            self._cache[key] = compute()
        return self._cache[key]

