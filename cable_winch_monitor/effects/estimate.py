"""The fused estimate of a sample under a plant model: every declared channel measured at it, weighted by
its noise from the plant file, with the model's rope law, load and measurement effects.

The encoders' noise is the plant file's `noise.length` [m]; a plant without it has its
lengths taken as exact, and the estimate is the model's forward kinematics (`PlantModel.solve`).
A channel is fused where it was measured (finite) and has a finite noise. Without
measurement effects the built-in channels are read off the state directly (load pins,
depth, x, y) or by their analytic prediction (roll, pitch); a user's channel, or any
channel when measurement effects act (a load pin reading the rope's weight too), is
predicted by `PlantModel.predict_states` for all candidate states at once, differentiated by
the chain rule where every channel and measurement effect gives its derivative
(`PlantModel.predict_gradients`), else numerically (`ModelledChannels`).
Where the geometry depends on the pose (pulleys, head-sheave tangent points), the samples
are estimated with each sample's anchors and free lengths from the last estimate's pose,
again until the pose settles (`PlantModel.refine`, the fixed point the per-sample solve
iterates to). The length and force-balance Jacobians then leave out the anchors' motion: at
the fixed point it does not change the optimum (a rope's wrapped arc plus its free span
grows with the attachment's motion along the free span alone), only the convergence rate.
"""
from __future__ import annotations

import functools
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace

import numpy as np

from ..channels import LENGTH_NOISE, TENSION_CHANNELS
from ..model.conditions import Conditions, StackedConditions
from ..model.estimator import BatchEstimate, Estimate, Observation, States, estimate_batch, forward_differences
from ..model.estimator import observations as obs
from ..model.statics.result import Solution
from .model import NO_CONDITIONS, REFINE_STEPS, REFINE_TOL, PlantModel

BUILT_IN: dict[str, Callable[[float | np.ndarray, float], Observation]] = {
    **{name: functools.partial(obs.load_pin, i) for i, name in enumerate(TENSION_CHANNELS)},
    "roll": obs.roll, "pitch": obs.pitch,
    "x": lambda value, sigma: obs.position_component(0, value, sigma),
    "y": lambda value, sigma: obs.position_component(1, value, sigma),
    "depth": lambda value, sigma: obs.position_component(2, value, sigma),
}


def length_noise(model: PlantModel) -> float | None:
    """The encoders' 1-sigma noise [m] (`noise.length` in the plant file), None where not given."""
    value = model.plant.noise.get(LENGTH_NOISE)
    return float(value) if value is not None and math.isfinite(value) and value > 0.0 else None


class ModelledChannels:
    """Every channel the plant model predicts for stacked states (`PlantModel.predict_states`) and its
    derivative by forward differences: computed once per set of states for all the modelled
    observations of a problem (the estimator asks each observation in turn for the same states)."""

    def __init__(self, model: PlantModel, conditions: Sequence[Conditions] | StackedConditions):
        self.model = model
        self.conditions = StackedConditions.of(conditions)
        self.differentiated = model.differentiated
        self._values: tuple[States, dict[str, np.ndarray]] | None = None
        self._jacobians: tuple[States, dict[str, np.ndarray]] | None = None

    def _conditions(self, states: States) -> StackedConditions:
        return self.conditions.take(states.sample if states.sample is not None else np.zeros(len(states), int))

    def _predict(self, states: States) -> dict[str, np.ndarray]:
        return self.model.predict_states(states, self._conditions(states))

    def values(self, states: States) -> dict[str, np.ndarray]:
        if self._values is None or self._values[0] is not states:
            self._values = (states, self._predict(states))
        return self._values[1]

    def jacobians(self, states: States) -> dict[str, np.ndarray]:
        """(n, 10) derivative of every channel: the model's own where every channel and measurement effect
        gives one (the values predicted again with them), else from one prediction of all displaced
        states (forward differences)."""
        if self._jacobians is None or self._jacobians[0] is not states:
            exact = self.model.predict_gradients(states, self._conditions(states)) if self.differentiated else None
            if exact is not None:
                self._values, self._jacobians = (states, exact[0]), (states, exact[1])
            else:
                names = tuple(self.values(states))
                table = forward_differences(lambda moved: np.stack(list(self._predict(moved).values()), axis=1),
                                            states)
                self._jacobians = (states, {name: table[:, k] for k, name in enumerate(names)})
        return self._jacobians[1]

    def observation(self, name: str, value: float | np.ndarray, sigma: float) -> Observation:
        return Observation(name, value, sigma, lambda states: self.values(states)[name],
                           lambda states: self.jacobians(states)[name])


