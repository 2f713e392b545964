"""A plant with its enabled physical effects: the one solve path of the package.

`PlantModel.solve` turns encoder lengths into true lengths (geometry effects), builds the
load on the platform (gravity, then load effects) and the rope law (rope-law effects),
and solves with the matching solver -- the rigid one chosen (energy, or seed 002's
traversal), or the elastic one with EA and the rope's own-weight stretch -- then refines
pose-dependent geometry (the plant's pulleys, sheave tangent points) by fixed-point iteration.
`PlantModel.solve_batch` does the same for many samples along a trajectory at once
(model/batched*.py), where nothing makes the geometry depend on the pose.
`PlantModel.predict` gives every declared channel's reading for a solved state
(its registry's channels, then measurement effects), `predict_states` for stacked states.
The live node, replay, the analysis, `limits`, the command check and the wall clearance
all go through this object; a model without effects is exactly the monitor's rigid model.
"""
from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..channels import ChannelRegistry, Input
from ..model.conditions import Conditions, StackedConditions
from ..model.estimator import States
from ..model.estimator.observations import STATE_SIZE
from ..model.plantfile.plant import Plant, PlantConfigError
from ..model.solvers.batched import BatchSolution, solve_batch
from ..model.solvers.batched_elastic import solve_batch_elastic
from ..model.solvers.elastic import solve_elastic
from ..model.solvers.ropes import Ropes
from ..model.solvers.solve import METHODS, solve
from ..model.statics.result import Solution, SolveStatus, failed
from .base import Effect, EffectError, RopeLaw
from .pulley import wrap
from .registry import BUILTIN_REGISTRY, Registry
from .tracked import TrackedParameter, file_effect, tracked_parameters

REFINE_STEPS = 6
REFINE_TOL = 1e-7  # [m] pose change at which the pose-dependent geometry has settled
NO_CONDITIONS = Conditions()


def overrides(cls: type[Effect], hook: str) -> bool:
    """The effect class writes this hook of its own (it acts there)."""
    return getattr(cls, hook) is not getattr(Effect, hook)


def refines(cls: type[Effect]) -> bool:
    """The effect makes the geometry depend on the pose (it writes a refine hook)."""
    return overrides(cls, "refine") or overrides(cls, "refine_states")


def effects_from_mapping(section: Any, where: str, plant: Plant | None = None, registry: Registry = BUILTIN_REGISTRY
                         ) -> list[Effect]:
    """The enabled effects of an `effects:` mapping {name: {enabled: bool, parameter: value, ...}}, named in
    `registry`, their parameters resolved for `plant` (Effect)."""
    if section is None:
        return []
    if not isinstance(section, Mapping):
        raise EffectError(f"key '{where}' must be a mapping of effect names to their parameters")
    effects = []
    for name, spec in section.items():
        spec = dict(spec or {})
        enabled = spec.pop("enabled", True)
        if not isinstance(enabled, bool):
            raise EffectError(f"key '{where}.{name}.enabled' must be true or false, got {enabled!r}")
        try:
            effect = registry.effect_class(str(name))(spec, plant)
        except EffectError as error:
            raise EffectError(f"key '{where}.{name}': {error}") from None
        if enabled:
            effects.append(effect)
    return effects


def _call(effect: Effect, hook: str, *args: Any) -> Any:
    """An effect's hook called; anything it raises comes out as an EffectError naming the effect and the hook:
    a user's effect may raise anything, and the sample (or the command) is refused with that line."""
    try:
        return getattr(effect, hook)(*args)
    except Exception as error:
        raise EffectError(f"effect '{effect.name}': its {hook.removesuffix('_states')} hook raised "
                          f"{type(error).__name__}: {error}") from None


def _finite(effect: Effect, hook: str, value: Any, shape: tuple[int, ...], what: str) -> np.ndarray:
    """A hook's result as `shape` finite numbers, else an EffectError saying what it gave."""
    try:
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        array = None
    if array is None or array.shape != shape or not np.isfinite(array).all():
        shown = array.tolist() if array is not None else repr(value)
        raise EffectError(f"effect '{effect.name}': its {hook} hook gave {what} that {'is' if what[0] == 'a' else 'are'}"
                          f" not {' x '.join(map(str, shape))} finite numbers: {shown}")
    return array


