"""Measurements the estimator fuses with the cable lengths: a value, its noise and a prediction from the state.

A prediction is a function of stacked equilibrium states (`States`: n rows of pose and
tensions) returning n predicted readings, with an optional analytic gradient with respect
to the state coordinates (position [m], a rotation vector [rad] applied on the left,
tensions [N]); where none is given the estimator differentiates numerically. The built-in
observations are the plant's sensors as the monitor's rigid model reads them: load pin i
reads tau_i, the inclinometer roll and pitch of `platform` (REP-103, as
geometry.roll_pitch_yaw), the depth gauge the platform origin's z (and x, y where measured).
A user declares any other channel the same way, with its own prediction function.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from functools import cached_property, lru_cache

import numpy as np

from ..plantfile.plant import CABLE_NAMES, Plant
from ..statics.geometry import rotations_from_vectors
from ..statics.result import Solution, solved_rows

STATE_SIZE = 10          # position (3), rotation vector (3), tensions (4)
FD_STEPS = np.array([1e-6] * 3 + [1e-8] * 3 + [1e-3] * 4)  # finite-difference steps [m, rad, N]


@dataclass(frozen=True)
class States:
    """n equilibrium states: rotation (n, 3, 3), position (n, 3) [m], tensions (n, 4) [N] of `plant`, the
    sample each explains (its index in a batch: a prediction may depend on the sample's conditions),
    the solver's Solutions where the states are those (`solutions` then gives them as they are), and
    each state's anchors (n, 4, 3) where the geometry depends on the pose (None: the plant's)."""

    plant: Plant
    rotation: np.ndarray
    position: np.ndarray
    tensions: np.ndarray
    sample: np.ndarray | None = None
    solved: tuple[Solution, ...] | None = None
    anchors: np.ndarray | None = None

    @classmethod
    def of(cls, plant: Plant, solutions: Sequence[Solution]) -> States:
        """The states of solved samples, keeping their Solutions."""
        return cls(plant, np.array([s.rotation for s in solutions]).reshape(-1, 3, 3),
                   np.array([s.position for s in solutions]).reshape(-1, 3),
                   np.array([s.tensions for s in solutions]).reshape(-1, 4), solved=tuple(solutions))

    def __len__(self) -> int:
        return len(self.position)

    @cached_property
    def finite(self) -> np.ndarray:
        """(n,) the states whose pose and tensions are all numbers (the others predict nothing)."""
        return np.isfinite(self.position).all(axis=1) & np.isfinite(self.rotation).all(axis=(1, 2)) \
            & np.isfinite(self.tensions).all(axis=1)

    @cached_property
    def points_b(self) -> np.ndarray:
        """Attachment points B_i in `shaft`, (n, 4, 3)."""
        return self.position[:, None, :] + np.einsum("nij,cj->nci", self.rotation, self.plant.attachments)

    @cached_property
    def spans(self) -> np.ndarray:
        """|A_i B_i|, (n, 4) [m]."""
        return np.linalg.norm(self.points_b - (self.plant.anchors if self.anchors is None else self.anchors), axis=2)

    def solutions(self) -> list[Solution]:
        """The states as the package's Solutions: the solver's where given, else made from the states
        (each rope taut where its tension is positive)."""
        if self.solved is not None:
            return list(self.solved)
        return solved_rows(self.plant, "estimate", self.spans, self.rotation, self.position, self.tensions,
                           self.tensions > 0.0, [0] * len(self), anchors=self.anchors)

    def repeated(self, times: int) -> States:
        """The n states `times` over, stacked (times * n rows, in blocks of n)."""
        sample = None if self.sample is None else np.tile(self.sample, times)
        anchors = None if self.anchors is None else np.tile(self.anchors, (times, 1, 1))
        return States(self.plant, np.tile(self.rotation, (times, 1, 1)), np.tile(self.position, (times, 1)),
                      np.tile(self.tensions, (times, 1)), sample, anchors=anchors)

    def moved(self, step: np.ndarray, turns: np.ndarray) -> States:
        """The states moved by `step` (n, 10) in the state coordinates; `turns` (n, 3, 3) are the rotations
        of its rotation vectors, which the caller makes once (`_displacements`)."""
        rotation = turns @ self.rotation
        return States(self.plant, rotation, self.position + step[:, 0:3], self.tensions + step[:, 6:10], self.sample,
                      anchors=self.anchors)


Predict = Callable[[States], np.ndarray]


@dataclass(frozen=True)
class Observation:
    """One measured channel: value (scalar, or (N,) over a batch of samples; NaN = not measured at
    that sample), 1-sigma noise, and the prediction of its reading from the state.

    `gradient(states)` returns (n, 10): the derivative of the prediction with respect to
    position [m], rotation vector [rad] (applied on the left: R -> exp([w]x) R) and tensions [N].
    `coordinate` marks a reading that is one of those coordinates itself (a load pin, the
    depth gauge): the estimator then reads it off the state without calling `predict`.
    """

    name: str
    value: float | np.ndarray
    sigma: float
    predict: Predict
    gradient: Callable[[States], np.ndarray] | None = None
    coordinate: int | None = None

    def __post_init__(self) -> None:
        if not (np.isfinite(self.sigma) and self.sigma > 0.0):
            raise ValueError(f"observation {self.name!r}: noise sigma must be finite and positive, got {self.sigma!r}")

    def evaluate(self, states: States) -> np.ndarray:
        """The predictions (n,) for n states; ValueError naming the channel where the function gives
        another shape."""
        values = np.asarray(self.predict(states), dtype=float)
        if values.shape != (len(states),):
            raise ValueError(f"observation {self.name!r}: prediction must give one value per state, "
                             f"got shape {values.shape} for {len(states)} states")
        return values

    def jacobian(self, states: States) -> np.ndarray:
        """(n, 10) derivative of the prediction; forward differences where no gradient is declared."""
        if self.gradient is not None:
            return np.asarray(self.gradient(states), dtype=float).reshape(len(states), STATE_SIZE)
        return forward_differences(self.evaluate, states)

    def with_value(self, value: float | np.ndarray) -> Observation:
        """The same channel with another reading."""
        return replace(self, value=value)


def forward_differences(function: Callable[[States], np.ndarray], states: States) -> np.ndarray:
    """The derivative of function(states) -- (n,) or (n, k) values -- with respect to the state
    coordinates, (n, 10) or (n, k, 10), by forward differences of FD_STEPS: the states and their ten
    displaced copies in one call (the steps are small enough that the one-sided error, of the order of
    the step, is far below the sensors' noise)."""
    n, copies = len(states), STATE_SIZE + 1
    values = np.asarray(function(states.repeated(copies).moved(*_displacements(n))), dtype=float)
    values = values.reshape((copies, n) + values.shape[1:])
    slopes = (values[1:] - values[0]) / FD_STEPS.reshape((STATE_SIZE,) + (1,) * (values.ndim - 1))
    return np.moveaxis(slopes, 0, -1)


@lru_cache(maxsize=64)
def _displacements(n: int) -> tuple[np.ndarray, np.ndarray]:
    """The forward differences' steps of n states ((11 n, 10): none, then each coordinate's in turn, in
    blocks of n) and the rotations of their rotation vectors, made once for each n (read-only): the
    estimator differentiates a few states at a time, many times a sample."""
    blocks = np.zeros((STATE_SIZE + 1, n, STATE_SIZE))
    for k, h in enumerate(FD_STEPS):
        blocks[k + 1, :, k] = h
    steps = blocks.reshape(-1, STATE_SIZE)
    turns = rotations_from_vectors(steps[:, 3:6])
    steps.flags.writeable = turns.flags.writeable = False
    return steps, turns


def unit_gradient(n: int, column: int) -> np.ndarray:
    """(n, 10): the derivative of one of the state coordinates themselves (a load pin, the depth)."""
    out = np.zeros((n, STATE_SIZE))
    out[:, column] = 1.0
    return out


def load_pin(cable: int, value: float | np.ndarray, sigma: float) -> Observation:
    """Load pin of cable `cable` (0-based): reads the rope tension tau_i [N]."""
    return Observation(f"tension_{CABLE_NAMES[cable]}", value, sigma, lambda s: s.tensions[:, cable],
                       lambda s: unit_gradient(len(s), 6 + cable), coordinate=6 + cable)


def position_component(axis: int, value: float | np.ndarray, sigma: float) -> Observation:
    """Depth gauge (axis 2, named 'depth') or a horizontal position sensor (0: 'x', 1: 'y') [m]."""
    return Observation(("x", "y", "depth")[axis], value, sigma, lambda s: s.position[:, axis],
                       lambda s: unit_gradient(len(s), axis), coordinate=axis)


def roll_of(states: States) -> np.ndarray:
    """The platform's roll [rad] in each state (REP-103, as geometry.roll_pitch_yaw)."""
    r = states.rotation
    return np.arctan2(r[:, 2, 1], r[:, 2, 2])


def roll_gradient(states: States) -> np.ndarray:
    """d roll / d omega: with dR = [w]x R, d r_2j = w_0 r_1j - w_1 r_0j."""
    r = states.rotation
    r21, r22 = r[:, 2, 1], r[:, 2, 2]
    norm = r21 ** 2 + r22 ** 2
    out = np.zeros((len(states), STATE_SIZE))
    # d atan2(r21, r22) = (r22 d r21 - r21 d r22) / (r21^2 + r22^2)
    out[:, 3] = (r22 * r[:, 1, 1] - r21 * r[:, 1, 2]) / norm
    out[:, 4] = -(r22 * r[:, 0, 1] - r21 * r[:, 0, 2]) / norm
    return out


def pitch_of(states: States) -> np.ndarray:
    """The platform's pitch [rad] in each state."""
    return np.arcsin(np.clip(-states.rotation[:, 2, 0], -1.0, 1.0))


def pitch_gradient(states: States) -> np.ndarray:
    """d pitch / d omega: pitch = asin(-r_20), with dR = [w]x R, d r_20 = w_0 r_10 - w_1 r_00."""
    r = states.rotation
    scale = -1.0 / np.sqrt(np.maximum(1.0 - r[:, 2, 0] ** 2, 1e-30))
    out = np.zeros((len(states), STATE_SIZE))
    out[:, 3] = scale * r[:, 1, 0]
    out[:, 4] = -scale * r[:, 0, 0]
    return out


def roll(value: float | np.ndarray, sigma: float) -> Observation:
    """Inclinometer roll of `platform` [rad] (REP-103)."""
    return Observation("roll", value, sigma, roll_of, roll_gradient)


def pitch(value: float | np.ndarray, sigma: float) -> Observation:
    """Inclinometer pitch of `platform` [rad] (REP-103)."""
    return Observation("pitch", value, sigma, pitch_of, pitch_gradient)
