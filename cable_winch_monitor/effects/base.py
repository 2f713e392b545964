"""What a physical effect is: named parameters with units and bounds, and hooks where it acts.

An effect acts on one part of the model (`acts`):

* ``rope_law`` -- the cable's constitutive law (elastic stretch, own weight): it edits
  the `RopeLaw` the equilibrium solver uses;
* ``geometry`` -- the mechanism (encoder lengths to true lengths, anchors, centre of
  gravity, mass): it edits the plant or the lengths before the solve (`lengths`, or
  `lengths_states` for many samples at once), or, where the geometry depends on the pose
  (a sheave's tangent point), refines them after it;
* ``load`` -- the external wrench on the platform (gravity by default): inertia when the
  winches accelerate, a side pull;
* ``measurement`` -- what a sensor reads for a given equilibrium (load-pin friction,
  sensor calibration): it edits the predicted channels only. Its hook comes in two
  forms: `measure` for one solved state (the simple one to write), `measure_states`
  for stacked states at once (what the estimator and the analysis call, hundreds of
  states per call); the built-in effects write the stacked form, a user's effect may
  write either. `measure_gradients`, optional, gives the stacked hook's derivative: the
  estimator then needs no forward differences of the model's predictions.

Parameters scale with the plant: a default, bounds or fit step may be a function of the
plant (`relative`: of its weight m g, its anchors' span, its attachments' reach), so one
library describes a 10 t sinking platform and a 13 kg laboratory robot; the plant file's
`effect_bounds:` section replaces an effect's bounds where the plant needs others.
`Parameter.resolved(plant)` gives the numbers, and an effect made for a plant holds them
(`Effect.specs`).

Hooks default to "no change"; an effect overrides the ones it needs. The hooks that run
per sample see its `Conditions` (time, payout speeds and accelerations, direction of
motion, extra inputs): an effect that reads a topic declares it in `inputs`
(channels.Input) and finds its value in `conditions.inputs[input.key]`. Parameters with
``fit=False`` are settings (a wrap angle, a sensor span), written in YAML but not fitted.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, ClassVar, Protocol, cast

import numpy as np

from ..channels import Input
from ..model.conditions import Conditions, StackedConditions
from ..model.estimator import States
from ..model.plantfile.plant import Plant, file_number
from ..model.statics.result import Solution

ACTS = ("rope_law", "geometry", "load", "measurement")


class EffectError(ValueError):
    """An effect name, parameter or value is wrong; the message names it."""


Number = float | Callable[[Plant], float]
Bounds = tuple[float, float] | Callable[[Plant], tuple[float, float]]
UNKNOWN = float("nan")  # a plant-relative default without a plant: the value must be given


def span(plant: Plant) -> float:
    """The plant's size [m]: the largest distance between two anchors (sheaves)."""
    a = plant.anchors
    return float(np.linalg.norm(a[:, None, :] - a[None, :, :], axis=2).max())


def reach(plant: Plant) -> float:
    """How far the attachments sit from the platform's origin [m] (largest |B_i|)."""
    return float(np.linalg.norm(plant.attachments, axis=1).max())


@dataclass(frozen=True)
class Parameter:
    """One parameter: name, unit, default, (low, high) bounds, typical size of a fit step, meaning.

    default, bounds and scale are numbers, or functions of the plant where the parameter's size
    depends on it (see `relative`)."""

    name: str
    unit: str
    default: Number
    bounds: Bounds
    scale: Number
    doc: str = ""
    fit: bool = True

    def resolved(self, plant: Plant | None, bounds: tuple[float, float] | None = None) -> Resolved:
        """The numbers for this plant; `bounds` (the plant file's effect_bounds) replace the declared ones.
        Without a plant, plant-relative bounds are open and a plant-relative default unknown."""
        def number(spec: Any, unknown: Any) -> Any:
            return (unknown if plant is None else spec(plant)) if callable(spec) else spec
        low, high = bounds if bounds is not None else number(self.bounds, (-np.inf, np.inf))
        return cast(Resolved, Parameter(self.name, self.unit, float(number(self.default, UNKNOWN)),
                                        (float(low), float(high)), float(number(self.scale, UNKNOWN)), self.doc,
                                        self.fit))  # its default, bounds and scale are numbers now