def _check_predicted(predicted: dict[str, np.ndarray], posed: np.ndarray, who: str) -> None:
    """EffectError where a channel is not predicted as one finite number per state with a pose. The channels
    are checked as one array: the estimator predicts a few states at a time, and a dozen channels checked
    one by one were half the time of a prediction."""
    names = list(predicted)
    if not names:
        return
    try:
        table = np.array([predicted[name] for name in names], dtype=float).reshape(len(names), len(posed))
    except ValueError:
        shapes = ", ".join(f"{name} {np.shape(predicted[name])}" for name in names)
        raise EffectError(f"{who} gave other than one value per state ({len(posed)}): {shapes}") from None
    bad = ~np.isfinite(table) & posed
    if bad.any():
        channel, state = np.argwhere(bad)[0]
        raise EffectError(f"{who} gave {names[channel]} = {table[channel, state]} at a solved state")


def _check_effect_bounds(plant: Plant, registry: Registry) -> None:
    """Every effect and parameter the plant file's effect_bounds names exists."""
    for name, params in plant.effect_bounds.items():
        known = {p.name for p in registry.effect_class(name).parameters}
        unknown = sorted(set(params) - known)
        if unknown:
            raise EffectError(f"key 'plant.effect_bounds.{name}.{unknown[0]}': effect '{name}' has no such parameter "
                              f"(known: {', '.join(sorted(known))})")


def _check_noise_keys(plant: Plant, channels: ChannelRegistry) -> None:
    """Every key of the plant file's noise section is a declared channel's (or the encoders')."""
    unknown = sorted(set(plant.noise) - set(channels.noise_keys()))
    if unknown:
        raise EffectError(f"unknown key 'plant.noise.{unknown[0]}' (known: {', '.join(channels.noise_keys())}; a "
                          "user's channel needs its module in plant.effect_modules)")