def observations_for(model: PlantModel, measured: Mapping[str, float | np.ndarray],
                     conditions: Sequence[Conditions] | StackedConditions = (NO_CONDITIONS,)) -> list[Observation]:
    """The observations of the measured channels with a noise in the plant file: values a number, or
    arrays over a batch (NaN where a channel was not measured) with each sample's conditions."""
    noise, known = model.plant.noise, model.channels.channels
    direct = not model.measuring
    modelled = ModelledChannels(model, conditions)
    out = []
    for name, value in measured.items():
        sigma = noise.get(known[name].noise_key) if name in known else None
        if sigma is None or not math.isfinite(sigma) or sigma <= 0.0 or not np.any(np.isfinite(value)):
            continue
        if direct and name in BUILT_IN:
            out.append(BUILT_IN[name](value, sigma))
        else:
            out.append(modelled.observation(name, value, sigma))
    return out


def fuses(model: PlantModel) -> bool:
    """Whether the model's samples are estimated (lengths with a noise, the energy solver)."""
    return length_noise(model) is not None and model.solver == "energy"


def estimate_recording(model: PlantModel, reported: np.ndarray, measured: Mapping[str, np.ndarray],
                       conditions: Sequence[Conditions],
                       warm_starts: Sequence[Estimate | None] | None = None) -> list[Estimate]:
    """The fused states of N samples: reported (N, 4), each channel (N,) (NaN where not measured), each
    sample's conditions (its load, its lengths, what its sensors read depend on them), and optionally each
    sample's estimate under slightly different parameters to start from (a fit); the model's forward
    kinematics where it cannot fuse (no length noise, or not the energy solver)."""
    reported = np.asarray(reported, dtype=float).reshape(-1, 4)
    if len(conditions) != len(reported):
        raise ValueError(f"{len(conditions)} conditions for {len(reported)} samples")
    if not fuses(model):
        previous: Solution | None = None
        out = []
        for row, at in zip(reported, conditions):
            out.append(forward_estimate(model.solve(row, previous, at), row))
            previous = out[-1].solution if out[-1].ok else previous
        return out
    if not model.refining:
        return recording_batch(model, reported, measured, conditions, warm_starts).estimates()
    lengths, loads, hooked = model.batch_inputs(reported, conditions)
    estimates = _estimate_refined(model, lengths, observations_for(model, measured, conditions), loads, conditions,
                                  warm_starts)
    for k in hooked:
        estimates[k] = unhooked(model, reported[k], conditions[k])
    return estimates


def recording_batch(model: PlantModel, reported: np.ndarray, measured: Mapping[str, np.ndarray],
                    conditions: Sequence[Conditions],
                    warm_starts: Sequence[Estimate | None] | None = None) -> BatchEstimate:
    """`estimate_recording`'s estimates as arrays, for a model that fuses and whose geometry does not
    depend on the pose (not `refining`): what a second process can compute and send back cheaply."""
    lengths, loads, hooked = model.batch_inputs(reported, conditions)
    batch = _batch(model, lengths, observations_for(model, measured, conditions), loads, warm_starts)
    for k in hooked:
        batch.fallback[k] = unhooked(model, reported[k], conditions[k])
        batch.status[k] = batch.fallback[k].solution.status.value
    return batch


