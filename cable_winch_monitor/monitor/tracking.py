"""Plant parameters tracked live: estimated from the windows that keep the model's error, used once known,
and watched for drift.

The estimator keeps the model's error per rope (model.model_error): how far the plant
file's lengths and load pins are off, as slowly varying states. The parameters the plant
file lists under `plant.track` (effects.tracked) are what explains that error. At the end
of each update window, from the window's estimated states and the readings it fused (a
sensor left out as a fault is not among them), one Gauss-Newton step estimates the
parameters and the model's error jointly: the sensitivities of every residual (lengths,
load pins, inclinometer, depth) to each parameter, numerically, through the model at the
parameters' estimates; each sample's own state optimised again (its Schur complement,
`fusion.reduced_normal`); the model's error taken as zero with the spread of its random
walk over one window, so that what persists from window to window is the parameters' and
what comes and goes is the error's. The parameters are random walks (`track_drift`), so
their estimate rests on the last hour or so.

- A parameter the window does not excite (information below one over its tolerance
  squared: friction at rest, the offset of a slack rope) is held: its estimate is not
  moved, and the output says so.
- A window whose data place a parameter STEP sigma from its prediction (an encoder that
  slipped on its drum) restarts that parameter from its initial spread, so that the step
  is taken at once rather than over the random walk's hours.
- A tracked value replaces the file's in the model only while its 1-sigma is below the
  bound (`track_sigma` of its tolerance), and moves by at most `track_rate` of its
  tolerance per minute: a sensor fault cannot pull the model away in seconds. When the
  model changes, the model's error is moved by what the change now explains.
- A parameter whose estimate is more than its tolerance plus two sigma from the file's
  value is drifting (a WARNING in /diagnostics), since the window where it last left the
  file's value by more than two sigma.

Everything here is a function of the windows in order, so the node and replay track the
same values; the tracker pickles (numbers only), the model is given back by its owner.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from ..effects import PlantModel
from ..effects.plantfile import write_plant
from ..effects.tracked import TrackedParameter, tracked_parameters
from ..model.plantfile.error_spec import SIZE
from ..model.plantfile.track import TrackSpec
from .seconds import FirstOfEachSecond
from .sensitivity import WindowSamples, window_information

INITIAL = 10.0     # [tolerances] 1-sigma of a tracked parameter before the first window, and after a step
STEP = 6.0         # [sigma] a window's data this far from the prediction: the parameter stepped
MAX_MOVE = 5.0     # [sigma of the prediction] the largest move of the estimate at one window
DRIFT_SIGMAS = 2.0  # a drift is a change beyond the tolerance by this many sigma


@dataclass(frozen=True, eq=False)
class ParameterView:
    """The tracked parameters as the outputs say them at a sample (arrays in the order of `names`); one object
    from a window's update to the next, equal to itself alone (what is said of it is worked out once)."""

    names: tuple[str, ...]       # `effect.param`
    units: tuple[str, ...]
    values: np.ndarray           # the tracked estimate
    sigmas: np.ndarray           # its 1-sigma
    in_use: np.ndarray           # the model follows it (its sigma is below the bound)
    used: np.ndarray             # the value the model uses now (the file's until in use; then at the rate limit)
    files: np.ndarray            # the plant file's value (or the default of an effect the file has off)
    tolerances: np.ndarray       # the change that is a drift
    excited: np.ndarray          # the last window moved it (else it is held)
    drifting: np.ndarray         # beyond its tolerance from the file's value
    since: np.ndarray            # [s] since when it has left the file's value (NaN: it has not)
    stamp: float                 # [s] the end of the last window it was updated from (NaN: none yet)


class TrackState(NamedTuple):
    """The tracker after a window: the estimate (k,), its covariance (k, k), the stamp it holds at, which
    parameters the window excited, since when each has left the file's value, and how the model's error
    (16) moves per unit of each parameter (16, k) where the model takes it on."""

    mean: np.ndarray
    covariance: np.ndarray
    reference: float
    excited: np.ndarray
    since: np.ndarray
    signature: np.ndarray