@dataclass(frozen=True)
class PlantModel:
    """The nominal plant, its enabled effects (at most one of each name), the rigid-rope solver and the registry
    its effects and channels are named in (the built-ins and the plant file's user modules)."""

    plant: Plant
    effects: tuple[Effect, ...] = field(default=())
    solver: str = "energy"
    registry: Registry = field(default=BUILTIN_REGISTRY, compare=False, repr=False)

    def __post_init__(self) -> None:
        if self.solver not in METHODS:
            raise EffectError(f"unknown solver {self.solver!r}; use one of {', '.join(METHODS)}")
        if self.solver != "energy" and self.rope_law.EA is not None:
            elastic = ", ".join(e.name for e in self.effects if e.rope(RopeLaw()).EA is not None)
            raise EffectError(f"solver '{self.solver}' is for rigid ropes, but the plant's effects ({elastic}) make "
                              "them elastic: use the energy solver")

    @classmethod
    def from_plant(cls, plant: Plant, solver: str = "energy") -> PlantModel:
        """The effects the plant file switches on (`plant.effects`), named among the built-ins and in the user
        modules of `plant.effect_modules`."""
        try:
            registry = BUILTIN_REGISTRY.with_modules(plant.effect_modules)
            _check_effect_bounds(plant, registry)
            _check_noise_keys(plant, registry.channels)
            tracked_parameters(plant, registry)
            model = cls(plant, tuple(effects_from_mapping(plant.effects, "plant.effects", plant, registry)), solver,
                        registry)
            _ = model.physical, model.rope_law  # the effects' plant and rope hooks, run once: a failure is said now
            return model
        except EffectError as error:
            raise PlantConfigError(f"plant file: {error}") from None

    def names(self) -> list[str]:
        return [e.name for e in self.effects]

    def get(self, name: str) -> Effect | None:
        return next((e for e in self.effects if e.name == name), None)

    def with_effects(self, effects: Iterable[Effect]) -> PlantModel:
        """Add or replace effects by name."""
        replaced = {e.name: e for e in effects}
        kept = [replaced.pop(e.name, e) for e in self.effects]
        return PlantModel(self.plant, tuple(kept + list(replaced.values())), self.solver, self.registry)

    def with_tracked(self, tracked: Sequence[TrackedParameter], values: np.ndarray, every: bool = False) -> PlantModel:
        """This model (the plant file's) with the tracked parameters at `values`: an effect that is off in the
        file switched on where one of its values differs from its start (`every`: all of them, as the tracker's
        derivatives need: an effect off is not the effect at its default)."""
        changed: dict[str, dict[str, float]] = {}
        for parameter, value in zip(tracked, np.asarray(values, dtype=float).tolist()):
            if every or parameter.enabled or value != parameter.start:
                changed.setdefault(parameter.effect, {})[parameter.name] = value
        if not changed:
            return self
        effects = []
        for name, values_of in changed.items():
            effect = self.get(name) or self._file_effect(name)
            effects.append(effect.replaced(**values_of))
        return self.with_effects(effects)

    def _file_effect(self, name: str) -> Effect:
        """An effect the file has off, as the file gives it: made once for this model (its parameters resolved
        for the plant, which the tracker's updates otherwise did at each window's every derivative)."""
        if name not in self._file_effects:
            self._file_effects[name] = file_effect(self.registry.effect_class(name), self.plant)
        return self._file_effects[name]

    @cached_property
    def _file_effects(self) -> dict[str, Effect]:
        return {}

    @property
    def channels(self) -> ChannelRegistry:
        """The channels this model predicts: the built-ins and those its user modules declare."""
        return self.registry.channels

    @cached_property
    def physical(self) -> Plant:
        """The plant as the geometry effects make it (centre of gravity, mass, ...)."""
        plant = self.plant
        for effect in self.effects:
            plant = _call(effect, "plant", plant)
        return plant

    @cached_property
    def rope_law(self) -> RopeLaw:
        law = RopeLaw()
        for effect in self.effects:
            law = _call(effect, "rope", law)
        return law

    @cached_property
    def ropes(self) -> Ropes:
        """The rope law as the solvers and the estimator take it (rigid ropes carry no weight of their own)."""
        return Ropes.of(self.rope_law.EA, self.rope_law.weight)

    @cached_property
    def _refiners(self) -> tuple[Effect, ...]:
        return tuple(e for e in self.effects if refines(type(e)))

    @cached_property
    def _measurers(self) -> tuple[Effect, ...]:
        return tuple(sorted((e for e in self.effects if overrides(type(e), "measure")
                             or overrides(type(e), "measure_states")), key=lambda e: e.order))

    @cached_property
    def _loaders(self) -> tuple[Effect, ...]:
        return tuple(e for e in self.effects if overrides(type(e), "load"))

    @cached_property
    def inputs(self) -> tuple[Input, ...]:
        """The extra inputs the effects read (each once)."""
        return tuple({i.key: i for e in self.effects for i in e.inputs}.values())

    @property
    def measuring(self) -> bool:
        """Some effect changes what a sensor reads (the plain channel predictions do not hold)."""
        return bool(self._measurers)

    @property
    def refining(self) -> bool:
        """The geometry depends on the pose (an effect's, or the plant's pulleys): fixed-point refinement."""
        return bool(self._refiners) or bool(self.physical.sheaves)

    @property
    def reads_conditions(self) -> bool:
        """Something reads a sample's conditions: an effect, or a channel a user declared."""
        return bool(self.effects) or self.channels.user

    @property
    def plain(self) -> bool:
        """No effect and no pulleys: the rigid model, which the batched solver serves."""
        return not self.effects and not self.plant.sheaves

    @property
    def batchable(self) -> bool:
        """`solve_batch` solves many samples at once: the energy solver, no pose-dependent geometry."""
        return self.solver == "energy" and not self.refining

    @cached_property
    def _lengtheners(self) -> tuple[Effect, ...]:
        return tuple(e for e in self.effects if overrides(type(e), "lengths"))

    def solve_key(self) -> tuple:
        """Everything a solve depends on besides the sample: two models with equal keys have the same equilibria."""
        law = self.rope_law
        geometry = tuple((e.name, tuple(e.values.items())) for e in self.effects
                         if refines(type(e)) or any(overrides(type(e), hook) for hook in ("plant", "lengths", "load")))
        return law.EA, law.weight if law.EA is not None else 0.0, geometry, self.solver

    def true_lengths(self, reported: np.ndarray, conditions: Conditions = NO_CONDITIONS) -> np.ndarray:
        """The true lengths for the reported ones by the geometry effects; EffectError where a hook raises or
        makes finite lengths not finite."""
        lengths = np.asarray(reported, dtype=float)
        for effect in self._lengtheners:
            given = lengths
            lengths = _call(effect, "lengths", given, conditions)
            if np.isfinite(given).all() and np.shape(given) == (4,):
                lengths = _finite(effect, "lengths", lengths, (4,), "lengths")
        return lengths

    def load(self, conditions: Conditions = NO_CONDITIONS) -> np.ndarray:
        """The external wrench on the platform at these conditions: gravity, then the load effects; EffectError
        where a hook raises or gives a wrench that is not six finite numbers."""
        wrench = self.physical.wrench
        for effect in self._loaders:
            wrench = _finite(effect, "load", _call(effect, "load", wrench, self.physical, conditions), (6,),
                             "a wrench")
        return wrench

    def _solve_once(self, plant: Plant, lengths: np.ndarray, warm_start: Solution | None,
                    load: np.ndarray) -> Solution:
        law = self.rope_law
        if law.EA is None:
            return solve(plant, lengths, self.solver, warm_start=warm_start, load=load)
        return solve_elastic(plant, self._elastic_lengths(lengths), law.EA, warm_start=warm_start, load=load)

    def _elastic_lengths(self, lengths: np.ndarray) -> np.ndarray:
        """What an elastic rope of these true lengths is as a weightless one: l + w l^2 / (2 EA)."""
        law = self.rope_law
        assert law.EA is not None  # asked for elastic ropes only
        return lengths + law.weight * lengths ** 2 / (2.0 * law.EA)

    def solve(self, reported: ArrayLike, warm_start: Solution | None = None,
              conditions: Conditions = NO_CONDITIONS) -> Solution:
        """Equilibrium for the lengths the winches report at these conditions; never raises (model.result)."""
        try:
            lengths = self.true_lengths(np.asarray(reported, dtype=float), conditions)
            load = self.load(conditions)
        except EffectError as error:  # an effect's hook failed on this sample (its lengths are numbers)
            return failed(SolveStatus.INVALID_INPUT, str(error), self.solver, np.asarray(reported, dtype=float))
        except (TypeError, ValueError) as error:
            if np.shape(reported) != (4,):
                return failed(SolveStatus.INVALID_INPUT, f"cannot apply the plant's effects: {error}",
                              self.solver, np.full(4, np.nan))
            # a reported length is not a number: the solver says which (as given: an elastic rope's stretch is
            # of numbers)
            law = self.rope_law
            if law.EA is None:
                return solve(self.physical, reported, self.solver, warm_start=warm_start, load=self.physical.wrench)
            return solve_elastic(self.physical, reported, law.EA, warm_start=warm_start, load=self.physical.wrench)
        solution = self._solve_once(self.physical, lengths, warm_start, load)
        for _ in range(REFINE_STEPS if self.refining else 0):
            if not solution.ok:
                break
            try:
                anchors, refined = self.refine(lengths[None], States.of(self.physical, [solution]))
            except EffectError as error:
                return failed(SolveStatus.INVALID_INPUT, str(error), self.solver, lengths)
            previous = solution
            solution = self._solve_once(self.physical.with_changes(anchors=anchors[0]), refined[0], solution, load)
            if solution.ok:
                assert solution.points_b is not None and previous.points_b is not None  # both solved poses
                if np.abs(solution.points_b - previous.points_b).max() < REFINE_TOL:
                    break
        return solution

    def refine(self, lengths: np.ndarray, states: States) -> tuple[np.ndarray, np.ndarray]:
        """The pose-dependent geometry at stacked states: anchors (n, 4, 3) -- the pulleys' tangent points,
        then each refining effect's -- and the free lengths (n, 4) from there, for true lengths (n, 4)."""
        plant = self.physical
        anchors = np.broadcast_to(plant.anchors, (len(states), 4, 3)).copy()
        if plant.sheaves:
            anchors, lengths, _ = wrap(plant, lengths, states.points_b)
        for effect in self._refiners:
            anchors, lengths = _call(effect, "refine_states", plant, anchors, lengths, states)
        return anchors, lengths

    def solve_batch(self, reported: np.ndarray, conditions: Sequence[Conditions] | None = None,
                    warm_start: Solution | None = None) -> list[Solution]:
        """`solve` of each row of `reported` (N, 4), in order along a trajectory (each warm-started from
        the last solved one), at its conditions (None: none); batched where `batchable`, the answers the same."""
        reported = np.asarray(reported, dtype=float).reshape(-1, 4)
        conditions = [NO_CONDITIONS] * len(reported) if conditions is None else list(conditions)
        if not self.batchable:
            return self._solve_each(reported, conditions, warm_start)
        lengths, loads, hooked = self.batch_inputs(reported, conditions)
        solutions = self.solve_true_batch(lengths, loads, warm_start).solutions()
        for k in hooked:  # an effect's hook failed on this row: `solve` says why
            solutions[k] = self.solve(reported[k], None, conditions[k])
        return solutions

    def solve_true_batch(self, lengths: np.ndarray, loads: np.ndarray | None = None,
                         warm_start: Solution | None = None) -> BatchSolution:
        """The batched solver of this rope law for true lengths (N, 4) under `loads` ((N, 6), (6,) or None:
        gravity), as arrays; only for a `batchable` model."""
        law = self.rope_law
        if law.EA is None:
            return solve_batch(self.physical, lengths, warm_start, loads)
        return solve_batch_elastic(self.physical, self._elastic_lengths(np.asarray(lengths, dtype=float)), law.EA,
                                   warm_start, loads)

    def _solve_each(self, reported: np.ndarray, conditions: list[Conditions],
                    warm_start: Solution | None) -> list[Solution]:
        solutions, warm = [], warm_start
        for lengths, at in zip(reported, conditions):
            solutions.append(self.solve(lengths, warm, at))
            warm = solutions[-1] if solutions[-1].ok else warm
        return solutions

    def batch_inputs(self, reported: np.ndarray, conditions: Sequence[Conditions] | StackedConditions
                     ) -> tuple[np.ndarray, np.ndarray, list[int]]:
        """True lengths (N, 4) and loads (N, 6) of every row by the effects' hooks, and the rows where a
        hook failed (NaN lengths and gravity there: the batch leaves them to `solve`, which says why)."""
        reported = np.asarray(reported, dtype=float).reshape(-1, 4)
        lengths, loads = reported.copy(), np.tile(self.physical.wrench, (len(reported), 1))
        hooked: list[int] = []
        if not (self._lengtheners or self._loaders):
            return lengths, loads, hooked
        stacked = None if self._loaders else self._stacked_lengths(lengths, conditions)
        if stacked is not None:
            return stacked, loads, hooked
        for k, at in enumerate(conditions):
            try:
                lengths[k] = self.true_lengths(lengths[k], at)
                loads[k] = self.load(at)
            except (TypeError, ValueError):
                lengths[k], loads[k] = np.nan, self.physical.wrench
                hooked.append(k)
        return lengths, loads, hooked

    def _stacked_lengths(self, reported: np.ndarray, conditions: Sequence[Conditions] | StackedConditions
                         ) -> np.ndarray | None:
        """The true lengths of all rows at once, where every geometry effect writes `lengths_states` and none
        fails on a row (a hook raising, or making finite lengths not finite); else None, and the rows are
        taken one by one, which finds the rows a hook fails on."""
        if not all(overrides(type(e), "lengths_states") for e in self._lengtheners):
            return None
        stacked = StackedConditions.of(conditions)
        lengths = reported
        for effect in self._lengtheners:
            given = lengths
            try:
                lengths = np.asarray(effect.lengths_states(given, stacked), dtype=float)
            except Exception:
                return None
            if lengths.shape != given.shape or not np.isfinite(lengths[np.isfinite(given).all(axis=1)]).all():
                return None
        return lengths

    def predict(self, solution: Solution, conditions: Conditions = NO_CONDITIONS) -> dict[str, float]:
        """What every declared channel reads for a solved state: the plain model, then measurement effects."""
        if not self._measurers:
            return self.channels.predicted(solution, self.physical, conditions)
        predicted = self.predict_states(States.of(self.physical, [solution]), StackedConditions.of((conditions,)))
        return {name: float(values[0]) for name, values in predicted.items()}

    def predict_solutions(self, solutions: Sequence[Solution], conditions: Sequence[Conditions]
                          ) -> dict[str, np.ndarray]:
        """`predict` for each of many solutions at its conditions, all solved ones at once: arrays (n,) by
        channel, NaN where a solution is not solved."""
        solved = [k for k, solution in enumerate(solutions) if solution.ok]
        out = {name: np.full(len(solutions), np.nan) for name in self.channels.names()}
        if solved:
            table = self.predict_states(States.of(self.physical, [solutions[k] for k in solved]),
                                        StackedConditions.of([conditions[k] for k in solved]))
            for name, values in table.items():
                out.setdefault(name, np.full(len(solutions), np.nan))[solved] = values
        return out

    def predict_states(self, states: States, conditions: StackedConditions) -> dict[str, np.ndarray]:
        """`predict` for stacked states (row k of `conditions` is state k's): arrays (n,) by channel."""
        return self._predicted(states, conditions, None)

    @property
    def differentiated(self) -> bool:
        """Every channel and every measurement effect gives its derivative (`predict_gradients` can answer)."""
        return self._measure_differentiated and self.channels.differentiable()

    @cached_property
    def _measure_differentiated(self) -> bool:
        return all(overrides(type(e), "measure_gradients") for e in self._measurers)

    def predict_gradients(self, states: States, conditions: StackedConditions
                          ) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]] | None:
        """`predict_states` and each channel's derivative (n, 10) in the state coordinates, by the chain rule
        through the measurement effects; None where a channel or an effect gives no derivative (the
        estimator then takes forward differences)."""
        if not self._measure_differentiated:
            return None
        try:
            gradients = self.channels.gradients_states(states)
        except Exception as error:
            raise EffectError(f"a channel's gradient raised {type(error).__name__}: {error}") from None
        if gradients is None:
            return None
        predicted = self._predicted(states, conditions, gradients)
        shape = (len(states), STATE_SIZE)
        for name, gradient in gradients.items():
            if np.shape(gradient) != shape:
                raise EffectError(f"the derivative of channel '{name}' has shape {np.shape(gradient)}, not {shape}: "
                                  "a measure_gradients hook gave another")
        return predicted, gradients

    def _predicted(self, states: States, conditions: StackedConditions,
                   gradients: dict[str, np.ndarray] | None, checked: bool = False) -> dict[str, np.ndarray]:
        """The channels predicted for `states`, their derivatives `gradients` (None: not asked) carried
        through each measurement effect in place. The readings are checked once, at the end (the
        estimator predicts a few states at a time, many times a sample); where they fail, the prediction
        is made again, `checked` after each step, to name the step that gave them."""
        try:
            predicted = self.channels.predicted_states(states, conditions)
        except Exception as error:
            raise EffectError(f"a channel's prediction raised {type(error).__name__}: {error}") from None
        if checked:
            _check_predicted(predicted, states.finite, "a channel's prediction")
        for effect in self._measurers:
            if gradients is not None:  # at the readings before the effect, which its hook then changes
                _call(effect, "measure_gradients", gradients, predicted, states, self.physical, conditions)
            _call(effect, "measure_states", predicted, states, self.physical, conditions)
            if checked:
                _check_predicted(predicted, states.finite, f"effect '{effect.name}': its measure hook")
        if not checked:
            try:
                _check_predicted(predicted, states.finite, "a channel's prediction or a measure hook")
            except EffectError:
                self._predicted(states, conditions, None, checked=True)
                raise
        return predicted

    def effects_config(self) -> dict[str, dict[str, Any]]:
        """The `effects:` section of a plant file with these effects on."""
        return {e.name: {"enabled": True, **{k: float(v) for k, v in e.values.items()}} for e in self.effects}

    def user_modules(self) -> list[str]:
        """Files of the user modules this model needs (for `effect_modules:`): those defining its effects or
        declaring channels."""
        used = {type(effect) for effect in self.effects}
        return sorted(path for path, module in self.registry.loaded.items()
                      if used.intersection(module.effects) or module.channels)