class Resolved(Protocol):
    """A `Parameter` with the numbers for one plant (`Parameter.resolved`): what `Effect.specs` holds."""

    @property
    def name(self) -> str: ...
    @property
    def unit(self) -> str: ...
    @property
    def default(self) -> float: ...
    @property
    def bounds(self) -> tuple[float, float]: ...
    @property
    def scale(self) -> float: ...
    @property
    def doc(self) -> str: ...
    @property
    def fit(self) -> bool: ...


def relative(factor: float, size: Callable[[Plant], float]) -> Callable[[Plant], float]:
    """A parameter size proportional to one of the plant's: e.g. relative(0.5, lambda p: p.mass)."""
    return lambda plant: factor * size(plant)


def relative_bounds(low: float, high: float, size: Callable[[Plant], float]) -> Callable[[Plant], tuple[float, float]]:
    """Bounds (low, high) times one of the plant's sizes."""
    return lambda plant: (low * size(plant), high * size(plant))


def weight(plant: Plant) -> float:
    """m g [N]: forces scale with it."""
    return plant.weight


@dataclass
class RopeLaw:
    """The rope model the solver uses: EA None is rigid; weight [N/m] stretches elastic ropes."""

    EA: float | None = None
    weight: float = 0.0


class Effect:
    """Base class of a physical effect; a subclass sets the class attributes and its hooks."""

    name: ClassVar[str] = ""          # stable snake_case identifier (YAML, JSON, CLI)
    title: ClassVar[str] = ""         # plain words for reports
    acts: ClassVar[str] = "measurement"
    parameters: ClassVar[tuple[Parameter, ...]] = ()
    signature: ClassVar[str] = ""     # the residual pattern it leaves when missing from the model
    source: ClassVar[str] = ""        # seed or reference of the formula
    order: ClassVar[int] = 50         # measurement effects apply in this order (physics before sensors)
    inputs: ClassVar[tuple[Input, ...]] = ()  # extra topics the effect reads (their values in Conditions.inputs)

    def __init__(self, values: Mapping[str, Any] | None = None, plant: Plant | None = None):
        """The effect with these values (the rest at their defaults), its parameters resolved for `plant`
        (its size and its file's effect_bounds; without a plant, plant-relative bounds are not checked)."""
        self.for_plant = plant
        given_bounds = plant.effect_bounds.get(self.name, {}) if plant is not None else {}
        self.specs: tuple[Resolved, ...] = tuple(p.resolved(plant, given_bounds.get(p.name)) for p in self.parameters)
        self.values: dict[str, float] = self._checked(values or {})

    def _checked(self, values: Mapping[str, Any]) -> dict[str, float]:
        """Every parameter's value: the one given, else its default; EffectError where a name is not a
        parameter's, or a value is not a number within the resolved bounds."""
        known = {p.name for p in self.specs}
        unknown = sorted(set(values) - known)
        if unknown:
            raise EffectError(f"effect '{self.name}': unknown parameter '{unknown[0]}' "
                              f"(known: {', '.join(sorted(known)) or 'none'})")
        out = {}
        for p in self.specs:
            try:
                value = file_number(values.get(p.name, p.default))
            except (TypeError, ValueError):
                raise EffectError(f"effect '{self.name}': parameter '{p.name}' must be a number, "
                                  f"got {values[p.name]!r}") from None
            if np.isnan(value):
                raise EffectError(f"effect '{self.name}': parameter '{p.name}' needs a value (its default "
                                  "depends on the plant)")
            if not p.bounds[0] <= value <= p.bounds[1]:
                raise EffectError(f"effect '{self.name}': parameter '{p.name}' = {value:g} {p.unit} is outside "
                                  f"its bounds [{p.bounds[0]:g}, {p.bounds[1]:g}]")
            out[p.name] = value
        return out

    def __getitem__(self, name: str) -> float:
        return self.values[name]

    def __repr__(self) -> str:
        return f"{self.name}(" + ", ".join(f"{k}={v:g}" for k, v in self.values.items()) + ")"

    @classmethod
    def fittable(cls) -> bool:
        """The effect has parameters a fit adjusts."""
        return any(p.fit for p in cls.parameters)

    def fitted(self) -> tuple[Resolved, ...]:
        """The parameters a fit adjusts, resolved for the plant (bounds, step)."""
        return tuple(p for p in self.specs if p.fit)

    def replaced(self, **values: float) -> Effect:
        """A copy with some parameter values changed (for the same plant). Its parameters' numbers for the plant
        are this one's, not resolved again (parameter tracking replaces values many times a window), unless
        the class sets itself up in an `__init__` of its own."""
        values = {**self.values, **values}
        if type(self).__init__ is not Effect.__init__:
            return type(self)(values, self.for_plant)
        out = object.__new__(type(self))
        out.for_plant, out.specs = self.for_plant, self.specs
        out.values = out._checked(values)
        return out

    # -- hooks: each returns its input unchanged unless the effect acts there ---------------
    def rope(self, law: RopeLaw) -> RopeLaw:
        """rope_law: the rope model to solve with."""
        return law

    def plant(self, plant: Plant) -> Plant:
        """geometry: the plant as it really is (centre of gravity, mass, anchors)."""
        return plant

    def lengths(self, lengths: np.ndarray, conditions: Conditions) -> np.ndarray:
        """geometry: the true unstretched rope lengths for the lengths the winches report."""
        return lengths

    def lengths_states(self, lengths: np.ndarray, conditions: StackedConditions) -> np.ndarray:
        """geometry, many samples: the true lengths (N, 4) for the reported ones (N, 4) (conditions[k] is row
        k's). By default `lengths` on each row; an effect writing it spares the estimator a loop per sample."""
        return np.array([self.lengths(row, conditions[k]) for k, row in enumerate(lengths)], dtype=float)

    def load(self, wrench: np.ndarray, plant: Plant, conditions: Conditions) -> np.ndarray:
        """load: the external wrench on the platform (force [N], moment about C [N m], shaft frame)."""
        return wrench

    def input_value(self, conditions: Conditions, name: str) -> float:
        """The value of the declared input `name` at this sample (NaN if the sample has none)."""
        spec = next(i for i in self.inputs if i.name == name)
        return float(conditions.inputs.get(spec.key, np.nan))

    def refine(self, plant: Plant, lengths: np.ndarray, solution: Solution) -> tuple[Plant, np.ndarray] | None:
        """geometry that depends on the pose, one solved state: plant and lengths for the next solve
        (None: no such effect). A built-in effect writes `refine_states` instead."""
        return None

    def refine_states(self, plant: Plant, anchors: np.ndarray, lengths: np.ndarray,
                      states: States) -> tuple[np.ndarray, np.ndarray]:
        """geometry that depends on the pose, stacked states: the anchors (n, 4, 3) and lengths (n, 4)
        for the next solve, from this solve's (row k is state k's; `plant` the model's physical plant).
        By default `refine` on each state, with that row's anchors."""
        anchors, lengths = anchors.copy(), lengths.copy()
        for k, solution in enumerate(states.solutions()):
            refined = self.refine(plant.with_changes(anchors=anchors[k]), lengths[k], solution)
            if refined is not None:
                anchors[k], lengths[k] = refined[0].anchors, refined[1]
        return anchors, lengths

    def measure(self, channels: dict[str, float], solution: Solution, plant: Plant, conditions: Conditions) -> None:
        """measurement, one solved state: edit the predicted sensor readings in place."""

    def measure_states(self, channels: dict[str, np.ndarray], states: States, plant: Plant,
                       conditions: StackedConditions) -> None:
        """measurement, stacked states (conditions[k] is state k's): edit the predicted readings, arrays
        (n,) by channel, in place. By default `measure` on each state."""
        for k, solution in enumerate(states.solutions()):
            row = {name: float(values[k]) for name, values in channels.items()}
            self.measure(row, solution, plant, conditions[k])
            for name, value in row.items():
                channels[name][k] = value

    def measure_gradients(self, gradients: dict[str, np.ndarray], channels: dict[str, np.ndarray], states: States,
                          plant: Plant, conditions: StackedConditions) -> None:
        """measurement, stacked states: the derivative of `measure_states`. Given the readings before this
        effect (`channels`), replace the derivative (n, 10) in `gradients` -- by position [m], rotation
        vector [rad] (applied on the left), tensions [N] -- of every reading it changes (chain rule).
        Optional: where an acting measurement effect does not write it, the estimator differentiates the
        model's predictions numerically (a few times slower)."""

    def implausible(self, plant: Plant) -> list[str]:
        """Why the values are physically implausible for this plant, each "name.parameter: reason" (empty: none)."""
        return []

    def warnings(self, conditions: list[Conditions]) -> list[str]:
        """Why a bag with these conditions cannot identify the parameters (empty: no reason known)."""
        return []