class ParameterTracker:
    """The tracked parameters of one stream of samples: estimate, covariance, values in use, drift."""

    def __init__(self, parameters: Sequence[TrackedParameter], spec: TrackSpec, walk: np.ndarray, period: float):
        """`walk`: the model error's random walk per second (16, 16), `period`: the update window [s]."""
        self.parameters = tuple(parameters)
        self.start = np.array([p.start for p in self.parameters])
        self.tolerance = np.array([p.tolerance for p in self.parameters])
        self.low = np.array([p.bounds[0] for p in self.parameters])
        self.high = np.array([p.bounds[1] for p in self.parameters])
        self.bound = spec.sigma * self.tolerance       # the 1-sigma below which a value is used
        self.rate = spec.rate * self.tolerance / 60.0  # [unit/s] how fast the value in use may move
        self.walk = np.diag((spec.drift * self.tolerance) ** 2 / 3600.0)
        self.nuisance = np.linalg.inv(walk * period)   # the model error's information within a window
        self.mean = self.start.copy()
        self.covariance = np.diag((INITIAL * self.tolerance) ** 2)
        self.used = self.start.copy()
        self.reference = math.nan  # [s] where the estimate holds (the middle of its last window)
        self.updated_at = math.nan  # [s] the end of the last window applied
        self.excited = np.zeros(len(self.parameters), bool)
        self.since = np.full(len(self.parameters), math.nan)
        self.first_of_second = FirstOfEachSecond()  # where the view is published
        self._view: ParameterView | None = None

    @classmethod
    def of(cls, model: PlantModel) -> ParameterTracker | None:
        """The tracker of a plant model's file (None: it tracks nothing)."""
        plant = model.plant
        if not plant.track.enabled:
            return None
        return cls(tracked_parameters(plant, model.registry), plant.track, plant.model_error.walk(),
                   plant.model_error.period)

    @property
    def in_use(self) -> np.ndarray:
        return np.sqrt(np.diag(self.covariance)) <= self.bound

    def model(self, base: PlantModel) -> PlantModel:
        """The plant file's model `base` with the values in use."""
        return base.with_tracked(self.parameters, self.used)

    def write(self, base: PlantModel, path: str | Path, by: str) -> str:
        """Write the plant file of `base` with the values in use to `path` (its folder must exist; ValueError
        says why not); what was written, in one line."""
        path = Path(path)
        if not str(path) or path.is_dir() or not path.parent.is_dir():
            raise ValueError(f"cannot write a plant file to '{path}': give a file in an existing folder")
        write_plant(self.model(base), path, by)
        view = self.view()
        return f"wrote {path}: " + ", ".join(
            f"{name} = {used:.6g}" + ("" if use else " (the file's: not known well enough yet)")
            for name, used, use in zip(view.names, view.used, view.in_use))

    # -- a window's update (worked out beside the next window's samples, as the model error's) --------------
    def updated(self, base: PlantModel, window: WindowSamples | None, end: float, period: float) -> TrackState:
        """The tracker after the window ending at `end` [s] (None: no sample of it was estimated): reads the
        tracker as it is now and changes nothing (`apply` takes it)."""
        middle = end - 0.5 * period
        elapsed = 0.0 if math.isnan(self.reference) else max(middle - self.reference, 0.0)
        predicted = self.covariance + elapsed * self.walk
        k = len(self.parameters)
        if window is None or not len(window.rows[0]):
            return TrackState(self.mean.copy(), predicted, middle, np.zeros(k, bool), self.since.copy(),
                              np.zeros((SIZE, k)))
        information, gradient, signature = window_information(base, self.parameters, self.mean, window,
                                                              self.nuisance)
        excited = np.diag(information) * self.tolerance ** 2 >= 1.0
        held = ~excited
        information[held, :], information[:, held], gradient[held] = 0.0, 0.0, 0.0
        stepped = np.zeros(len(self.parameters), bool)
        while True:  # a step: start that parameter afresh from the window's data, the most significant first
            scores = np.where(stepped | held, 0.0, self._scores(information, gradient, predicted))
            j = int(np.argmax(scores))
            if scores[j] <= STEP:
                break
            stepped[j] = True
            predicted[j, :], predicted[:, j] = 0.0, 0.0
            predicted[j, j] = (INITIAL * self.tolerance[j]) ** 2
        posterior = np.linalg.inv(predicted) + information
        move = -np.linalg.solve(posterior, gradient)
        reach = math.sqrt(max(float(move @ np.linalg.solve(predicted, move)), 0.0))
        if reach > MAX_MOVE:  # a linearised step this far out of the prediction is not to be trusted: part of it
            move *= MAX_MOVE / reach
        mean = np.clip(self.mean + move, self.low, self.high)
        covariance = np.linalg.inv(posterior)
        covariance = 0.5 * (covariance + covariance.T)
        away = np.abs(mean - self.start) > DRIFT_SIGMAS * np.sqrt(np.diag(covariance))
        since = np.where(away, np.where(np.isnan(self.since) | stepped, end - period, self.since), math.nan)
        return TrackState(mean, covariance, middle, excited, since, signature)

    @staticmethod
    def _scores(information: np.ndarray, gradient: np.ndarray, predicted: np.ndarray) -> np.ndarray:
        """(k,) how many sigma the window's data lie from the prediction, parameter by parameter: its score
        (the gradient) against the score's spread, information times (the prediction's spread plus the
        window's own) times information. A parameter that stepped raises its neighbours' scores too, less
        once its prediction is let go."""
        spread = np.diag(information @ predicted @ information + information)
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.nan_to_num(np.abs(gradient) / np.sqrt(np.maximum(spread, 0.0)))

    def apply(self, state: TrackState, end: float) -> np.ndarray:
        """Take a window's update at the end `end` [s] of the window after it; returns how far the values in
        use moved (k,): towards the estimate, where it is known well enough, at most at the rate limit."""
        self.mean, self.covariance, self.reference, self.excited, self.since, _ = state
        elapsed = 0.0 if math.isnan(self.updated_at) else max(end - self.updated_at, 0.0)
        self.updated_at = end
        reach = self.rate * elapsed
        used = np.where(self.in_use, self.used + np.clip(self.mean - self.used, -reach, reach), self.used)
        moved, self.used = used - self.used, used
        self._view = None
        return moved

    # -- what the outputs say ---------------------------------------------------------------------------------
    def due(self, stamps: Sequence[float]) -> list[bool]:
        """Whether each of these samples (in order) publishes the parameters: the first of each second."""
        return [self.first_of_second(stamp) for stamp in stamps]

    def view(self) -> ParameterView:
        """The parameters as they stand (the same object until the next update)."""
        if self._view is None:
            sigmas = np.sqrt(np.diag(self.covariance))
            drifting = np.abs(self.mean - self.start) - DRIFT_SIGMAS * sigmas > self.tolerance
            self._view = ParameterView(tuple(p.key for p in self.parameters), tuple(p.unit for p in self.parameters),
                                       self.mean.copy(), sigmas, self.in_use, self.used.copy(), self.start.copy(),
                                       self.tolerance.copy(), self.excited.copy(), drifting, self.since.copy(),
                                       self.updated_at)
        return self._view

    def __getstate__(self) -> dict[str, Any]:
        return {**self.__dict__, "_view": None}