def unhooked(model: PlantModel, reported: np.ndarray, conditions: Conditions) -> Estimate:
    """A sample where an effect's hook failed: the solve, which says which and why (invalid input)."""
    return forward_estimate(model.solve(reported, None, conditions), reported)


def _batch(model: PlantModel, lengths: np.ndarray, observations: Sequence[Observation], loads: np.ndarray,
           warm_starts: Sequence[Estimate | None] | None, anchors: np.ndarray | None = None) -> BatchEstimate:
    """The estimator on true (or free) lengths (N, 4) with the model's rope law under each sample's load
    (N, 6), each warm-started from an estimate of the same sample."""
    ropes = model.ropes
    sigma = length_noise(model)
    assert sigma is not None  # only a model that fuses is estimated in batches
    return estimate_batch(model.physical, lengths, observations, sigma, ropes.axial_stiffness, ropes.weight,
                          loads=loads, warm_starts=warm_starts, anchors=anchors)


def _estimate_refined(model: PlantModel, lengths: np.ndarray, observations: Sequence[Observation], loads: np.ndarray,
                      conditions: Sequence[Conditions], warm_starts: Sequence[Estimate | None] | None
                      ) -> list[Estimate]:
    """Estimates where the geometry depends on the pose: each round estimates every sample with the
    anchors and free lengths of its last estimate's pose, warm-started there, until no attachment
    point moves more than REFINE_TOL (at most REFINE_STEPS rounds); the first round with the tangent
    points of the warm starts' poses (a fit: the reference model's estimate of the same sample, whose
    pose is close: a round fewer than from the plant's anchors), else with
    the plant's anchors. A sample the estimator leaves gets the model's forward kinematics, which
    refines its own geometry."""
    nominal = np.broadcast_to(model.physical.anchors, (len(lengths), 4, 3))

    def geometry(states: States) -> tuple[np.ndarray, np.ndarray]:
        anchors, free = model.refine(lengths, states)
        posed = np.isfinite(states.position).all(axis=1)  # where no pose is known: the nominal geometry
        return np.where(posed[:, None, None], anchors, nominal), np.where(posed[:, None], free, lengths)

    def posed(batch: BatchEstimate) -> States:
        return States(model.physical, batch.rotation, batch.position, batch.tensions)

    anchors, free = None, lengths
    if warm_starts is not None and any(w is not None and w.ok for w in warm_starts):
        warm = [w.solution if w is not None and w.ok else None for w in warm_starts]
        anchors, free = geometry(States(model.physical,
                                        np.array([np.eye(3) if s is None else s.rotation for s in warm]),
                                        np.array([np.full(3, np.nan) if s is None else s.position for s in warm]),
                                        np.array([np.zeros(4) if s is None else s.tensions for s in warm])))
    batch = _batch(model, free, observations, loads, warm_starts, anchors)
    states = posed(batch)
    for _ in range(REFINE_STEPS):
        anchors, free = geometry(states)
        batch = _batch(model, free, observations, loads, batch.estimates(), anchors)
        previous, states = states, posed(batch)
        if not np.nanmax(np.abs(states.points_b - previous.points_b), initial=0.0) >= REFINE_TOL:
            break
    # reported: the true lengths, not the free lengths below the tangent points that the last round fitted
    estimates = [replace(e, reported=row) for e, row in zip(batch.estimates(), lengths)]
    for i in batch.fallback:
        estimates[i] = forward_estimate(model.solve(lengths[i], None, conditions[i]), lengths[i])
    return estimates


def forward_estimate(solution: Solution, reported: Sequence[float] | np.ndarray) -> Estimate:
    """A solve of the reported lengths as an estimate that fused nothing."""
    return Estimate(solution, np.asarray(reported, dtype=float), np.zeros(4), float("nan"))
