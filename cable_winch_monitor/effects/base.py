"""What a physical effect is: named parameters with units and bounds, and hooks where it acts.

An effect acts on one part of the model (`acts`):

* ``rope_law`` -- the cable's constitutive law (elastic stretch, own weight): it edits
  the `RopeLaw` the equilibrium solver uses;
* ``geometry`` -- the mechanism (encoder lengths to true lengths, anchors, centre of
  gravity, mass): it edits the plant or the lengths before the solve, or, where the
  geometry depends on the pose (a sheave's tangent point), refines them after it;
* ``load`` -- the external wrench on the platform (gravity by default): inertia when the
  winches accelerate, a side pull;
* ``measurement`` -- what a sensor reads for a given equilibrium (load-pin friction,
  sensor calibration): it edits the predicted channels only, so fitting it needs no
  new solves.

Hooks default to "no change"; an effect overrides the ones it needs. The hooks that run
per sample see its `Conditions` (time, payout speeds and accelerations, direction of
motion, extra inputs): an effect that reads a topic declares it in `inputs`
(channels.Input) and finds its value in `conditions.inputs[input.key]`. Parameters with
``fit=False`` are settings (a wrap angle, a sensor span), written in YAML but not fitted.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar, Mapping

import numpy as np

from ..channels import Input
from ..model.conditions import Conditions
from ..model.plant import Plant
from ..model.result import Solution

ACTS = ("rope_law", "geometry", "load", "measurement")


class EffectError(ValueError):
    """An effect name, parameter or value is wrong; the message names it."""


@dataclass(frozen=True)
class Parameter:
    """One parameter: name, unit, default, (low, high) bounds, typical size of a fit step, meaning."""

    name: str
    unit: str
    default: float
    bounds: tuple[float, float]
    scale: float
    doc: str = ""
    fit: bool = True


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

    def __init__(self, values: Mapping[str, Any] | None = None):
        values = dict(values or {})
        known = {p.name for p in self.parameters}
        unknown = sorted(set(values) - known)
        if unknown:
            raise EffectError(f"effect '{self.name}': unknown parameter '{unknown[0]}' "
                              f"(known: {', '.join(sorted(known)) or 'none'})")
        self.values: dict[str, float] = {}
        for p in self.parameters:
            try:
                value = float(values.get(p.name, p.default))
            except (TypeError, ValueError):
                raise EffectError(f"effect '{self.name}': parameter '{p.name}' must be a number, "
                                  f"got {values[p.name]!r}") from None
            if not p.bounds[0] <= value <= p.bounds[1]:
                raise EffectError(f"effect '{self.name}': parameter '{p.name}' = {value:g} {p.unit} is outside "
                                  f"its bounds [{p.bounds[0]:g}, {p.bounds[1]:g}]")
            self.values[p.name] = value

    def __getitem__(self, name: str) -> float:
        return self.values[name]

    def __repr__(self) -> str:
        return f"{self.name}(" + ", ".join(f"{k}={v:g}" for k, v in self.values.items()) + ")"

    @classmethod
    def fitted(cls) -> tuple[Parameter, ...]:
        """The parameters a fit adjusts."""
        return tuple(p for p in cls.parameters if p.fit)

    def replaced(self, **values: float) -> "Effect":
        """A copy with some parameter values changed."""
        return type(self)({**self.values, **values})

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

    def load(self, wrench: np.ndarray, plant: Plant, conditions: Conditions) -> np.ndarray:
        """load: the external wrench on the platform (force [N], moment about C [N m], shaft frame)."""
        return wrench

    def input_value(self, conditions: Conditions, name: str) -> float:
        """The value of the declared input `name` at this sample (NaN if the sample has none)."""
        spec = next(i for i in self.inputs if i.name == name)
        return float(conditions.inputs.get(spec.key, np.nan))

    def refine(self, plant: Plant, lengths: np.ndarray, solution: Solution) -> tuple[Plant, np.ndarray] | None:
        """geometry that depends on the pose: plant and lengths for the next solve (None: no such effect)."""
        return None

    def measure(self, channels: dict[str, float], solution: Solution, plant: Plant, conditions: Conditions) -> None:
        """measurement: edit the predicted sensor readings in place."""

    def implausible(self, plant: Plant) -> list[str]:
        """Why the values are physically implausible for this plant, each "name.parameter: reason" (empty: none)."""
        return []

    def warnings(self, conditions: list[Conditions]) -> list[str]:
        """Why a bag with these conditions cannot identify the parameters (empty: no reason known)."""
        return []
