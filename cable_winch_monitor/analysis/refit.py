"""`fit`: fit chosen effects on the training part, compare before and after on training and held-out data,
and write a plant file with the effects on (effects.plantfile; the live node and replay then use it)."""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..effects import PlantModel
from .data import Dataset
from .evaluate import ChannelStats, Evaluator, channel_stats, noise, split, thin
from .fit import FitResult, fit_effects

PER_KIND = 300  # training rows per sensor kind the fit uses


@dataclass
class PartScores:
    """Per-channel statistics and the score of one part of the bag under one model."""

    channels: dict[str, ChannelStats]
    score: float


@dataclass
class FitReport:
    fit: FitResult
    effects: list[str]
    before: dict[str, PartScores]  # "training", "held_out"
    after: dict[str, PartScores]
    noise_source: dict[str, str]


def _scores(model: PlantModel, evaluator: Evaluator, sigma: np.ndarray) -> PartScores:
    residuals = evaluator.residuals(model)
    return PartScores(channel_stats(residuals, evaluator.data.measured, sigma, evaluator.data.channels),
                      evaluator.score(model, sigma))


def fit_command(base: PlantModel, data: Dataset, names: Sequence[str]) -> FitReport:
    """Fit `names` (added to, or refitted within, `base`) and score both models on both parts."""
    sigma, source = noise(base, data)
    train_rows, held_rows = split(data)
    effects = [base.get(n) or base.registry.effect_class(n)(plant=base.plant) for n in names]
    fit = fit_effects(base, effects, Evaluator(data.subset(thin(train_rows, data.kinds, PER_KIND)), base), sigma)
    parts = {"training": Evaluator(data.subset(train_rows), base), "held_out": Evaluator(data.subset(held_rows), base)}
    before = {k: _scores(base, e, sigma) for k, e in parts.items()}
    after = {k: _scores(fit.model, e, sigma) for k, e in parts.items()}
    return FitReport(fit, list(names), before, after, source)
